"""Perception must not depend on how a laser numbers its beams: where its angles start (-pi..pi or
0..2 pi on a full-circle laser), which way it turns (a clockwise laser has a negative increment) or how
it is mounted. Also: health, end-of-row and ground tracking on the inputs a robot really delivers
(no scan at all, control steps without a scan, a robot standing still), and scan files that round-trip."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from agnav_host.perception import (GroundTracker, ProximityFollower, ProximityFollowerParams,
                                   RowParams, TiltedMount, clusters_from_scan, detect_rows, expected_ground_range_m,
                                   mixed_pixel_mask, scan_with_virtual_obstacles)
from agnav_host.perception._health import LaserWatchdog
from agnav_host.planning.row_navigator import RowNavigator, RowNavigatorParams
from agnav_host.scanio import ScanFileError, load_scan_csv, save_scan_csv
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import World, plants_along
from agnav_host.types import Goal, LaserScan, Observation, Pose2D


def _descending(s: LaserScan) -> LaserScan:
    """The same beams numbered the other way round (a clockwise laser)."""
    n = len(s.ranges_m)
    return replace(s, angle_min_rad=s.angle_min_rad + (n - 1) * s.angle_increment_rad,
                   angle_increment_rad=-s.angle_increment_rad, ranges_m=s.ranges_m[::-1].copy())


def _rows_world(seed: int = 3) -> World:
    rng = np.random.default_rng(seed)
    w = World()
    for k in range(4):  # rows at y = -1.125, -0.375, 0.375, 1.125: the robot's lane is centred on y = 0
        y = -1.125 + 0.75 * k
        w.add_circles(plants_along(np.array([[-3.0, y], [10.0, y]]), 0.15, 0.05, rng, 3, 0.015, None))
    return w


def _full_circle(w: World, y_m: float, yaw_rad: float, angle_min_rad: float, n: int = 720, rmax: float = 8.0) -> LaserScan:
    inc = 2.0 * math.pi / n
    r = w.raycast(0.0, y_m, yaw_rad, angle_min_rad, inc, n, rmax, 0.0)
    return LaserScan(angle_min_rad, inc, np.where(np.isfinite(r), r, np.inf), rmax, 0.0, Pose2D(0.0, y_m, yaw_rad))


def _hits(scan: LaserScan, post_xy: tuple[float, float]) -> tuple[int, float]:
    out = np.asarray(scan_with_virtual_obstacles(scan, Pose2D(), np.array([post_xy]), 0.2).ranges_m)
    fin = np.isfinite(out)
    return int(fin.sum()), float(out[fin].min()) if fin.any() else math.inf


@pytest.mark.parametrize("post", [(1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.0, 1.0)])
def test_virtual_posts_get_their_beams_however_the_laser_numbers_them(post):
    n, inc = 360, 2.0 * math.pi / 360
    scans = [LaserScan(-math.pi, inc, np.full(n, np.inf), 10.0), LaserScan(0.0, inc, np.full(n, np.inf), 10.0)]
    scans += [_descending(s) for s in scans]
    counts = [_hits(s, post) for s in scans]
    # a 0.2 m post 1 m away covers +-11.5 deg: 23 one-degree beams, its near side 0.8 m away
    for k, r in counts:
        assert k == 23 and r == pytest.approx(0.8, abs=1e-3)
    tim = LaserScan(math.radians(-135.0), math.radians(1.0), np.full(271, np.inf), 10.0)
    if post[0] >= 0.0:  # inside the 270 deg field of view
        assert _hits(tim, post) == _hits(_descending(tim), post) == (23, pytest.approx(0.8, abs=1e-3))


def test_tracker_keeps_an_object_whole_across_a_full_circle_lasers_seam():
    w = World()
    w.add_circles(np.array([[2.0, 0.0, 0.2]]))  # straight ahead: on the seam of a 0..2 pi laser
    for a0 in (-math.pi, 0.0):
        cl = clusters_from_scan(_full_circle(w, 0.0, 0.0, a0), world=False)
        assert len(cl) == 1, a0
        assert not cl[0].cut
        assert (cl[0].x_m, cl[0].y_m) == pytest.approx((2.0, 0.0), abs=0.05)


def test_laser_watchdog_faults_when_no_scan_ever_arrives():
    w = LaserWatchdog()
    h = w.health
    for k in range(31):  # 3 s of a laser that never delivers (unplugged at boot)
        h = w.update(None, 0.1 * k)
    assert not h.ok and "no scan" in h.reason and w.faults == 1
    w2 = LaserWatchdog()
    assert w2.update(None, 0.0).ok and w2.update(None, 0.4).ok  # within max_gap_s of the start: fine


@pytest.mark.parametrize("method", ["offset", "lsq", "triangle", "ransac", "hough"])
def test_row_detectors_agree_for_any_beam_numbering(method):
    w = _rows_world()
    ref = detect_rows(_full_circle(w, 0.1, 0.05, -math.pi), method, RowParams())
    assert ref.lateral_offset_m == pytest.approx(0.1, abs=0.03)
    for scan in (_full_circle(w, 0.1, 0.05, 0.0), _descending(_full_circle(w, 0.1, 0.05, -math.pi))):
        est = detect_rows(scan, method, RowParams())
        tol = 0.01 if method == "ransac" else 1e-9  # ransac samples by point order: the same within its scatter
        assert est.lateral_offset_m == pytest.approx(ref.lateral_offset_m, abs=tol)
        assert est.heading_rad == pytest.approx(ref.heading_rad, abs=tol)
        assert est.confidence == pytest.approx(ref.confidence, abs=10 * tol)


def test_offset_detector_with_a_laser_mounted_backwards():
    w = _rows_world()
    fwd = Laser2D(laser_preset("tim310")).scan(w, Pose2D(0.0, 0.1, 0.0), 0.0, None)
    back_mount = Pose2D(0.0, 0.0, math.pi)
    back = Laser2D(laser_preset("tim310"), back_mount).scan(w, Pose2D(0.0, 0.1, 0.0), 0.0, None)
    a = detect_rows(fwd, "offset", RowParams())
    b = detect_rows(back, "offset", RowParams(), mount=back_mount)
    assert a.lateral_offset_m == pytest.approx(0.1, abs=0.03)
    assert b.lateral_offset_m == pytest.approx(a.lateral_offset_m, abs=0.02)
    assert b.confidence > 0.5 and b.row_spacing_m == pytest.approx(a.row_spacing_m, abs=0.05)


def test_row_end_counts_only_fresh_scans():
    w = _rows_world()
    good = Laser2D(laser_preset("tim310")).scan(w, Pose2D(), 0.0, None)
    empty = LaserScan(good.angle_min_rad, good.angle_increment_rad, np.full(len(good.ranges_m), np.inf), good.range_max_m)
    nav = RowNavigator(RowNavigatorParams(end_scans=3))
    feed = [good, good, good, empty, None, None, None]
    for k, sc in enumerate(feed):
        nav.step(Observation(0.1 * k, Pose2D(), 0.4, 0.0, Goal(10.0, 0.0), sc))
    assert nav.phase == "follow"  # one empty scan and control steps without a scan: not a row end
    for k in range(3):
        nav.step(Observation(1.0 + 0.1 * k, Pose2D(), 0.4, 0.0, Goal(10.0, 0.0), empty))
    assert nav.phase == "exit"


@pytest.mark.parametrize("dist", [1.0, 3.0])
def test_proximity_follower_finds_a_row_further_than_its_default_search(dist):
    rng = np.random.default_rng(0)
    w = World()
    w.add_circles(plants_along(np.array([[-3.0, 0.0], [20.0, 0.0]]), 0.2, 0.05, rng, 1, 0.0, None))
    laser = Laser2D(laser_preset("tim561"))
    f = ProximityFollower(ProximityFollowerParams(side="left", distance_m=dist))
    for k in range(10):
        pose = Pose2D(0.05 * k, -dist, 0.0)
        f.step(Observation(0.1 * k, pose, 0.5, 0.0, Goal(10.0, 0.0), laser.scan(w, pose, 0.1 * k)))
    est = f.distance_estimate_m()
    assert est is not None and est == pytest.approx(dist, abs=0.1)


def test_a_smooth_wall_at_a_grazing_angle_is_not_mixed_pixels_but_an_edge_blend_is():
    # a wall 1 m to the left seen by a 1-degree laser: its points spread beyond 0.15 m apart from ~3 m on
    a = np.radians(np.arange(5.0, 90.0, 1.0))
    r = 1.0 / np.sin(a)
    r[r > 8.0] = np.nan
    assert not mixed_pixel_mask(a, r, 0.15)[np.isfinite(r)][1:-1].any()
    # foreground 2 m, background 5 m, one beam in between reading 3.5 m: still a mixed pixel
    a2 = np.radians(np.arange(7) - 3.0)
    r2 = np.array([2.0, 2.0, 2.0, 3.5, 5.0, 5.0, 5.0])
    assert mixed_pixel_mask(a2, r2, 0.15).tolist() == [False, False, False, True, False, False, False]


def test_ground_roughness_is_unknown_until_the_robot_moves():
    tm = TiltedMount(0.5, math.radians(20.0))
    a0, inc, n = math.radians(-45.0), math.radians(1.0), 91
    ang = a0 + inc * np.arange(n)
    rng = np.random.default_rng(0)

    def bumpy() -> LaserScan:
        return LaserScan(a0, inc, expected_ground_range_m(ang, 0.5, tm.tilt_rad) + rng.normal(0.0, 0.05, n), 10.0)

    standing = GroundTracker(tm)
    for _ in range(3):
        _, rough = standing.update(bumpy(), Pose2D())
    assert np.isnan(rough).all()  # two lines from one spot say nothing about the ground
    moving = GroundTracker(tm)
    for k in range(3):
        _, rough = moving.update(bumpy(), Pose2D(0.05 * k, 0.0, 0.0))
    assert np.nanmedian(rough) > 0.2  # +-5 cm relief reads rough
    _, still = moving.update(bumpy(), Pose2D(0.1, 0.0, 0.0))  # stopped: the last line's figure stays
    assert np.array_equal(still, rough, equal_nan=True)
    for beams in (0, 1):
        g = GroundTracker(tm)
        for k in range(2):
            _, r = g.update(LaserScan(a0, inc, np.full(beams, 1.0), 10.0), Pose2D(0.05 * k, 0.0, 0.0))
        assert r.shape == (beams,)


def test_scan_files_round_trip_and_comments_are_free_text(tmp_path):
    s = LaserScan(-1.0, 0.01, np.array([1.0, -np.inf, np.nan, 2.5, 0.0]), 10.0, 1.5, Pose2D(1.0, 2.0, 0.5))
    for scan in (s, _descending(s)):
        back = load_scan_csv(save_scan_csv(scan, tmp_path / "s.csv"))
        order = np.argsort(scan.angles_rad)
        assert np.allclose(back.angles_rad, np.asarray(scan.angles_rad)[order])
        want = np.asarray(scan.ranges_m)[order]
        assert np.array_equal(np.isfinite(back.ranges_m), np.isfinite(want))
        assert np.allclose(back.ranges_m[np.isfinite(want)], want[np.isfinite(want)])
    with pytest.raises(ValueError, match="at least 2 beams"):
        save_scan_csv(LaserScan(0.0, 0.01, np.array([1.0]), 10.0), tmp_path / "one.csv")
    f = tmp_path / "c.csv"
    f.write_text("# agnav-scan v1\n# operator=Anna, field=north\n# range_max_m=8\nangle_rad,range_m\n0.0,1.0\n0.1,2.0\n")
    assert load_scan_csv(f).range_max_m == 8.0
    f.write_text("# range_max_m=eight\nangle_rad,range_m\n0.0,1.0\n0.1,2.0\n")
    with pytest.raises(ScanFileError, match="range_max_m is not a number"):
        load_scan_csv(f)


def test_tracker_skips_a_scan_older_than_the_last_one():
    from agnav_host.perception import Cluster, ObstacleTracker

    tr = ObstacleTracker()
    for k in range(6):  # a walker at 0.5 m/s along +y
        tr.update_clusters([Cluster(2.0, 0.05 * k, 0.2, 10)], 0.1 * k)
    before = tr.tracks()
    late = tr.update_clusters([Cluster(2.0, 0.0, 0.2, 10)], 0.25)  # an old scan arriving late
    assert tr.stale_scans == 1
    assert [(t.x_m, t.y_m, t.vy_m_s) for t in late] == [(t.x_m, t.y_m, t.vy_m_s) for t in before]
    after = tr.update_clusters([Cluster(2.0, 0.30, 0.2, 10)], 0.6)
    assert after[0].vy_m_s == pytest.approx(0.5, abs=0.1)
