import math

import numpy as np
import pytest

from agnav_host.sim import World, cast_rays, laser_preset
from agnav_host.sim.sensors import Laser2D, TiltedLaser
from agnav_host.sim.world import Hole, Step, box_segments
from agnav_host.types import Pose2D

N, INC, A0 = 811, math.radians(270) / 810, -math.radians(135)


def test_wall_at_known_distance():
    segs = np.array([[3.0, -20.0, 3.0, 20.0]])
    r = cast_rays(0.0, 0.0, 0.0, A0, INC, N, 10.0, segs, np.zeros((0, 3)))
    ang = A0 + INC * np.arange(N)
    hit = np.isfinite(r)
    assert np.allclose(r[hit] * np.cos(ang[hit]), 3.0, atol=1e-9)
    assert np.all(np.abs(ang[hit]) < math.acos(0.3) + INC)  # beyond 10 m range -> no return
    assert r[405] == pytest.approx(3.0)


def test_circle_analytic_distance_and_edges():
    circ = np.array([[5.0, 0.0, 1.0]])
    r = cast_rays(0.0, 0.0, 0.0, A0, INC, N, 10.0, np.zeros((0, 4)), circ)
    ang = A0 + INC * np.arange(N)
    hit = np.isfinite(r)
    # exact: t = 5 cos a - sqrt(1 - 25 sin^2 a)
    expect = 5 * np.cos(ang[hit]) - np.sqrt(1 - 25 * np.sin(ang[hit]) ** 2)
    assert np.allclose(r[hit], expect, atol=1e-9)
    assert np.all(np.abs(ang[hit]) <= math.asin(0.2) + 1e-9)
    assert np.all(~np.isfinite(r[np.abs(ang) > math.asin(0.2) + INC]))


def test_objects_behind_and_wrapping_sector():
    # a full-circle sensor (scan centred backwards) sees a wall behind the robot
    n, inc = 360, math.radians(1.0)
    segs = np.array([[-2.0, -5.0, -2.0, 5.0]])
    r = cast_rays(0.0, 0.0, 0.0, -math.pi, inc, n, 10.0, segs, np.zeros((0, 3)))
    assert r[0] == pytest.approx(2.0)
    assert not np.isfinite(r[180])


def test_matches_brute_force_on_random_world():
    rng = np.random.default_rng(0)
    p = rng.uniform(-8, 8, (60, 2))
    segs = np.column_stack((p, p + rng.uniform(-2, 2, (60, 2))))
    circ = np.column_stack((rng.uniform(-8, 8, (60, 2)), rng.uniform(0.05, 0.5, 60)))
    r = cast_rays(0.3, -0.2, 0.7, A0, INC, N, 10.0, segs, circ)
    # brute force with a dense march
    ang = 0.7 + A0 + INC * np.arange(N)
    best = np.full(N, np.inf)
    for i, a in enumerate(ang):
        d = np.array([math.cos(a), math.sin(a)])
        for x0, y0, x1, y1 in segs:
            e = np.array([x1 - x0, y1 - y0])
            den = d[0] * e[1] - d[1] * e[0]
            if abs(den) < 1e-12:
                continue
            q = np.array([x0 - 0.3, y0 + 0.2])
            t = (q[0] * e[1] - q[1] * e[0]) / den
            s = (q[0] * d[1] - q[1] * d[0]) / den
            if t >= 0 and 0 <= s <= 1:
                best[i] = min(best[i], t)
        for cx, cy, rr in circ:
            f = np.array([0.3 - cx, -0.2 - cy])
            b = f @ d
            c = f @ f - rr * rr
            disc = b * b - c
            if disc >= 0:
                t = -b - math.sqrt(disc) if c > 0 else -b + math.sqrt(disc)
                if t >= 0:
                    best[i] = min(best[i], t)
    best[best > 10.0] = np.inf
    assert np.array_equal(np.isfinite(r), np.isfinite(best))
    assert np.allclose(r[np.isfinite(r)], best[np.isfinite(best)], atol=1e-9)


def test_laser_presets_and_no_return_values():
    assert laser_preset("tim561").n_beams == 811
    assert laser_preset("lms200").n_beams == 181
    assert laser_preset("tim310").n_beams == 271
    w = World()
    w.add_segments(box_segments(0, 0, 4, 4))
    scan = Laser2D(laser_preset("tim310")).scan(w, Pose2D(), 0.0, np.random.default_rng(1))
    assert np.all(np.isfinite(scan.ranges_m) | np.isnan(scan.ranges_m))
    assert np.nanmax(scan.ranges_m) <= 4.0
    with pytest.raises(ValueError, match="known"):
        laser_preset("nope")


def test_mixed_pixels_lie_between_foreground_and_background():
    w = World()
    w.add_segments(np.array([[6.0, -20.0, 6.0, 20.0]]))
    w.add_circles([[2.0, 0.0, 0.3]])
    spec = laser_preset("tim561")
    from dataclasses import replace
    spec = replace(spec, mixed_pixel_prob=1.0, range_std_m=0.0)
    las = Laser2D(spec)
    exact = las.exact_ranges(w, Pose2D())
    noisy = las.scan(w, Pose2D(), 0.0, np.random.default_rng(2)).ranges_m
    changed = np.nonzero(np.isfinite(exact) & (np.abs(noisy - exact) > 1e-9))[0]
    assert len(changed) >= 2
    assert np.all((noisy[changed] > 1.6) & (noisy[changed] < 6.1))


def test_tilted_laser_sees_flat_ground_hole_and_step():
    spec = laser_preset("lms200")
    tl = TiltedLaser(spec, height_m=0.5, tilt_rad=math.radians(20))
    w = World()
    r = tl.exact_ranges(w, Pose2D())
    mid = spec.n_beams // 2
    assert r[mid] == pytest.approx(0.5 / math.sin(math.radians(20)), abs=0.02)
    w.holes.append(Hole(1.4, 0.0, 0.4, 2.0, 0.5))  # flat-ground hit at 1.374 m ahead falls in the hole
    assert tl.exact_ranges(w, Pose2D())[mid] > r[mid] + 0.1
    w2 = World(steps=[Step(1.0, 0.0, 0.0, 0.2)])  # a 20 cm step up at 1 m
    assert tl.exact_ranges(w2, Pose2D())[mid] < r[mid] - 0.1
