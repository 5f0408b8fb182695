import json

import pytest

from agnav_host.cli import build_parser, main, parse_goal
from agnav_host.sim import SUMMARY_KEYS, builtin_names


def test_scenarios_lists_builtins(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    for n in builtin_names():
        assert n in out
    assert "(default)" in out


def test_sim_default_scenario_succeeds(tmp_path, capsys):
    assert main(["sim", "--out", str(tmp_path), "--seed", "1", "--quiet", "--no-plot"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(summary) == SUMMARY_KEYS
    assert summary["success"] is True
    assert (tmp_path / "trajectory.csv").read_text().startswith("t_s,x_m,y_m,yaw_rad")


def test_goal_with_negative_numbers(tmp_path):
    ns = build_parser().parse_args(["sim", "--goal=-3,5,90", "--out", "x"])
    assert ns.goal == (-3.0, 5.0, 90.0)
    assert main(["sim", "canyon", "--goal", "-3,5,90", "--duration", "1", "--out", str(tmp_path), "--quiet", "--no-plot"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["final_heading_error_deg"] is not None


def test_parse_goal_forms_and_errors():
    assert parse_goal("-3.5,-2") == (-3.5, -2.0, None)
    assert parse_goal("1e1,-2,-45") == (10.0, -2.0, -45.0)
    import argparse
    with pytest.raises(argparse.ArgumentTypeError):
        parse_goal("1,2,3,4")
    with pytest.raises(argparse.ArgumentTypeError):
        parse_goal("a,b")


def test_unknown_planner_and_bad_scenario(tmp_path, capsys):
    assert main(["sim", "--planner", "nope", "--out", str(tmp_path), "--quiet"]) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text('[scenario]\nname = "b"\n[robot]\nmodel = "diff_drive"\nstart = { x_m = 0, y_m = 0 }\n[[goals]]\nx_m = "a"\ny_m = 0\n')
    assert main(["sim", str(bad), "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "goals[0].x_m" in err and ":7:" in err
