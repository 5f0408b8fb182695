"""Regression tests for reviewed simulator / metrics / localisation defects (one test or more per defect)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agnav_host.localisation import LandmarkMap, PoseFilter, PostLocaliser
from agnav_host.sim.controller import GoalSeek, GoalSeekParams
from agnav_host.sim.metrics import SUMMARY_KEYS, RunMetrics, bending_energy
from agnav_host.sim.runner import robot_spec, run_scenario, write_outputs
from agnav_host.sim.scenario import ScenarioError, builtin_text, load_scenario, parse_scenario
from agnav_host.types import DriveCommand, Goal, Observation, Pose2D

EMPTY = """
[scenario]
name = "review"
duration_s = %(dur)s
dt_s = %(dt)s
control_hz = %(hz)s
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0 }
[laser]
model = "tim561"
%(laser)s
[[goals]]
x_m = 3.0
y_m = 1.0
tolerance_m = %(tol)s
%(extra)s
"""


def _text(**over: object) -> str:
    return EMPTY % {**dict(dur=40.0, dt=0.02, hz=15.0, laser="", tol=0.3, extra=""), **over}


class _Recorder:
    """A controller that stands still and records when it was called."""

    uses_sonar = False

    def __init__(self) -> None:
        self.t_s: list[float] = []

    def reset(self) -> None:
        self.t_s.clear()

    def step(self, obs: Observation) -> DriveCommand:
        self.t_s.append(obs.t_s)
        return DriveCommand(0.0, 0.0)


# ---- 1: the planners' control period is the period at which the runner calls them ------------------
@pytest.mark.parametrize("name", ["corridor_obstacles", "flb_setup1"])
def test_robot_spec_control_dt_is_the_real_call_period(name: str) -> None:
    sc = load_scenario(name)
    rec = _Recorder()
    run_scenario(sc, "rec", 0, duration_s=3.0, controller=rec)
    period = float(np.diff(rec.t_s).mean())
    assert robot_spec(sc).control_dt_s == pytest.approx(period, abs=1e-12)


def test_control_hz_above_physics_rate_is_rejected_with_key_and_line() -> None:
    txt = builtin_text("corridor_obstacles").replace("control_hz = 15.0", "control_hz = 100.0")
    assert "control_hz = 100.0" in txt
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(txt, "<t>")
    line = next(i for i, s in enumerate(txt.splitlines(), 1) if s.startswith("control_hz"))
    assert ei.value.field == "scenario.control_hz" and ei.value.line == line
    sc = parse_scenario(_text(hz=50.0))  # exactly one call per physics step is fine
    assert robot_spec(sc).control_dt_s == pytest.approx(0.02)


# ---- 2: goal_seek reaches goals with a tight tolerance ------------------------------------------------
@pytest.mark.parametrize("tol", [0.1, 0.05, 0.02])
def test_goal_seek_arrives_at_a_tight_tolerance(tol: float) -> None:
    r = run_scenario(parse_scenario(_text(tol=tol)), "goal_seek", 0)
    assert r.end_reason == "arrived"
    assert r.metrics.final_position_error_m <= tol


def _goal_seek_cmd(d_m: float, bearing_deg: float) -> DriveCommand:
    b = math.radians(bearing_deg)
    goal = Goal(d_m * math.cos(b), d_m * math.sin(b), None, None, 0.01)
    return GoalSeek(GoalSeekParams()).step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))


def test_goal_seek_speed_fits_the_turning_circle_near_the_goal() -> None:
    p = GoalSeekParams()
    # 5 cm away, 35 deg off: the old 0.5 * (0.05 / 0.6 + 0.2) * cos^2 = 0.095 m/s circles the goal
    cmd = _goal_seek_cmd(0.05, 35.0)
    cap = p.max_yaw_rate_rad_s * 0.05 / (2.0 * math.sin(math.radians(35.0)))
    assert cmd.speed_m_s == pytest.approx(cap)
    # far away the cap does not bind: speed as before, max_speed * cos^2 of the chosen direction
    far = _goal_seek_cmd(3.0, 30.0)
    theta = far.yaw_rate_rad_s / p.yaw_gain  # not saturated here
    assert abs(theta) < p.max_yaw_rate_rad_s / p.yaw_gain
    assert far.speed_m_s == pytest.approx(p.max_speed_m_s * math.cos(theta) ** 2)


# ---- 3: reversals are counted apart and leave the bending energy continuous ---------------------------
def _back_off(tilt_deg: float, back_m: float = 0.5) -> np.ndarray:
    fwd = np.column_stack((np.linspace(0.0, 1.0, 101), np.zeros(101)))
    a = math.radians(180.0 - tilt_deg)
    s = np.linspace(0.0, back_m, 51)[1:]
    return np.vstack((fwd, np.column_stack((1.0 + s * math.cos(a), s * math.sin(a)))))


@pytest.mark.parametrize("tilt_deg", [0.0, 0.2, 5.0, 25.0])
def test_bending_energy_skips_a_reversal(tilt_deg: float) -> None:
    assert bending_energy(_back_off(tilt_deg)) == pytest.approx(0.0, abs=1e-9)


def test_reversals_are_counted_in_the_run_metrics() -> None:
    for tilt, want in ((0.0, 1), (0.2, 1), (60.0, 0)):
        xy = _back_off(tilt)
        t = np.arange(len(xy)) * 0.1
        m = RunMetrics.compute(t, xy, np.zeros(len(t)), np.ones(len(t)), np.zeros(len(t)), np.full(len(t), 1.0),
                               (0.5, 0.0), None, None, True, float(t[-1]))
        assert m.reversals == want
        assert m.to_dict()["reversals"] == want
    assert "reversals" in SUMMARY_KEYS
    # a path without reversals keeps its bending energy (circle of radius 2: length / R^2)
    a = np.linspace(0.0, 1.5 * math.pi, 2000)
    assert bending_energy(2.0 * np.column_stack((np.cos(a), np.sin(a)))) == pytest.approx(1.5 * math.pi / 2.0, rel=0.02)


def test_summary_json_has_reversals(tmp_path) -> None:
    r = run_scenario(parse_scenario(_text(dur=2.0)), "goal_seek", 0)
    write_outputs(r, tmp_path, plot=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(summary) == SUMMARY_KEYS and summary["reversals"] == 0


# ---- 4: the first odometry report counts ------------------------------------------------------------
def test_pose_filter_uses_the_first_odometry_report() -> None:
    start = Pose2D(1.0, 2.0, math.pi / 2)
    f = PoseFilter(start, None)
    f.odometry(Pose2D(1.0, 0.0, math.pi / 2), 2.0, 0.0, 0.0)
    want = start.compose(Pose2D(1.0, 0.0, math.pi / 2))
    assert (f.pose.x_m, f.pose.y_m, f.pose.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)
    f.odometry(Pose2D(2.0, 0.0, math.pi / 2), 3.0, 0.0, 0.0)
    want = start.compose(Pose2D(2.0, 0.0, math.pi / 2))
    assert (f.pose.x_m, f.pose.y_m, f.pose.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)


@pytest.mark.parametrize("start", [Pose2D(0.0, 0.0, 0.0), Pose2D(-1.0, 3.0, 0.7)])
def test_post_localiser_uses_the_first_odometry_report(start: Pose2D) -> None:
    loc = PostLocaliser(start, LandmarkMap(np.array([[10.0, 10.0]]), np.array([0.05])))
    loc.odometry(1.0, 0.0, math.pi / 2, stamp_s=2.0, speed_m_s=0.0, yaw_rate_rad_s=0.0)
    p, want = loc.pose_at(2.0), start.compose(Pose2D(1.0, 0.0, math.pi / 2))
    assert (p.x_m, p.y_m, p.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)
    loc.odometry(2.0, 0.0, math.pi / 2, stamp_s=3.0, speed_m_s=0.0, yaw_rate_rad_s=0.0)
    p, want = loc.pose_at(3.0), start.compose(Pose2D(2.0, 0.0, math.pi / 2))
    assert (p.x_m, p.y_m, p.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)


# ---- 5: laser max range 0 is a ScenarioError, not a raw ValueError ---------------------------------
@pytest.mark.parametrize("table, extra", [("laser", ""), ("tilted_laser", "[tilted_laser]\nmax_range_m = 0.0")])
def test_zero_laser_range_is_a_scenario_error(table: str, extra: str) -> None:
    txt = _text(laser="max_range_m = 0.0" if table == "laser" else "", extra=extra)
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(txt, "<t>")
    assert ei.value.field == f"{table}.max_range_m"
    assert ei.value.line == [i for i, s in enumerate(txt.splitlines(), 1) if s.startswith("max_range_m")][0]
