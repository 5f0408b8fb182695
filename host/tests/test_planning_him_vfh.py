import math

import numpy as np
import pytest

from agnav_host.planning import RobotSpec
from agnav_host.planning.base import local_view
from agnav_host.planning.him import HimPlanner, escape_points, polar_grid
from agnav_host.planning.vfh import VfhParams, choose_direction, find_valleys, polar_histogram

from _planning_helpers import obs_with, scan_from_segments

SPEC = RobotSpec(radius_m=0.225)


def test_him_gap_selection_prefers_the_shorter_detour():
    """A wall 2 m ahead from y = -1.0 to y = +2.5, goal 4 m ahead: the gap on the right (y < -1) gives
    the smaller D = L + P, so the escape point chosen lies right of the wall's lower end."""
    scan = scan_from_segments([(2.0, -1.0, 2.0, 2.5)])
    obs = obs_with(scan, (4.0, 0.0))
    p = HimPlanner(SPEC)
    cmd = p.step(obs)
    assert p.subgoal_world is not None
    sx, sy = p.subgoal_world
    assert sy < -1.0 - SPEC.radius_m, f"escape point {sx:.2f}, {sy:.2f} is not beside the lower end"
    assert 1.5 < sx < 2.5
    assert cmd.yaw_rate_rad_s < 0.0  # turning right towards it


def test_him_gap_selection_mirrors():
    scan = scan_from_segments([(2.0, -2.5, 2.0, 1.0)])
    p = HimPlanner(SPEC)
    p.step(obs_with(scan, (4.0, 0.0)))
    assert p.subgoal_world is not None and p.subgoal_world[1] > 1.0 + SPEC.radius_m


def test_him_narrow_gap_is_not_chosen():
    """Two walls with a 0.4 m slot (narrower than the 0.45 m robot) straight ahead, goal behind it:
    the slot's edges yield candidates, but none survives the clearance check; the robot heads for an
    outer end instead."""
    scan = scan_from_segments([(2.0, -2.0, 2.0, -0.2), (2.0, 0.2, 2.0, 3.0)])
    view = local_view(obs_with(scan, (4.0, 0.0)), SPEC)
    ang, rng = polar_grid(view, math.radians(2.0), 6.0)
    pts = escape_points(ang, rng, SPEC.radius_m, 0.15, 6.0)
    assert len(pts) >= 2
    p = HimPlanner(SPEC)
    p.step(obs_with(scan, (4.0, 0.0)))
    assert p.subgoal_world is not None
    assert p.subgoal_world[1] < -2.0, f"chose {p.subgoal_world}"


def test_him_direct_path_goes_straight():
    scan = scan_from_segments([(2.0, 1.0, 2.0, 3.0)])  # obstacle off to the left only
    p = HimPlanner(SPEC)
    cmd = p.step(obs_with(scan, (4.0, 0.0)))
    assert p.subgoal_world is None and abs(cmd.yaw_rate_rad_s) < 1e-6 and cmd.speed_m_s > 0.2


def test_find_valleys_wraps_around():
    free = np.array([True, True, False, False, True, True, True, False, True])
    assert sorted(find_valleys(free)) == [(4, 3), (8, 3)]
    assert find_valleys(np.ones(5, dtype=bool)) == [(0, 5)]
    assert find_valleys(np.zeros(5, dtype=bool)) == []


def test_vfh_chooses_the_valley_nearest_the_goal():
    p = VfhParams(n_sectors=36, s_max=4)  # 10 deg sectors
    free = np.zeros(36, dtype=bool)
    free[20:23] = True  # narrow valley centred at +35 deg (sectors 20-22)
    free[10:13] = True  # narrow valley centred at -65 deg
    d = choose_direction(find_valleys(free), 36, math.radians(10.0), 0.0, p)
    assert d == pytest.approx(math.radians(35.0))
    d = choose_direction(find_valleys(free), 36, math.radians(-60.0), 0.0, p)
    assert d == pytest.approx(math.radians(-65.0))


def test_vfh_wide_valley_steers_inside_its_border():
    p = VfhParams(n_sectors=36, s_max=4)
    free = np.zeros(36, dtype=bool)
    free[18:30] = True  # 0..120 deg free; goal at -40 deg is blocked
    d = choose_direction(find_valleys(free), 36, math.radians(-40.0), 0.0, p)
    assert d == pytest.approx(math.radians(25.0))  # s_max / 2 sectors inside the near border (centre 5 deg)


def test_vfh_histogram_sees_a_wall_ahead_only():
    xy = np.column_stack((np.full(41, 1.0), np.linspace(-0.5, 0.5, 41)))
    h = polar_histogram(xy, 72, 2.5, 0.3, 0)
    centres = -math.pi + (2 * math.pi / 72) * (np.arange(72) + 0.5)
    assert h[np.abs(centres) < math.radians(20)].min() > 0.5
    assert h[np.abs(centres) > math.radians(90)].max() == 0.0


def test_him_departing_free_lets_the_body_move_off_a_wall_it_touches():
    from agnav_host.planning.base import free_distances_m
    from agnav_host.planning.him import departing_free_m

    wall = np.array([[x, -0.24] for x in np.linspace(-1.0, 1.0, 41)])  # 0.24 m to the right, robot r 0.225 + margin
    dirs = np.array([math.pi / 2, -math.pi / 2, 0.0])
    plain = free_distances_m(wall, dirs, 0.26, 1.0)
    off = departing_free_m(wall, dirs, 0.26, 1.0)
    assert plain[0] == 0.0  # the margin test blocks even moving away from the wall
    assert off[0] == pytest.approx(1.0)  # moving away (left) is free
    assert off[1] == 0.0 and off[2] == 0.0  # into it, or along it while overlapping, is not


def test_him_visited_cells_make_a_tried_escape_point_dearer():
    p = HimPlanner(SPEC)
    scan = scan_from_segments([(2.0, -1.0, 2.0, 2.5)])
    obs = obs_with(scan, (4.0, 0.0))
    pts = np.array([[1.8, -1.5], [1.8, 3.0]])
    assert np.all(p._visit_cost(obs, pts) == 0.0)
    for _ in range(60):  # four seconds at 15 Hz spent in the cell of the first point
        p._visit(p._cell(1.8, -1.5), SPEC.control_dt_s)
    cost = p._visit_cost(obs, pts)
    assert cost[0] == pytest.approx(min(p.params.visit_gain_m_s * 60 * SPEC.control_dt_s, p.params.visit_cap_m))
    assert cost[1] == 0.0
    p.reset()
    assert np.all(p._visit_cost(obs, pts) == 0.0)


def test_him_holds_its_escape_point_while_turning_towards_it():
    p = HimPlanner(SPEC)
    scan = scan_from_segments([(1.0, -1.0, 1.0, 1.0)])  # wall ahead: no direct path
    p.subgoal_world = (-1.0, 1.5)  # behind-left, chosen earlier
    cmd = p.step(obs_with(scan, (4.0, 0.0)))
    assert p.subgoal_world == (-1.0, 1.5)
    assert cmd.speed_m_s == 0.0 and cmd.yaw_rate_rad_s > 0.0  # turning left on the spot towards it
