"""Clustering into objects and tracking a moving object's velocity."""

import math

import numpy as np
import pytest

from agnav_host.perception import ObstacleTracker, TrackerParams, cluster_points, clusters_from_scan
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import Mover, World
from agnav_host.types import Pose2D


def test_a_round_post_becomes_one_cluster_with_its_size_and_centre():
    w = World()
    w.add_circles(np.array([[2.0, 0.5, 0.25], [3.0, -1.0, 0.1]]))
    scan = Laser2D(laser_preset("tim561")).scan(w, Pose2D(), 0.0, None)
    cl = sorted(clusters_from_scan(scan), key=lambda c: c.y_m)
    assert len(cl) == 2
    small, big = cl
    assert big.radius_m == pytest.approx(0.25, abs=0.05)
    assert small.radius_m == pytest.approx(0.1, abs=0.03)
    assert (big.x_m, big.y_m) == pytest.approx((2.0, 0.5), abs=0.05)
    assert (small.x_m, small.y_m) == pytest.approx((3.0, -1.0), abs=0.04)


def test_cluster_points_splits_at_gaps_and_drops_singletons():
    xy = np.array([[1.0, 0.0], [1.0, 0.05], [1.0, 0.1], [2.0, 1.0], [3.0, 0.0], [3.0, 0.05]])
    cl = cluster_points(xy, gap_m=0.2, min_points=2)
    assert [c.n_points for c in cl] == [3, 2]


@pytest.mark.parametrize("vx,vy", [(0.8, 0.0), (-0.5, 0.6)])
def test_tracker_estimates_the_velocity_of_a_moving_person(vx, vy):
    speed = math.hypot(vx, vy)
    start = (4.0, -1.0)
    end = (start[0] + vx * 20, start[1] + vy * 20)
    w = World(movers=[Mover(0.25, speed, (start, end), loop=False)])
    w.add_circles(np.array([[2.0, 2.0, 0.2]]))  # a static post
    las = Laser2D(laser_preset("tim561"))
    tr = ObstacleTracker(TrackerParams())
    rng = np.random.default_rng(0)
    tracks = []
    for k in range(45):  # 3 s at 15 Hz
        t = k / 15.0
        tracks = tr.update(las.scan(w, Pose2D(), t, rng), t)
    moving = [t for t in tracks if t.moving]
    static = [t for t in tracks if not t.moving]
    assert len(moving) == 1 and len(static) == 1
    m = moving[0]
    assert (m.vx_m_s, m.vy_m_s) == pytest.approx((vx, vy), abs=0.1)
    assert m.radius_m == pytest.approx(0.25, abs=0.08)
    assert m.speed_sigma_m_s < 0.2
    px, py = w.movers[0].position(44 / 15.0)
    assert (m.x_m, m.y_m) == pytest.approx((px, py), abs=0.1)
    assert static[0].speed_m_s < 0.1
    assert len(m.covariance) == 4
