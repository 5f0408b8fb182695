"""Host planners on inputs the reference experiments did not exercise: a far goal, a tight goal
tolerance, a reversing car, a laser whose beam count is not a multiple of the view's thinning, a stall
in front of a wall, a car-like robot's blind-spot memory, and parameter values that would divide by 0."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.planning.apf import ApfParams
from agnav_host.planning.base import RobotSpec, drive_command, local_view
from agnav_host.planning.flb import FlbParams, FlbPlanner
from agnav_host.planning.follow_path import PathFollower
from agnav_host.planning.pbf import PbfParams, PbfPlanner
from agnav_host.planning.vfh import VfhParams
from agnav_host.sim.runner import run_scenario
from agnav_host.sim.scenario import parse_scenario
from agnav_host.sim.sensors import laser_preset
from agnav_host.types import Goal, LaserScan, Observation, Pose2D

_FAR = """
[scenario]
name = "far_goal_behind_a_wall"
duration_s = 25.0
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0 }
[laser]
model = "tim561"
[[walls]]
points = [[3.0, -1.5], [3.0, 1.5]]
[[goals]]
x_m = 35.0
y_m = 0.0
"""


def test_follow_path_goes_round_a_wall_to_a_goal_beyond_its_default_map():
    # the goal is 35 m away, beyond the default 60 m map centred on the start: before, A* had no cell for
    # it and the robot drove the straight line into the wall at x = 3 m
    r = run_scenario(parse_scenario(_FAR), "follow-path", 0)
    assert r.end_reason != "collision"
    assert r.trajectory[-1, 1] > 6.0  # past the wall and on its way


def test_reversing_car_turns_the_way_it_is_asked():
    spec = RobotSpec(kinematics="ackermann", wheelbase_m=0.174, max_speed_m_s=1.0, max_steer_rad=math.radians(25.0))
    for v in (0.3, -0.3):
        cmd = drive_command(spec, v, 0.5)
        yaw_rate = cmd.speed_m_s * math.tan(cmd.steer_rad) / spec.wheelbase_m
        assert yaw_rate == pytest.approx(0.5, rel=0.05), v


@pytest.mark.parametrize("preset", ["tim561", "lms200"])
def test_view_thinning_keeps_the_last_beams(preset):
    ls = laser_preset(preset)
    res = VfhParams().resolution_rad
    for which in (0, ls.n_beams - 1):
        r = np.full(ls.n_beams, np.nan)
        r[which] = 0.5
        scan = LaserScan(ls.angle_min_rad, ls.resolution_rad, r, ls.max_range_m, 0.0, Pose2D())
        v = local_view(Observation(0.0, Pose2D(), 0.0, 0.0, Goal(5.0, 0.0), scan, None, {}), RobotSpec(), resolution_rad=res)
        assert len(v.xy) == 1, which


@pytest.mark.parametrize("length", [7.15, 4.75, 7.0])
def test_path_follower_end_heading_on_any_path_length(length):
    yaw = 2.0
    f = PathFollower()
    f.set_path(np.array([[0.0, 0.0], [length * math.cos(yaw), length * math.sin(yaw)]]))
    assert np.diff(f.s_arr).min() > 1e-6
    assert f.heading[-1] == pytest.approx(yaw, abs=1e-9)
    assert np.abs(f.kappa).max() < 1e-9


_TIGHT = """
[scenario]
name = "tight"
duration_s = 40.0
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0 }
[laser]
model = "tim561"
[sonar]
[[goals]]
x_m = 3.0
y_m = 1.0
tolerance_m = 0.05
"""


@pytest.mark.parametrize("planner", ["apf", "subsumption"])
def test_tight_goal_tolerance_is_reached(planner):
    r = run_scenario(parse_scenario(_TIGHT), planner, 0)
    assert r.end_reason == "arrived"
    assert r.metrics.final_position_error_m <= 0.05


def test_pbf_stall_escape_turns_to_the_goals_side():
    spec = RobotSpec()
    a = np.radians(np.arange(-135.0, 135.01, 1.0))
    with np.errstate(divide="ignore"):
        r = np.where(np.cos(a) > 0, 0.6 / np.cos(a), np.inf)  # a wall 0.6 m ahead ...
    r = np.where(np.abs(r * np.sin(a)) <= 3.0, r, np.inf)
    scan = LaserScan(a[0], math.radians(1.0), r, 10.0, 0.0, Pose2D())
    for side in (1.0, -1.0):  # ... and the goal behind it, 20 deg to the left, then to the right
        goal = Goal(5.0, side * 5.0 * math.tan(math.radians(20.0)), None, None, 0.3)
        pl = PbfPlanner(spec, PbfParams())
        pl.reset()
        cmd = None
        for k in range(300):
            cmd = pl.step(Observation(k * spec.control_dt_s, Pose2D(), 0.0, 0.0, goal, scan, None, {}))
            if pl._escape_left > 0 and k > 0:
                break
        assert pl._escape_left > 0, "the planner never stalled in front of the wall"
        assert cmd is not None and math.copysign(1.0, cmd.yaw_rate_rad_s) == side


def test_flb_remembers_returns_where_they_are_for_a_car_like_robot():
    spec = RobotSpec(kinematics="ackermann", radius_m=0.16, wheelbase_m=0.174, footprint_offset_m=0.087)
    pl = FlbPlanner(spec)
    pl.reset()
    a = np.radians(np.arange(-135.0, 135.01, 1.0))
    r = np.full(len(a), np.nan)
    r[np.argmin(np.abs(a - math.pi / 2))] = 0.5  # one return 0.5 m to the left of the reference point
    pl.step(Observation(0.0, Pose2D(), 0.0, 0.0, Goal(5.0, 0.0), LaserScan(a[0], math.radians(1.0), r, 10.0, 0.0, Pose2D()), None, {}))
    assert tuple(pl._mem_xy[0]) == pytest.approx((0.0, 0.5), abs=1e-9)


@pytest.mark.parametrize("make", [
    lambda: PbfParams(slow_radius_m=0.0),
    lambda: VfhParams(slow_radius_m=0.0),
    lambda: VfhParams(n_sectors=8, smooth=10),
    lambda: FlbParams(slow_radius_m=0.0),
    lambda: ApfParams(backoff_speed_m_s=0.0),
])
def test_planner_parameters_that_would_divide_by_zero_are_refused(make):
    with pytest.raises(ValueError):
        make()


def test_him_memory_counts_as_out_of_view_only_outside_the_lasers_beams():
    from agnav_host.planning.base import LocalView
    from agnav_host.planning.him import HimPlanner

    spec = RobotSpec()
    empty = LocalView(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0))
    n = 360
    for a0, inc, n_beams, point, blind in [
        (0.0, 2.0 * math.pi / n, n, (0.0, -1.0), False),  # full circle numbered 0..2 pi: the right side is seen
        (-math.pi, 2.0 * math.pi / n, n, (0.0, -1.0), False),
        (math.radians(-135.0), math.radians(1.0), 271, (-1.0, 0.0), True),  # straight behind a 270 deg laser
        (math.radians(135.0), math.radians(-1.0), 271, (-1.0, 0.0), True),  # the same laser turning clockwise
        (math.radians(135.0), math.radians(-1.0), 271, (0.0, -1.0), False),
    ]:
        pl = HimPlanner(spec)
        pl.reset()
        pl._mem_xy = np.array([point])
        pl._mem_t = np.zeros(1)
        scan = LaserScan(a0, inc, np.full(n_beams, np.inf), 10.0, 0.0, Pose2D())
        obs = Observation(0.0, Pose2D(), 0.0, 0.0, Goal(5.0, 0.0), scan, None, {})
        out = pl._wide_view(obs, empty, trapped=True)
        assert (len(out.xy) == 1) is blind, (a0, inc, point)
