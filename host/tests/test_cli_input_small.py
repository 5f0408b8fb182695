"""The CLI audit's low-severity findings (session 8): scenario error lines inside multi-line TOML values, empty
option values, whole numbers typed in other forms, waits too long for the threading timeouts, and a flash port
that does not exist. Each test is what a user typed and what must happen."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from agnav_host import cli
from agnav_host.sim.scenario import ScenarioError, _key_index, builtin_names, builtin_text, parse_scenario
from _cli_helpers import _no_user_config, free_port, nowhere, usage_error  # noqa: F401 (the fixture is autouse)
from test_cli_input_audit import SMALL, sim_refused

# ---- scenario error lines inside multi-line values --------------------------------------------------------
BASE = """[scenario]
name = "t"
duration_s = 5.0
{scenario}
[robot]
model = "diff_drive"
start = {{ x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }}

[[goals]]
x_m = 3.0
y_m = 0.0
"""
BAD = "# <- bad"


def _error(text: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "s.toml")
    return e.value


def _bad_line(text: str) -> int:
    """The line marked ``# <- bad`` (the only one)."""
    (line,) = [n for n, s in enumerate(text.splitlines(), 1) if s.rstrip().endswith(BAD)]
    return line


@pytest.mark.parametrize("body, field", [
    ('[[walls]]\npoints = [\n  [0, 0],\n  [1, 0],\n  [1, "x"],  ' + BAD + '\n]\n', "walls[0].points[2]"),
    ('[[walls]]\npoints = [[0, 0], [1, 0]]\n\n[[walls]]\npoints = [\n  [0, 0],\n  [true, 1],  ' + BAD + '\n]\n',
     "walls[1].points[1]"),
    ('[[walls]]\npoints = [[0, 0],\n  [1, 0], [2, "x"]]  ' + BAD + '\n', "walls[0].points[2]"),
    ('[[rows]]\npoints = [\n  [0, 0],\n  [5, 0],\n  [6, "x"],  ' + BAD + '\n]\n', "rows[0].points[2]"),
    ('[[rows]]\nstart = { x_m = 0, y_m = 0, yaw_deg = 0 }\nlength_m = 5\ngaps = [\n  [1, 2],\n  [3, 2],  ' + BAD
     + '\n]\n', "rows[0].gaps[1]"),
    ('[[movers]]\nwaypoints = [\n  [0, 0],\n  [1],  ' + BAD + '\n]\n', "movers[0].waypoints[1]"),
    ('[meta]\npath = [\n  [0, 0],\n  [1, 0],\n  [2, nan],  ' + BAD + '\n]\n', "meta.path[2]"),
    ('[meta]\nlandmarks = [\n  [0, 0, 0.1],\n  [1, 0, -1],  ' + BAD + '\n]\n', "meta.landmarks[1]"),
], ids=["walls", "second-walls", "two-elements-on-a-line", "rows-points", "rows-gaps", "movers", "meta-path",
        "meta-landmarks"])
def test_an_element_of_a_multiline_array_names_its_own_line(body, field):
    """It named the line of the key (``points = [``), whichever element was wrong."""
    text = BASE.format(scenario="") + "\n" + body
    e = _error(text)
    assert e.field == field
    assert e.line == _bad_line(text), (e, text.splitlines()[e.line - 1])


@pytest.mark.parametrize("scenario", [
    'description = """\nrows [1 and 2\n"""\ncontrol_hz = -1  ' + BAD + "\n",  # "[" in a string: later keys lost
    'description = """\ncontrol_hz = 3\n"""\ncontrol_hz = -1  ' + BAD + "\n",  # a "key" inside a string taken
    'description = "say \\"[\\" now"\ncontrol_hz = -1  ' + BAD + "\n",  # an escaped quote ended the string
    "description = '''\nit's [here]\n'''\ncontrol_hz = -1  " + BAD + "\n",
    '"control_hz" = -1  ' + BAD + "\n",  # a quoted key
    'bounds = [\n  -5, -5,\n  5, 5,\n]\ncontrol_hz = -1  ' + BAD + "\n",
], ids=["bracket-in-string", "key-in-string", "escaped-quote", "literal-string", "quoted-key", "multiline-array"])
def test_a_key_after_a_multiline_string_or_array_keeps_its_line(scenario):
    text = BASE.format(scenario=scenario)
    e = _error(text)
    assert e.field == "scenario.control_hz" and e.line == _bad_line(text), (e, text)


def test_a_table_header_inside_a_multiline_string_is_not_a_table():
    """``[[goals]]`` inside a description counted as a goal: goals[1]'s error named goals[0]'s line."""
    text = BASE.format(scenario="description = '''\n[[goals]]\n'''\n") + '\n[[goals]]\nx_m = 1.0\ny_m = "x"  ' + BAD + "\n"
    e = _error(text)
    assert e.field == "goals[1].y_m" and e.line == _bad_line(text)


def test_sim_names_the_line_of_a_bad_element_in_a_multiline_wall(tmp_path, capsys):
    text = SMALL + '\n[[walls]]\npoints = [\n  [0, 0],\n  [1, "x"],  ' + BAD + '\n]\n'
    f = tmp_path / "s.toml"
    f.write_text(text)
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:{_bad_line(text)}: walls[0].points[1]: must be a [x_m, y_m] pair"), err


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n", "\ufeff"])
def test_sim_of_an_empty_scenario_says_it_is_empty(text, tmp_path, capsys):
    """It said "<root>: missing required table [scenario]"."""
    f = tmp_path / "s.toml"
    f.write_text(text, encoding="utf-8")
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}: no scenario in the file (it is empty or holds only comments)"), err


def _value_paths(v, path=()):
    """Every table key, array-of-tables entry and array element of a parsed TOML document, as paths."""
    if path:
        yield path
    items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
    for k, x in items:
        yield from _value_paths(x, (*path, k))


@pytest.mark.parametrize("name", builtin_names())
def test_every_value_of_a_builtin_scenario_has_its_own_line(name):
    """Whatever a scenario check blames (a key, a table, one element of a list) is found itself, not a parent:
    the built-ins have multi-line arrays, inline tables and [[tables]]."""
    text = builtin_text(name)
    index = dict(reversed(_key_index(text)))  # the first line of each path
    missing = [p for p in _value_paths(tomllib.loads(text)) if p not in index]
    assert not missing
    lines = text.splitlines()
    for path, line in index.items():  # a key's line names the key
        if isinstance(path[-1], str):
            assert path[-1] in lines[line - 1], (path, line)


# ---- empty option values ---------------------------------------------------------------------------------
def _empty_cases() -> list[tuple[list[str], str]]:
    """(argv with one empty value, the argument argparse must name). Each would have run, or said something
    about "." or the option's default, without the check (the extra options keep such a run short)."""
    dev = ["--device", "tcp:127.0.0.1:1", "--wait", "0.2"]
    return [
        (["sim", "--out", "", "--duration", "0.1", "--quiet", "--no-plot", "--no-rrd"], "--out"),  # wrote into .
        (["sim", "", "--out", "o", "--duration", "0.1", "--quiet"], "scenario"),  # ".: is a directory"
        (["sim", "--planner", "", "--out", "o"], "--planner"),
        (["run", "--device", "", "--no-tlog", "--wait", "0.2"], "--device"),  # the config's device instead
        (["run", *dev, "--config", "", "--no-tlog"], "--config"),
        (["run", *dev, "--tlog", ""], "--tlog"),  # the default log path instead
        (["run", *dev, "--key-file", "", "--sign", "--no-tlog"], "--key-file"),
        (["run", *dev, "--planner", "", "--no-tlog"], "--planner"),  # the firmware layers alone instead
        (["run", *dev, "--rrd", "", "--no-tlog"], "--rrd"),  # no recording
        (["calibrate", "steering", *dev, "--plot-dir", "", "--no-tlog", "--yes"], "--plot-dir"),
        (["param", "get", "", *dev, "--no-tlog"], "name"),
        (["key", "show", "--key-file", ""], "--key-file"),
        (["key", "push", *dev, "--old-key-file", "", "--no-tlog"], "--old-key-file"),
        (["config", "--config", ""], "--config"),  # the defaults shown
        (["flash", "--dry-run", "--port", ""], "--port"),  # pio's autodetect instead
        (["flash", "--dry-run", "--env", ""], "--env"),
        (["replay", ""], "log"),
        (["rows", "--scan", ""], "--scan"),
        (["faults", "--list", "--only", ""], "--only"),  # "" is in every name: every case
        (["faults", "--list", "--markdown", ""], "--markdown"),
        (["sil", "", "--duration", "0.1"], "scenario"),
        (["sil", "--tcp", "", "--duration", "0.1"], "--tcp"),
        (["sil", "--tcp", f"127.0.0.1:{free_port()}", "--tlog", "", "--duration", "0.1"], "--tlog"),
        (["bench", "planners", "--out", "", "--scenarios", "canyon", "--planners", "flb", "--seeds", "1"], "--out"),
        (["bench", "planners", "--out", "o", "--planners", ""], "--planners"),
        (["bench", "planners", "--out", "o", "--scenarios", ""], "--scenarios"),
    ]


@pytest.mark.parametrize("argv, name", _empty_cases(), ids=lambda x: " ".join(x) if isinstance(x, list) else x)
def test_an_empty_value_is_refused_naming_its_option(argv, name, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = usage_error(capsys, argv)
    assert f"error: argument {name}: empty value (a shell variable that is not set?)" in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) in ([], [tmp_path / "xdg"])  # nothing written in the current folder


def test_text_options_with_choices_or_a_type_keep_their_own_message(capsys):
    assert "argument --firmware: invalid choice: ''" in usage_error(capsys, ["sim", "--firmware", "", "--out", "o"])
    assert "argument --goal: goal must be X,Y" in usage_error(capsys, ["sim", "--goal", "", "--out", "o"])


# ---- whole numbers typed in other forms -------------------------------------------------------------------
@pytest.mark.parametrize("typed, value", [("010", 10), ("0x10", 16), ("0b101", 5), ("1_000", 1000), (" 7", 7), ("00", 0)])
def test_a_seed_typed_with_leading_zeros_or_a_base_prefix_is_read(typed, value):
    """"010" was refused as "expected a whole number" (Python's base-0 int() takes no leading zero)."""
    assert cli.build_parser().parse_args(["sim", "--out", "o", "--seed", typed]).seed == value


@pytest.mark.parametrize("argv, message", [
    (["sim", "--out", "o", "--seed", "1e3"], "argument --seed: expected a whole number, got '1e3' (write it in digits: 1000)"),
    (["sim", "--out", "o", "--seed", "10.0"], "argument --seed: expected a whole number, got '10.0' (write it in digits: 10)"),
    (["sim", "--out", "o", "--seed", "1.5"], "argument --seed: expected a whole number, got '1.5'\n"),
    (["sim", "--out", "o", "--seed", "-1"], "argument --seed: must be >= 0, got '-1'"),
    (["bench", "planners", "--seeds", "0"], "argument --seeds: must be >= 1, got '0'"),
    (["bench", "planners", "--jobs", "0"], "argument --jobs: must be >= 1, got '0'"),
    (["bench", "planners", "--jobs", "-2"], "argument --jobs: must be >= 1, got '-2'"),
    (["plan", "--start", "0,0,0", "--goal", "5,0,0", "--samples", "1e3"],
     "argument --samples: expected a whole number, got '1e3' (write it in digits: 1000)"),
])
def test_a_whole_number_in_another_form_is_refused_naming_the_option(argv, message, capsys):
    err = usage_error(capsys, argv)
    assert message in err and "Traceback" not in err


# ---- waits longer than the threading timeouts take --------------------------------------------------------
@pytest.mark.parametrize("argv, option", [
    (["run", "--device", nowhere(), "--no-tlog", "--wait", "1e300"], "--wait"),  # OverflowError traceback before
    (["param", "get", "LINK_TIMEOUT_MS", "--device", nowhere(), "--no-tlog", "--timeout", "1e300"], "--timeout"),
    (["key", "push", "--device", nowhere(), "--no-tlog", "--timeout", "1e10"], "--timeout"),
])
def test_a_wait_longer_than_a_day_is_refused_naming_the_option(argv, option, capsys):
    err = usage_error(capsys, argv)
    assert f"argument {option}: must be <= 86400 (a day), got '{argv[-1]}'" in err and "Traceback" not in err


def test_a_wait_of_a_day_is_taken():
    ns = cli.build_parser().parse_args(["param", "list", "--wait", "86400", "--timeout", "86400"])
    assert (ns.wait, ns.timeout) == (86400.0, 86400.0)


# ---- flash to a port that does not exist ------------------------------------------------------------------
@pytest.mark.parametrize("port, why", [
    ("{tmp}/ttyNOPE", "no such device (is the board plugged in?"),
    ("{tmp}/ttyQQ*", "matches no device (is the board plugged in?"),
    ("{tmp}", "a folder, not a serial device"),
])
def test_flash_to_a_port_that_does_not_exist_is_refused_even_in_a_dry_run(port, why, tmp_path, capsys):
    """The dry run printed the upload command and said 0; the upload itself failed in pio's words."""
    port = port.format(tmp=tmp_path)
    assert cli.main(["flash", "--dry-run", "--port", port]) == 1
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.startswith(f"agnav flash: --port {port}: {why}") and len(cap.err.strip().splitlines()) == 1


def test_flash_dry_run_to_a_device_that_exists_prints_the_command(capsys):
    assert Path("/dev/null").exists()
    assert cli.main(["flash", "--dry-run", "--port", "/dev/null"]) == 0
    assert "--upload-port /dev/null" in capsys.readouterr().out
