"""Scenario files as people write them: not UTF-8, malformed entries, bounds, sizes beyond the limits, errors
inside multi-line values and empty files. ``agnav sim`` and ``agnav sil`` refuse each with exit 2 and one line
naming the file, the line and the field, before anything runs."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from agnav_host import cli
from agnav_host.sim.scenario import ScenarioError, _key_index, builtin_names, builtin_text, parse_scenario
from _cli_helpers import _no_user_config  # noqa: F401 (the fixture is autouse)

SMALL = """[scenario]
name = "t"
duration_s = 5.0

[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }

[laser]
model = "tim561"

[[goals]]
x_m = 3.0
y_m = 0.0
"""


def sim_refused(capsys, tmp_path: Path, scenario: Path, *extra: str) -> str:
    """Run ``agnav sim scenario`` expecting a clean exit 2 before the run; return the one error line."""
    out = tmp_path / "out"
    rc = cli.main(["sim", str(scenario), "--duration", "1", "--quiet", "--no-plot", "--no-rrd", "--out", str(out), *extra])
    cap = capsys.readouterr()
    assert rc == 2, cap.err
    assert "Traceback" not in cap.err and len(cap.err.strip().splitlines()) == 1, cap.err
    assert not out.exists() or not any(out.iterdir())
    return cap.err.strip()


# a scenario file that is not UTF-8
@pytest.mark.parametrize("body, line, what", [
    (SMALL.replace('"t"', '"caf\u00e9"').encode("latin-1"), 2, "not UTF-8 text (byte 0xe9)"),
    (SMALL.encode("utf-16"), 1, "UTF-16 text"),
    (b"\x00\x17\x80garbage\n", 1, "not UTF-8 text (byte 0x80)"),
    (SMALL.encode() + b"# r\xe9sum\xe9\n", SMALL.count("\n") + 1, "not UTF-8 text (byte 0xe9)"),
])
def test_sim_and_sil_name_a_scenario_file_that_is_not_utf8(tmp_path, capsys, body, line, what):
    f = tmp_path / "bad.toml"
    f.write_bytes(body)
    err = sim_refused(capsys, tmp_path, f)
    assert err == f"agnav sim: {f}:{line}: cannot read scenario file: {what}; save it as UTF-8"
    assert cli.main(["sil", str(f), "--duration", "1", "--tcp", "tcp:127.0.0.1:0"]) == 2
    assert capsys.readouterr().err.strip() == err.replace("agnav sim", "agnav sil")


def test_sim_accepts_a_scenario_with_a_utf8_bom(tmp_path, capsys):
    f = tmp_path / "bom.toml"
    f.write_bytes(b"\xef\xbb\xbf" + SMALL.encode())
    assert cli.main(["sim", str(f), "--duration", "1", "--quiet", "--no-plot", "--no-rrd", "--out", str(tmp_path / "o")]) == 0


# [meta] path / landmarks, [[weeds]] region, bounds: refused when the file is loaded, with file:line
_N = SMALL.count("\n")


@pytest.mark.parametrize("extra, line, field, why", [
    ('[meta]\npath = "abc"\n', _N + 2, "meta.path", "must be a list of at least 2 [x_m, y_m] points"),
    ("[meta]\npath = [[0, 0], [1]]\n", _N + 2, "meta.path[1]", "must be a [x_m, y_m] pair of numbers, got [1]"),
    ("[meta]\npath = [[0, 0], [1, inf]]\n", _N + 2, "meta.path[1]", "must be a [x_m, y_m] pair of numbers"),
    ('[meta]\nlandmarks = "abc"\n', _N + 2, "meta.landmarks", "must be a list of [x_m, y_m, radius_m] rows"),
    ("[meta]\nlandmarks = [[1, 2]]\n", _N + 2, "meta.landmarks[0]", "must be a [x_m, y_m, radius_m] row of finite"),
    ("[meta]\nlandmarks = [[1, 2, 0.1], [1, nan, 0.1]]\n", _N + 2, "meta.landmarks[1]", "row of finite numbers"),
    ("[meta]\nlandmarks = [[1, 2, 0]]\n", _N + 2, "meta.landmarks[0]", "radius_m > 0"),
    ("[[weeds]]\nregion = [0, 0, inf, 1]\n", _N + 2, "weeds[0].region", "finite numbers with min < max"),
])
def test_malformed_scenario_entries_are_refused_at_load_time(tmp_path, capsys, extra, line, field, why):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + extra)
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:{line}: {field}: ") and why in err, err


@pytest.mark.parametrize("bounds", ["[-inf, -inf, inf, inf]", "[true, 0, 5, 5]", "[0, 0, 5, nan]"])
def test_scenario_bounds_must_be_finite_numbers(tmp_path, capsys, bounds):
    f = tmp_path / "s.toml"
    f.write_text(SMALL.replace("duration_s = 5.0\n", f"duration_s = 5.0\nbounds = {bounds}\n"))
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:4: scenario.bounds: must be [xmin_m, ymin_m, xmax_m, ymax_m], finite"), err


def test_malformed_landmarks_refused_before_a_firmware_in_the_loop_run(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + '[meta]\nlandmarks = "abc"\n')
    assert "meta.landmarks: must be" in sim_refused(capsys, tmp_path, f, "--firmware", "sil")


def test_well_formed_meta_path_and_landmarks_still_run(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + "[meta]\npath = [[0, 0], [3, 0]]\nlandmarks = [[1, 2, 0.08]]\n")
    assert cli.main(["sim", str(f), "--planner", "follow-path", "--duration", "1", "--quiet", "--no-plot", "--no-rrd",
                     "--out", str(tmp_path / "o")]) == 0


# huge durations, tiny steps, dense plants, many weeds: refused before anything is allocated
def test_sim_duration_beyond_the_step_limit_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sim", "canyon", "--duration", "1e7", "--no-plot", "--no-rrd", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("agnav sim: --duration 1e+07: ") and "5e+08 physics steps (29.8 GiB of trajectory)" in err
    assert "at most 2000000 steps: --duration <= 40000 s" in err and not out.exists()


@pytest.mark.parametrize("edit, line, field, why", [
    (("duration_s = 5.0\n", "duration_s = 5.0\ndt_s = 1e-9\ncontrol_hz = 1\n"), 4, "scenario.dt_s", "5e+09 physics steps"),
    (("duration_s = 5.0\n", "duration_s = 1e9\n"), 3, "scenario.duration_s", "at most 2000000 steps"),
    (("", "[[rows]]\npoints = [[0, 2], [5, 2]]\nplant_spacing_m = 1e-9\n"), _N + 3, "rows[0].plant_spacing_m",
     "1.5e+10 obstacle circles"),
    (("", "[[weeds]]\nregion = [0, 0, 1, 1]\ncount = 1000000000\n"), _N + 3, "weeds[0].count",
     "this many weeds would make 1e+09 obstacle circles; at most 1000000"),
])
def test_scenario_sizes_beyond_the_limits_are_refused_at_load_time(tmp_path, capsys, edit, line, field, why):
    f = tmp_path / "s.toml"
    old, new = edit
    f.write_text(SMALL.replace(old, new, 1) if old else SMALL + new)
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:{line}: {field}: ") and why in err, err


def test_run_scenario_refuses_a_run_beyond_the_step_limit():
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import load_scenario

    with pytest.raises(ValueError, match="at most 2000000 steps"):
        run_scenario(load_scenario("canyon"), duration_s=1e9)


def test_fault_suite_sends_a_scenario_that_is_really_not_utf8():
    from agnav_host.faults.host_faults import _case_corrupt_scenarios

    out = _case_corrupt_scenarios()
    assert out.passed, out.measured
    assert "not UTF-8 (Latin-1): exit 2" in out.measured and "cannot read scenario file: not UTF-8" in out.measured



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
    """The line of the wrong element, not the line of the key (``points = [``)."""
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
    """``[[goals]]`` inside a description is text, not a goal: goals[1]'s error names goals[1]'s line."""
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
    """Not "<root>: missing required table [scenario]": the file is named as empty."""
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

