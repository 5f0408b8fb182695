"""Negative values typed after a space, in every command that takes them: ``--goal -3,5,90``, ``--start-steer-deg
-5``, ``--mount -0.2,0.1,-5``, ``param set NAME -1e3``; and options between positionals."""

from __future__ import annotations

import argparse
import json

import pytest

from agnav_host import cli
from agnav_host.link.fake import FakeRobot
from _cli_helpers import _no_user_config  # noqa: F401 (the fixture is autouse)

#: The least each command needs to parse (its required options and positionals)
MINIMAL = {"sim": ["--out", "o"], "plan": ["--start", "0,0,0", "--goal", "3,5,90"], "rows": ["--scan", "s.csv"],
           "bench": ["planners"], "calibrate": ["steering"], "param": ["list"], "key": ["show"], "replay": ["r.tlog"],
           "field": ["new", "--out", "f.toml"]}
NEGATIVES = ("-1", "-1,-2", "-1,-2,-3", "-0.5,2,-90")


def _negative_options() -> list[tuple[str, str, str, object]]:
    """(command, option, value, parsed value) for every option of every command whose type takes a negative number."""
    cli.build_parser()
    out = []
    for name, sub in cli.SUBCOMMANDS.items():
        for flags, kw in sub.args:
            kind = kw.get("type")
            if not flags[0].startswith("--") or kind is None or "choices" in kw:
                continue
            for text in NEGATIVES:
                try:
                    value = kind(text)
                except (argparse.ArgumentTypeError, ValueError):
                    continue
                out.append((name, flags[0], text, [value] if kw.get("action") == "append" else value))
                break
    return out


def test_the_commands_that_take_negative_values_are_all_found():
    found = {(c, o) for c, o, _, _ in _negative_options()}
    assert {("sim", "--goal"), ("plan", "--start"), ("plan", "--goal"), ("plan", "--start-steer-deg"),
            ("plan", "--goal-steer-deg"), ("rows", "--mount"), ("run", "--goal"), ("run", "--start"),
            ("run", "--row-half-width")} <= found


@pytest.mark.parametrize("command, option, text, value", _negative_options(), ids=lambda x: str(x))
def test_every_option_takes_a_negative_value_after_a_space(command, option, text, value):
    ns = cli.parse_args([command, *MINIMAL.get(command, []), option, text])
    dest = option.lstrip("-").replace("-", "_")
    assert getattr(ns, dest) == value


@pytest.mark.parametrize("argv, dest, value", [
    (["sim", "--goal", "-3,-5,-90", "--out", "o"], "goal", (-3.0, -5.0, -90.0)),
    (["sim", "-3", "--out", "o"], "scenario", "-3"),  # a positional that reads as a number (a file named -3)
    (["plan", "--start", "-1,-2,-30", "--goal", "-10,5,-90"], "goal", (-10.0, 5.0, -90.0)),
    (["plan", "--start", "0,0,0", "--goal", "3,5,90", "--goal-steer", "-5"], "goal_steer_deg", -5.0),
    (["run", "--goal", "-1,2", "--goal", "-3,-4,-45"], "goal", [(-1.0, 2.0, None), (-3.0, -4.0, -45.0)]),
    (["run", "--start", "-2,-1,-180"], "start", (-2.0, -1.0, -180.0)),
    (["run", "--row-half-width", "-0.1"], "row_half_width", -0.1),
    (["rows", "--scan", "s.csv", "--mount", "-0.2,0.1,-5"], "mount", (-0.2, 0.1, -5.0)),
    (["param", "set", "AVOID_WAIT_MS", "-1e3"], "value", "-1e3"),
    (["param", "set", "--device", "tcp:h:1", "AVOID_WAIT_MS", "--no-tlog", "-.5"], "value", "-.5"),
    (["param", "set", "AVOID_WAIT_MS", "--", "-7"], "value", "-7"),  # after the user's own "--"
    (["sil", "--param", "AVOID_WAIT_MS=-5"], "param", [("AVOID_WAIT_MS", -5)]),
])
def test_negative_values_of_each_command(argv, dest, value):
    assert getattr(cli.parse_args(argv), dest) == value


@pytest.mark.parametrize("argv, message", [
    (["sim", "--out", "o", "--duration", "-1"], "argument --duration: must be > 0, got '-1'"),
    (["plan", "--start", "0,0,0", "--goal", "-3,abc,90"], "argument --goal: pose must contain numbers"),
    (["run", "--goal", "-1"], "argument --goal: goal must be X,Y or X,Y,HEADING_DEG, got '-1'"),
    (["rows", "--scan", "s.csv", "--mount", "-1"], "argument --mount: mount must be X,Y[,YAW_DEG] (m, m, deg)"),
    (["sim", "--out", "o", "--seed", "-2"], "argument --seed: must be >= 0, got '-2'"),
])
def test_a_negative_value_an_option_refuses_gets_the_options_own_message(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    assert message in capsys.readouterr().err


def test_an_option_still_needs_its_value(capsys):
    with pytest.raises(SystemExit):
        cli.main(["sim", "--out", "--quiet"])
    assert "argument --out: expected one argument" in capsys.readouterr().err


def test_plan_with_negative_poses_plans(capsys):
    assert cli.main(["plan", "--start", "-2,-1,-90", "--goal", "-2,-8,-90", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feasible"] and 6.9 < out["path_length_m"] < 7.5


def test_param_set_of_a_negative_value_reaches_the_robot(capsys):
    """The value goes to the robot, which keeps its own when the value is out of the parameter's range."""
    with FakeRobot() as fr:
        assert cli.main(["param", "set", "--device", fr.device, "--no-tlog", "AVOID_WAIT_MS", "-1"]) == 1
        assert {m.param_value for m in fr.received_of("PARAM_SET")} == {-1.0}
        assert fr.params["AVOID_WAIT_MS"] == 1000
    assert "robot kept 1000 (asked -1; out of range?)" in capsys.readouterr().err
