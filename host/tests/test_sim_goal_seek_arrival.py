"""The stand-in goal_seek controller reaches goals with a tight tolerance, slowing to a speed whose turning circle
fits near the goal."""

from __future__ import annotations

import math

import pytest

from agnav_host.sim.controller import GoalSeek, GoalSeekParams
from agnav_host.sim.runner import run_scenario
from agnav_host.sim.scenario import parse_scenario
from agnav_host.types import DriveCommand, Goal, Observation, Pose2D
from _scenario_text import scenario_text


@pytest.mark.parametrize("tol", [0.1, 0.05, 0.02])
def test_goal_seek_arrives_at_a_tight_tolerance(tol: float) -> None:
    r = run_scenario(parse_scenario(scenario_text(tol=tol)), "goal_seek", 0)
    assert r.end_reason == "arrived"
    assert r.metrics.final_position_error_m <= tol


def _goal_seek_cmd(d_m: float, bearing_deg: float) -> DriveCommand:
    b = math.radians(bearing_deg)
    goal = Goal(d_m * math.cos(b), d_m * math.sin(b), None, None, 0.01)
    return GoalSeek(GoalSeekParams()).step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))


def test_goal_seek_speed_fits_the_turning_circle_near_the_goal() -> None:
    p = GoalSeekParams()
    # 5 cm away, 35 deg off: 0.5 * (0.05 / 0.6 + 0.2) * cos^2 = 0.095 m/s would circle the goal
    cmd = _goal_seek_cmd(0.05, 35.0)
    cap = p.max_yaw_rate_rad_s * 0.05 / (2.0 * math.sin(math.radians(35.0)))
    assert cmd.speed_m_s == pytest.approx(cap)
    # far away the cap does not bind: max_speed * cos^2 of the chosen direction
    far = _goal_seek_cmd(3.0, 30.0)
    theta = far.yaw_rate_rad_s / p.yaw_gain  # not saturated here
    assert abs(theta) < p.max_yaw_rate_rad_s / p.yaw_gain
    assert far.speed_m_s == pytest.approx(p.max_speed_m_s * math.cos(theta) ** 2)
