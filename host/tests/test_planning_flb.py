"""FLB planner (ref 000): how the fuzzy heading change is executed, and the blind-spot guard."""

import math

import numpy as np
import pytest

from agnav_host.planning import RobotSpec
from agnav_host.planning.flb import FlbParams, FlbPlanner
from agnav_host.types import Goal, LaserScan, Observation, Pose2D

from _planning_helpers import A0, INC, N_BEAMS, empty_scan, obs_with, scan_from_segments

SPEC = RobotSpec(radius_m=0.35, max_speed_m_s=0.5)


def test_heading_change_is_spread_over_travel_when_moving_and_turned_on_the_spot_when_stopped():
    p = FlbPlanner(SPEC, FlbParams(steer_distance_m=0.4, turn_time_s=0.7))
    turn = math.radians(30)
    assert p.yaw_rate(turn, 0.0, 5.0) == pytest.approx(turn / 0.7)  # standing: in place
    v = 0.5
    assert p.yaw_rate(turn, v, 5.0) == pytest.approx(v * turn / 0.4)  # curvature dphi / L
    assert p.yaw_rate(turn, 0.1, 5.0) / 0.1 == pytest.approx(turn / 0.4)  # same curvature at SLOW speed
    # an obstacle 0.2 m ahead shortens the stretch: the turn must be done before it
    assert p.yaw_rate(turn, 0.1, 0.2) == pytest.approx(0.1 * turn / 0.2)
    assert p.yaw_rate(turn, 0.1, 0.0) == pytest.approx(0.1 * turn / FlbParams().min_steer_distance_m)


def test_open_field_drives_to_the_goal_with_a_gentle_curvature():
    p = FlbPlanner(SPEC)
    cmd = p.step(obs_with(empty_scan(), (3.0, 3.0)))
    assert cmd.speed_m_s > 0.3
    kappa = cmd.yaw_rate_rad_s / cmd.speed_m_s
    assert 0.0 < kappa <= math.radians(45) / p.params.steer_distance_m + 1e-9


def _obs_at(x: float, y: float, yaw: float, scan: LaserScan, t: float) -> Observation:
    pose = Pose2D(x, y, yaw)
    return Observation(t, pose, 0.1, 0.0, Goal(4.0, -3.0), LaserScan(scan.angle_min_rad, scan.angle_increment_rad,
                       scan.ranges_m, scan.range_max_m, scan.stamp_s, Pose2D(x + 0.3 * math.cos(yaw), y + 0.3 * math.sin(yaw), yaw)),
                       None, {})


def test_a_passed_obstacle_in_the_blind_spot_blocks_a_turn_towards_it():
    """A post seen ahead-right is later beside the robot, behind the laser's mounting line: FLB, which
    would now turn right towards the goal, must not swing into it."""
    p = FlbPlanner(SPEC)
    # first scan: a wall segment 0.5-0.9 m ahead of the centre, 0.37 m to its right (the laser is
    # mounted 0.3 m ahead of the centre; the segment is given in the laser's frame)
    seen = scan_from_segments([(0.2, -0.37, 0.6, -0.37)])
    p.step(_obs_at(0.0, 0.0, 0.0, seen, 0.0))
    # later: the robot has moved 0.6 m; the segment is beside it, the laser sees nothing
    nothing = LaserScan(A0, INC, np.full(N_BEAMS, np.nan), 10.0, 0.0, Pose2D())
    guarded = p.step(_obs_at(0.6, 0.0, 0.0, nothing, 1.0))
    fresh = FlbPlanner(SPEC).step(_obs_at(0.6, 0.0, 0.0, nothing, 1.0))
    assert fresh.yaw_rate_rad_s < -0.05  # without memory it turns right to the goal
    assert not (guarded.yaw_rate_rad_s < 0.0 and guarded.speed_m_s > 0.0)  # with it: no swing into the wall
