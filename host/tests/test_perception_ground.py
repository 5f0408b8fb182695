"""Tilted-laser ground obstacles and ruts against analytic geometry."""

import math

import numpy as np
import pytest

from agnav_host.perception import (
    GroundParams,
    GroundTracker,
    RutParams,
    TiltedMount,
    detect_ground_obstacles,
    detect_ruts,
    expected_ground_range_m,
    ground_points,
    terrain_roughness,
)
from agnav_host.sim.sensors import TiltedLaser, laser_preset
from agnav_host.sim.world import Hole, Rut, Step, World
from agnav_host.types import LaserScan, Pose2D

H, TILT = 0.8, math.radians(20.0)
TM = TiltedMount(H, TILT, Pose2D(0.3, 0.0, 0.0))


def _laser() -> TiltedLaser:
    return TiltedLaser(laser_preset("lms200"), H, TILT, Pose2D(0.3, 0.0, 0.0))


def _scan(world: World, pose: Pose2D = Pose2D(), seed: int | None = 0) -> LaserScan:
    return _laser().scan(world, pose, 0.0, None if seed is None else np.random.default_rng(seed))


def test_flat_ground_range_matches_d_formula():
    s = _scan(World(), seed=None)
    D = expected_ground_range_m(s.angles_rad, H, TILT)
    # D = H / (sin(theta) cos(alpha)); the simulator marches the beams in 2 cm steps
    near = np.isfinite(s.ranges_m)
    assert near.sum() > 50
    assert np.allclose(s.ranges_m[near], D[near], atol=0.02)
    assert D[np.argmin(np.abs(s.angles_rad))] == pytest.approx(H / math.sin(TILT))
    assert expected_ground_range_m(np.array([math.pi / 2]), H, TILT)[0] == math.inf


def test_flat_ground_gives_no_obstacles_and_zero_height():
    s = _scan(World())
    g = detect_ground_obstacles(s, TM)
    assert not g.any
    z = ground_points(s, TM)[:, 2]
    assert np.nanmax(np.abs(z)) < 0.03


@pytest.mark.parametrize("lx,wy,depth", [(2.0, 0.5, 0.8), (0.5, 2.0, 0.8), (0.6, 0.5, 0.6), (3.0, 4.0, 1.0)])
def test_hole_on_the_scan_line_is_detected_inside_the_hole(lx, wy, depth):
    x_line = 0.3 + H / math.tan(TILT)  # where the scan line meets flat ground, m ahead
    hole = Hole(x_line + lx / 2 - 0.1, 0.0, lx, wy, depth)
    g = detect_ground_obstacles(_scan(World(holes=[hole])), TM)
    assert len(g.holes_xy) >= 2
    inside = hole.height_m(g.holes_xy[:, 0], g.holes_xy[:, 1]) < 0
    assert inside.mean() > 0.8
    assert not g.step.any()


def test_step_up_above_0_2_m_is_a_step_and_a_10_cm_kerb_is_not():
    # the beam meets the top of a step of height h only within (H - h) / tan(tilt) of the laser;
    # further away it hits the face lower down. Put the edge 1.2 m ahead (top in view for h <= 0.35 m).
    for h, expect in [(0.3, True), (0.1, False)]:
        st = Step(1.2, 0.0, 0.0, h, width_m=1.0)  # 1 m wide: edges along the scan line too
        g = detect_ground_obstacles(_scan(World(steps=[st])), TM)
        assert g.step.any() == expect, f"step of {h} m"
        if expect:
            assert np.all(np.abs(g.steps_xy[:, 1]) < 0.6)


def test_neighbour_height_jump_marks_the_higher_point():
    # synthetic scan: flat ground except one beam that hits something 0.3 m high
    a = np.radians(np.arange(-10, 11, 1.0))
    D = expected_ground_range_m(a, H, TILT)
    r = D.copy()
    r[10] = (H - 0.3) / (math.cos(a[10]) * math.sin(TILT))
    g = detect_ground_obstacles(LaserScan(float(a[0]), math.radians(1.0), r, 8.0), TiltedMount(H, TILT), GroundParams())
    assert np.flatnonzero(g.step).tolist() == [10]


def test_roughness_is_zero_on_planes_and_large_on_bumps():
    u, v = np.meshgrid(np.linspace(0, 1, 6), np.linspace(0, 2, 40), indexing="ij")
    plane = np.stack((u, v, 0.3 * u - 0.2 * v), axis=2)
    assert np.nanmax(terrain_roughness(plane)) < 1e-6
    amp, lam = 0.05, 0.3
    u, v = np.meshgrid(np.linspace(0, 0.05, 6), np.arange(0.0, 2.0, 0.01), indexing="ij")
    bumps = np.stack((u, v, amp * np.sin(2 * math.pi * v / lam)), axis=2)
    r = terrain_roughness(bumps, window=31)  # 31 samples of 1 cm: about one wavelength
    # analytic: normals (0, -A k cos(kv), 1)/norm; their RMS spread about the mean over a period
    k = 2 * math.pi / lam
    vv = np.linspace(0, lam, 2000, endpoint=False)
    n = np.stack((np.zeros_like(vv), -amp * k * np.cos(k * vv), np.ones_like(vv)), axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    expect = math.sqrt(float(((n - n.mean(axis=0)) ** 2).sum(axis=1).mean()))
    assert expect > 0.2  # impassable by ref 000's threshold
    assert float(np.nanmedian(r[:, 20:-20])) == pytest.approx(expect, rel=0.1)
    with pytest.raises(ValueError):
        terrain_roughness(np.zeros((1, 5, 3)))


def test_ground_tracker_reports_roughness_across_scan_lines():
    tr = GroundTracker(TM, lines=3)
    _, r0 = tr.update(_scan(World()), Pose2D(0.0, 0.0, 0.0))
    assert np.all(np.isnan(r0))
    _, r1 = tr.update(_scan(World(), Pose2D(0.05, 0, 0), seed=1), Pose2D(0.05, 0.0, 0.0))
    assert np.nanmedian(r1) < 0.2  # flat ground is passable


def test_two_ruts_edges_and_midline():
    x_line = 0.3 + H / math.tan(TILT)
    rut = Rut(((x_line - 3, 0.2), (x_line + 3, 0.2)), width_m=0.3, depth_m=0.12, spacing_m=1.5, count=2)
    est = detect_ruts(_scan(World(ruts=[rut])), TM, RutParams())
    assert len(est.ruts) == 2
    right, left = sorted(est.ruts, key=lambda r: r.centre_y_m)
    # grooves centred at 0.2 -+ 0.75 m; 2 cm below ground is reached 0.12 m from a groove's centre
    # (cosine profile: depth/2 (1 + cos(pi w)) = 0.02 at w = 0.77 of the half width)
    half = 0.15 * math.acos(2 * 0.02 / 0.12 - 1) / math.pi
    # tolerances: one beam spacing on the ground (1 deg at 2.7 m: 0.05 m); the inner wall of each
    # groove is hidden from the laser, and a mixed pixel can land on that edge
    for r, c in ((right, 0.2 - 0.75), (left, 0.2 + 0.75)):
        assert r.centre_y_m == pytest.approx(c, abs=0.04)
        assert r.width_m == pytest.approx(2 * half, abs=0.05)
        assert r.depth_m > 0.08
    assert est.midline_xy is not None
    assert est.midline_xy[1] == pytest.approx(0.2, abs=0.03)
    assert est.midline_xy[0] == pytest.approx(x_line, abs=0.1)


def test_no_ruts_on_flat_ground():
    assert detect_ruts(_scan(World()), TM).midline_xy is None


def test_rut_follower_steers_towards_the_midline():
    from agnav_host.perception import RutFollower, RutFollowerParams
    from agnav_host.types import Goal, Observation

    x_line = 0.3 + H / math.tan(TILT)
    for y_mid, sign in ((0.3, 1.0), (-0.3, -1.0)):
        rut = Rut(((x_line - 3, y_mid), (x_line + 3, y_mid)), width_m=0.3, depth_m=0.12, spacing_m=1.5, count=2)
        ctrl = RutFollower(RutFollowerParams(tilted=TM))
        obs = Observation(0.0, Pose2D(), 0.4, 0.0, Goal(0, 0), None, None, {"tilted_scan": _scan(World(ruts=[rut]))})
        cmd = ctrl.step(obs)
        assert sign * cmd.yaw_rate_rad_s > 0.02
