"""Localisation: marker posts seen by the laser, fused with odometry (agnav_host.localisation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.localisation import (FilterParams, LandmarkMap, PoseFilter, PostLocaliser, extrapolate, landmarks_from_meta,
                                     relative, sight_posts)
from agnav_host.localisation.landmarks import fit_post_centre
from agnav_host.sim.scenario import load_scenario
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import World
from agnav_host.types import Pose2D, norm_angle_rad

POSTS = LandmarkMap.from_rows([[3.0, 1.0, 0.08], [2.0, -2.0, 0.08], [4.0, -0.5, 0.08], [-1.5, 1.5, 0.08]])


def _world(posts: LandmarkMap = POSTS) -> World:
    w = World()
    w.add_circles(np.column_stack((posts.xy, posts.radius_m)))
    return w


def _laser() -> Laser2D:
    return Laser2D(laser_preset("tim310"))


def test_relative_inverts_compose() -> None:
    a, b = Pose2D(1.0, -2.0, 0.7), Pose2D(0.3, 0.4, -1.1)
    back = a.compose(relative(a, a.compose(b)))
    assert math.hypot(back.x_m - a.compose(b).x_m, back.y_m - a.compose(b).y_m) < 1e-12
    assert abs(norm_angle_rad(back.yaw_rad - a.compose(b).yaw_rad)) < 1e-12


def test_extrapolate_follows_a_circle() -> None:
    # a quarter circle of radius 1 m: speed 1 m/s, yaw rate 1 rad/s for pi/2 s
    p = extrapolate(Pose2D(0.0, 0.0, 0.0), 1.0, 1.0, math.pi / 2)
    assert p.x_m == pytest.approx(1.0, abs=1e-9)
    assert p.y_m == pytest.approx(1.0, abs=1e-9)
    assert p.yaw_rad == pytest.approx(math.pi / 2, abs=1e-9)


def test_fit_post_centre_recovers_the_centre_from_the_facing_arc() -> None:
    rng = np.random.default_rng(3)
    c = np.array([2.5, 0.4])
    r = 0.08
    # returns on the side facing the origin, small noise
    ang = math.atan2(-c[1], -c[0]) + np.linspace(-0.9, 0.9, 7)
    pts = c + r * np.column_stack((np.cos(ang), np.sin(ang))) + rng.normal(0, 0.003, (7, 2))
    cx, cy = fit_post_centre(pts[:, 0], pts[:, 1], r)
    assert math.hypot(cx - c[0], cy - c[1]) < 0.01


def test_sight_posts_gives_range_and_bearing_of_the_posts_in_view() -> None:
    pose = Pose2D(0.5, 0.2, 0.3)
    scan = _laser().scan(_world(), pose, 0.0, np.random.default_rng(0))
    seen = sight_posts(scan.ranges_m, scan.angles_rad, pose, POSTS, range_max_m=scan.range_max_m)
    assert {s.index for s in seen} == {0, 1, 2, 3}  # all within 4 m and 270 deg
    for s in seen:
        lx, ly = POSTS.xy[s.index]
        assert s.range_m == pytest.approx(math.hypot(lx - pose.x_m, ly - pose.y_m), abs=0.04)
        want = norm_angle_rad(math.atan2(ly - pose.y_m, lx - pose.x_m) - pose.yaw_rad)
        assert abs(norm_angle_rad(s.bearing_rad - want)) < math.radians(1.5)


def test_sight_posts_ignores_a_post_hidden_behind_an_obstacle_and_unknown_things() -> None:
    w = _world()
    w.add_circles(np.array([[1.5, 0.5, 0.2]]))  # an unknown obstacle between the sensor and post 0
    w.add_circles(np.array([[0.0, 2.5, 0.08]]))  # an unknown pole, far from every post
    pose = Pose2D(0.0, 0.0, 0.0)
    scan = _laser().scan(w, pose, 0.0, np.random.default_rng(1))
    seen = sight_posts(scan.ranges_m, scan.angles_rad, pose, POSTS, range_max_m=scan.range_max_m)
    assert 0 not in {s.index for s in seen}
    assert {1, 3} <= {s.index for s in seen}


def test_filter_removes_odometry_drift_with_posts() -> None:
    """Odometry with a heading bias (3 deg/m) and 5 % scale error drifts by decimetres; the posts
    keep the estimate within a few centimetres of the truth."""
    rng = np.random.default_rng(5)
    laser = _laser()
    w = _world()
    start = Pose2D(0.0, 0.0, 0.0)
    loc = PostLocaliser(start, POSTS)
    bare = PoseFilter(start, None)  # odometry only
    true = start
    odo = Pose2D()
    dt = 0.1
    worst = 0.0
    for k in range(60):  # 6 s at 0.6 m/s on a gentle left arc
        v, w_rate = 0.6, 0.12
        true = extrapolate(true, v, w_rate, dt)
        odo = extrapolate(odo, v * 1.05, w_rate + math.radians(3.0) * v, dt)
        t = (k + 1) * dt
        loc.odometry(odo.x_m, odo.y_m, odo.yaw_rad, t, v, w_rate)
        bare.odometry(odo, t, v, w_rate)
        scan = laser.scan(w, true, t, rng)
        loc.scan(scan.ranges_m, scan.angles_rad, t, scan.range_max_m)
        est = loc.pose_at(t)
        worst = max(worst, math.hypot(est.x_m - true.x_m, est.y_m - true.y_m))
    drift = math.hypot(bare.pose.x_m - true.x_m, bare.pose.y_m - true.y_m)
    assert drift > 0.15
    assert worst < 0.05
    assert abs(math.degrees(norm_angle_rad(loc.pose_at(6.0).yaw_rad - true.yaw_rad))) < 1.0
    assert loc.sighted > 50


def test_filter_extrapolates_over_the_odometry_latency() -> None:
    f = PoseFilter(Pose2D(), None)
    f.odometry(Pose2D(), 1.0, 0.5, 0.0)
    f.odometry(Pose2D(0.05, 0.0, 0.0), 1.1, 0.5, 0.0)
    assert f.pose_at(1.2).x_m == pytest.approx(0.10, abs=1e-9)  # 0.1 s later at 0.5 m/s
    f.odometry(Pose2D(0.04, 0.0, 0.0), 1.05, 0.5, 0.0)  # an older report: ignored
    assert f.pose.x_m == pytest.approx(0.05)


def test_filter_rejects_a_sighting_far_outside_its_uncertainty() -> None:
    from agnav_host.localisation import PostSighting

    f = PoseFilter(Pose2D(), POSTS, params=FilterParams())
    before = f.pose
    # post 0 is at range 3.16 m; report it 1 m off
    used = f.sightings([PostSighting(0, 4.16, math.atan2(1.0, 3.0), 5)], 0.0)
    assert used == 0 and f.rejected == 1 and f.pose == before


def test_timed_scenarios_list_their_posts_as_obstacles_too() -> None:
    for name in ("timed_static", "timed_dynamic", "timed_delay"):
        sc = load_scenario(name)
        posts = landmarks_from_meta(sc.meta)
        assert posts is not None and len(posts) >= 6
        for (x, y), r in zip(posts.xy, posts.radius_m):
            d = np.hypot(sc.world.circles[:, 0] - x, sc.world.circles[:, 1] - y)
            assert np.any((d < 1e-9) & (np.abs(sc.world.circles[:, 2] - r) < 1e-9)), f"{name}: post ({x}, {y}) not in the world"
