"""What people type on the command line: options between positionals, negative values after abbreviated options
and as positionals, stray arguments, empty values, whole numbers in other forms, waits longer than a day,
option values that contradict each other, and a flash port that does not exist."""

from __future__ import annotations

from pathlib import Path

import pytest

from agnav_host import cli
from _cli_helpers import _no_user_config, free_port, nowhere, usage_error  # noqa: F401 (the fixture is autouse)


# ---- options between positionals, negative values after abbreviated options and as positionals ----
def _parse(argv: list[str]):
    return cli.parse_args(argv)


def test_param_takes_options_between_its_positionals_against_the_fake_robot(capsys):
    from agnav_host.link.fake import FakeRobot

    with FakeRobot() as fr:
        assert cli.main(["param", "set", "GOAL_TOL_MM", "--device", fr.device, "--no-tlog", "150"]) == 0
        assert fr.params["GOAL_TOL_MM"] == 150
        assert cli.main(["param", "get", "--device", fr.device, "--wait", "2", "--no-tlog", "GOAL_TOL_MM"]) == 0
    assert "GOAL_TOL_MM 150" in capsys.readouterr().out


@pytest.mark.parametrize("argv, dest, value", [
    (["param", "set", "AVOID_WAIT_MS", "-1e3", "--device", "tcp:h:1"], "value", "-1e3"),
    (["param", "set", "AVOID_WAIT_MS", "--device", "tcp:h:1", "-1e3"], "value", "-1e3"),
    (["param", "set", "AVOID_WAIT_MS", "-inf"], "value", "-inf"),
    (["plan", "--start", "0,0,0", "--goal", "3,5,90", "--start-steer", "-1e-3"], "start_steer_deg", -1e-3),
    (["rows", "--scan", "s.csv", "--mou", "-0.2,0.1,-5"], "mount", None),
    (["sim", "--out", "o", "--go", "-3,1"], "goal", (-3.0, 1.0, None)),
])
def test_negative_values_after_abbreviated_options_and_as_positionals(argv, dest, value):
    got = getattr(_parse(argv), dest)
    assert got is not None and (value is None or got == value), got


@pytest.mark.parametrize("goal, why", [("-3,abc,90", "pose must contain numbers, got '-3,abc,90'"),
                                       ("-3,5,90,", "pose must be X,Y,HEADING_DEG, got '-3,5,90,'"),
                                       ("-3,,90", "pose must contain numbers, got '-3,,90'")])
def test_a_malformed_negative_list_gets_the_options_own_message(capsys, goal, why):
    with pytest.raises(SystemExit) as e:
        cli.main(["plan", "--start", "0,0,0", "--goal", goal])
    assert e.value.code == 2
    assert f"agnav plan: error: argument --goal: {why}" in capsys.readouterr().err


def test_stray_arguments_are_named_with_the_subcommands_usage(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["param", "set", "A", "1", "2", "--device", nowhere()])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "usage: agnav param" in err and "agnav param: error: unrecognized arguments: 2" in err


# ---- calibrate --settle-s must be below the step's time limit, as in the config file -----------------
@pytest.mark.parametrize("opts, why", [
    (["--settle-s", "2", "--max-step-s", "0.5"], "--settle-s (2 s) must be < --max-step-s (0.5 s)"),
    (["--settle-s", "10"], "--settle-s (10 s) must be < [calibration] max_step_s (6 s)"),
    (["--max-step-s", "0.2"], "[calibration] settle_s (1 s) must be < --max-step-s (0.2 s)"),
])
def test_calibrate_settle_time_not_below_the_step_limit_is_refused_before_connecting(capsys, opts, why):
    assert cli.main(["calibrate", "steering", "--device", nowhere(), "--no-tlog", "--yes", *opts]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"agnav calibrate: {why}: a sweep step settles first, then measures"


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
    """"010" is ten, although Python's base-0 int() takes no leading zero."""
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
    """Refused before the command is shown, in agnav's words, not pio's after an upload attempt."""
    port = port.format(tmp=tmp_path)
    assert cli.main(["flash", "--dry-run", "--port", port]) == 1
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.startswith(f"agnav flash: --port {port}: {why}") and len(cap.err.strip().splitlines()) == 1


def test_flash_dry_run_to_a_device_that_exists_prints_the_command(capsys):
    assert Path("/dev/null").exists()
    assert cli.main(["flash", "--dry-run", "--port", "/dev/null"]) == 0
    assert "--upload-port /dev/null" in capsys.readouterr().out
