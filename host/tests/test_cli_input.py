"""What the CLI does with what people type: negative numbers after a space on any option, numbers that
are not numbers (nan, inf, negative counts), output folders that cannot be one, unknown scenarios."""

import argparse

import pytest

from agnav_host.cli import finite_float, int_in, main, parse_args, positive_float
from agnav_host.cli.argv import Options, arrange


def test_any_value_option_takes_a_negative_number_after_a_space():
    assert parse_args(["sim", "--goal", "-3,5,90", "--out", "o"]).goal == (-3.0, 5.0, 90.0)
    # --duration: joined because it takes a value (as the parser declares it)
    top = Options.of([(("-h", "--help"), False), (("--log-level",), True)])
    sim = {"sim": Options.of([(("--duration",), True), (("--goal",), True), (("--out",), True), (("--quiet",), False)])}
    assert arrange(["sim", "--duration", "-1e0", "--out", "o"], top, sim) == ["sim", "--duration=-1e0", "--out=o"]
    assert arrange(["sim", "--goal", "-inf,3,90", "--out", "o"], top, sim)[1] == "--goal=-inf,3,90"
    # a flag is never joined with what follows it, and a non-number is left alone
    assert arrange(["sim", "--quiet", "-1", "--out", "-x"], top, sim) == ["sim", "--quiet", "--out", "-x", "--", "-1"]
    # abbreviations as argparse resolves them; the positionals last, in the order typed
    assert arrange(["sim", "--dur", "-2", "s.toml", "--q"], top, sim) == ["sim", "--dur=-2", "--q", "--", "s.toml"]
    # agnav's own options before the command, its value joined as typed
    assert arrange(["--log-level", "debug", "sim", "--goal", "-1,2"], top, sim) == ["--log-level", "debug", "sim",
                                                                                   "--goal=-1,2"]


def test_negative_duration_is_refused_with_the_options_name(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["sim", "him_setup1", "--duration", "-1e0", "--out", str(tmp_path)])
    assert e.value.code == 2
    assert "argument --duration: must be > 0, got '-1e0'" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--duration", "nan"], "argument --duration: must be a finite number"),
    (["--duration", "inf"], "argument --duration: must be a finite number"),
    (["--duration", "0"], "argument --duration: must be > 0"),
    (["--seed", "-1"], "argument --seed: must be >= 0"),
    (["--seed", "1.5"], "argument --seed: expected a whole number"),
    (["--goal", "-inf,3,90"], "goal values must be finite"),
])
def test_sim_refuses_bad_numbers_before_running(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as e:
        main(["sim", "him_setup1", "--out", str(tmp_path), "--quiet", *argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_sim_out_that_is_a_file_is_refused_before_the_run(tmp_path, capsys):
    f = tmp_path / "summary"
    f.write_text("x")
    assert main(["sim", "him_setup1", "--out", str(f), "--quiet"]) == 2
    assert f"--out {f}: is a file, not a folder" in capsys.readouterr().err
    assert f.read_text() == "x"


def test_sim_out_that_cannot_be_made_is_refused(tmp_path, capsys):
    ro = tmp_path / "file"
    ro.write_text("")
    assert main(["sim", "him_setup1", "--out", str(ro / "sub"), "--quiet"]) == 2
    assert "cannot create the folder" in capsys.readouterr().err


def test_unknown_scenario_message_names_it_plainly(tmp_path, capsys):
    assert main(["sim", "nosuch", "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "agnav sim: nosuch: unknown scenario 'nosuch'" in err and "<name>" not in err
    assert "curvy_row" in err  # the built-ins are listed


@pytest.mark.parametrize("argv, message", [
    (["--duration", "nan"], "argument --duration: must be a finite number"),
    (["--speedup", "-2"], "argument --speedup: must be > 0"),
    (["--seed", "-1"], "argument --seed: must be >= 0"),
])
def test_sil_refuses_bad_numbers(capsys, argv, message):
    with pytest.raises(SystemExit) as e:
        main(["sil", "him_setup1", "--tcp", "tcp:127.0.0.1:0", *argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err


def test_number_types():
    assert finite_float("-1e-3") == -0.001
    assert positive_float("2.5") == 2.5
    for bad in ("nan", "-inf", "abc"):
        with pytest.raises(argparse.ArgumentTypeError):
            finite_float(bad)
    byte = int_in(0, 255)
    assert byte("0x10") == 16
    with pytest.raises(argparse.ArgumentTypeError, match=r"must be 0\.\.255, got '256'"):
        byte("256")


@pytest.mark.parametrize("scenario, planner, needs", [
    ("crop_rows", "subsumption", "[sonar]"),  # no sonar ring in that field
    ("fault_yard", "him", "[laser]"),  # sonar only
    ("ruts", "vfh+ground-guard", "[laser]"),  # a tilted laser only
])
def test_sim_refuses_a_planner_whose_sensor_the_scenario_lacks(tmp_path, capsys, scenario, planner, needs):
    """Before the run, not at its first step with an InvalidObservation traceback."""
    assert main(["sim", scenario, "--planner", planner, "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"planner {planner!r} needs a {needs}" in err and "Traceback" not in err
    assert "planners that run on it:" in err and "goal_seek" in err
    assert not (tmp_path / "summary.json").exists()
