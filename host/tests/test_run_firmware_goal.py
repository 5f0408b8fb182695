"""`agnav run --goal X,Y` with the firmware's move-to-goal layer, against the SIL firmware served over
TCP: a GOAL_REACHED left over from the previous goal must not end the next run."""

from __future__ import annotations

import re

import pytest

OPEN_FIELD = """
[scenario]
name = "open_field"
duration_s = 200.0
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }
radius_m = 0.225
max_speed_m_s = 0.5
[sonar]
enabled = true
[[goals]]
x_m = 5.0
y_m = 0.0
"""


@pytest.fixture()
def open_field_sil():
    from agnav_host.sim import parse_scenario

    from _sil_server import serve_sil

    yield serve_sil(parse_scenario(OPEN_FIELD, "<open_field>"), speedup=1.0, duration_s=40.0)  # real time, like a robot


def _reached_at(out: str) -> float:
    m = re.search(r"goal reached \(firmware\) at t=([0-9.]+) s", out)
    assert m is not None, out
    return float(m.group(1))


def test_a_second_goal_is_driven_to_not_taken_as_reached_at_once(open_field_sil, capsys):
    from agnav_host.cli import main

    common = ["--device", open_field_sil, "--no-tlog", "--duration", "15"]
    assert main(["run", "--goal", "0.4,0", *common]) == 0
    _reached_at(capsys.readouterr().out)
    # 1.2 m further at GOAL_SPEED_MM_S 400, slowing inside GOAL_SLOW_MM: over 3 s. The previous run's
    # GOAL_REACHED used to end this one at t = 0.2 s with the robot where it was.
    assert main(["run", "--goal", "1.6,0", *common]) == 0
    assert _reached_at(capsys.readouterr().out) >= 3.0
