"""Scan matching (ICP, the correlative search) and the pose graph, on synthetic scans and graphs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from _slam_helpers import scan_at
from agnav_host.localisation.pose_graph import PoseGraph
from agnav_host.localisation.scan_match import (
    LikelihoodGrid,
    PointMap,
    compose,
    correlative_search,
    icp_point_to_line,
    relative,
    scan_points,
    transform_points,
)

ANG0, INC = -math.pi / 2, math.pi / 180


def _points(pose: np.ndarray, seed: int = 0) -> np.ndarray:
    r = scan_at(pose, np.random.default_rng(seed))
    r[r > 30] = np.nan
    return scan_points(r, ANG0, INC, np.zeros(3))


def test_compose_and_relative_are_inverse():
    a, b = np.array([1.0, -2.0, 2.5]), np.array([0.3, 0.7, -3.0])
    np.testing.assert_allclose(compose(a, relative(a, b)), b, atol=1e-12)


def test_icp_recovers_a_small_offset_between_two_scans_of_the_hall():
    ref_pose = np.array([6.0, 2.0, 0.0])
    true = np.array([6.4, 2.1, math.radians(3.0)])
    ref = PointMap(transform_points(ref_pose, _points(ref_pose, 1)))
    src = _points(true, 2)
    res = icp_point_to_line(src, ref, ref_pose)  # started 0.41 m and 3 deg off
    assert np.hypot(*(res.pose[:2] - true[:2])) < 0.02
    assert abs(math.degrees(res.pose[2] - true[2])) < 0.5
    assert res.overlap > 0.85 and res.rms_m < 0.04


def test_icp_prior_holds_the_direction_a_corridor_leaves_open():
    # two parallel walls 2 m apart and 40 m long: nothing fixes x along them
    xs = np.arange(-20, 20, 0.05)
    ref = PointMap(np.concatenate([np.column_stack([xs, np.full_like(xs, 1.0)]),
                                   np.column_stack([xs, np.full_like(xs, -1.0)])]))
    src = np.concatenate([np.column_stack([xs[200:600] - 0.3, np.full(400, 1.05)]),
                          np.column_stack([xs[200:600] - 0.3, np.full(400, -0.95)])])
    prior = np.array([0.7, 0.0, 0.0])
    res = icp_point_to_line(src, ref, prior, prior=prior, prior_info=np.diag([1.0, 1.0, 1.0]))
    assert res.pose[0] == pytest.approx(0.7, abs=1e-3), "along the corridor the prior decides"
    assert res.pose[1] == pytest.approx(-0.05, abs=5e-3), "across it the walls do"
    w = np.linalg.eigvalsh(res.hessian)
    assert w[0] < 1e-3 * w[-1], "the Hessian says the match holds nothing along the corridor"


def test_correlative_search_finds_a_match_metres_and_degrees_off():
    ref_pose = np.array([12.0, 2.0, 0.0])
    true = np.array([13.5, 2.6, math.radians(-12.0)])
    ref_pts = transform_points(ref_pose, _points(ref_pose, 3))
    grid = LikelihoodGrid(ref_pts, res_m=0.05, sigma_m=0.08, coarse=6)
    src = _points(true, 4)
    sr = correlative_search(src, grid, ref_pose, 2.5, math.radians(20))
    assert np.hypot(*(sr.pose[:2] - true[:2])) < 0.1 and abs(math.degrees(sr.pose[2] - true[2])) < 1.5
    assert sr.score > 0.6
    # ICP from the search's answer lands on the truth
    res = icp_point_to_line(src, PointMap(ref_pts), sr.pose)
    assert np.hypot(*(res.pose[:2] - true[:2])) < 0.02


def _square_graph(odo_yaw_bias: float = math.radians(3.0)) -> tuple[PoseGraph, np.ndarray]:
    """A 4 x 4 m square driven in 1 m steps (16 poses, back at the start) with a yaw bias per step."""
    truth = []
    for side in range(4):
        for k in range(4):
            th = side * math.pi / 2
            c, s = math.cos(th), math.sin(th)
            base = [np.array([0, 0]), np.array([4, 0]), np.array([4, 4]), np.array([0, 4])][side]
            truth.append([base[0] + c * k, base[1] + s * k, th])
    truth = np.array(truth, dtype=float)
    g = PoseGraph()
    info = np.diag([100.0, 100.0, 400.0])
    pose = truth[0].copy()
    g.add_node(pose)
    for i in range(1, len(truth)):
        z = relative(truth[i - 1], truth[i])
        z[2] += odo_yaw_bias
        pose = compose(pose, z)
        g.add_node(pose)
        g.add_edge(i - 1, i, z, info)
    return g, truth


def test_pose_graph_closes_a_loop_and_spreads_the_drift():
    g, truth = _square_graph()
    before = np.hypot(*(g.poses[-1, :2] - truth[-1, :2]))
    g.add_edge(15, 0, relative(truth[15], truth[0]), np.diag([1e4, 1e4, 1e4]), loop=True)
    res = g.optimise(iterations=30)
    after = np.hypot(*(g.poses[:, :2] - truth[:, :2]).T)
    assert before > 1.0
    assert after.max() < 0.35 and after[-1] < 0.1
    assert res.cost_end < 1e-2 * res.cost_start and res.rejected == 0


def test_pose_graph_downweights_a_wrong_loop_closure():
    g, truth = _square_graph(odo_yaw_bias=0.0)
    g.add_edge(15, 0, relative(truth[15], truth[0]), np.diag([1e4, 1e4, 1e4]), robust=True)
    g.add_edge(8, 0, np.array([0.5, 0.0, 0.0]), np.diag([1e4, 1e4, 1e4]), robust=True)  # a false closure
    res = g.optimise(iterations=30)
    err = np.hypot(*(g.poses[:, :2] - truth[:, :2]).T)
    assert err.max() < 0.1, "the wrong closure must not pull the square together"
    assert res.rejected == 1
