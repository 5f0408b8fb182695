"""The relative-pose error of Kuemmerle et al. 2009 on synthetic trajectories with a known error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.localisation.relations import Relations, RelationsError, read_relations, score_relations


def _truth(n: int = 50) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    t = 1000.0 + np.arange(n) * 1.75
    poses = np.column_stack([np.cumsum(rng.uniform(0, 1, n)), np.cumsum(rng.uniform(-1, 1, n)),
                             rng.uniform(-math.pi, math.pi, n)])
    return t, poses


def _relations_of(t: np.ndarray, poses: np.ndarray, pairs: list[tuple[int, int]]) -> Relations:
    i = np.array([a for a, _ in pairs])
    j = np.array([b for _, b in pairs])
    a, b = poses[i], poses[j]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return Relations(t[i], t[j], c * dx + s * dy, -s * dx + c * dy, (b[:, 2] - a[:, 2] + np.pi) % (2 * np.pi) - np.pi)


PAIRS = [(k, k + 1) for k in range(49)] + [(3, 40), (10, 11)]


def test_the_true_trajectory_scores_zero_wherever_the_map_frame_is():
    t, p = _truth()
    rel = _relations_of(t, p, PAIRS)
    # the whole trajectory moved and turned: relative poses, and so the score, do not change
    th = 0.7
    c, s = math.cos(th), math.sin(th)
    moved = np.column_stack([5 + c * p[:, 0] - s * p[:, 1], -2 + s * p[:, 0] + c * p[:, 1], p[:, 2] + th])
    sc = score_relations(t, moved, rel)
    assert sc.scored == len(PAIRS) and sc.unmatched == 0
    assert sc.trans_mean_m == pytest.approx(0.0, abs=1e-9) and sc.rot_mean_deg == pytest.approx(0.0, abs=1e-7)


def test_one_pose_off_by_a_known_translation_gives_that_error_on_its_two_relations():
    t, p = _truth()
    rel = _relations_of(t, p, [(k, k + 1) for k in range(49)])
    est = p.copy()
    est[20, :2] += [0.3, -0.4]  # 0.5 m off
    sc = score_relations(t, est, rel)
    errs = np.sort(sc.trans_m)
    assert errs[-2:] == pytest.approx([0.5, 0.5]) and errs[:-2].max() == pytest.approx(0.0, abs=1e-9)
    assert sc.trans_mean_m == pytest.approx(1.0 / 49)
    assert sc.trans_sd_m == pytest.approx(float(np.std([0.5, 0.5] + [0.0] * 47)))
    assert sc.rot_mean_deg == pytest.approx(0.0, abs=1e-7)


def test_a_turned_pose_gives_its_angle_and_the_translation_its_lever_arm():
    t, p = _truth()
    rel = _relations_of(t, p, [(20, 21)])
    est = p.copy()
    est[20, 2] += math.radians(2.0)  # the frame of the relation turns: its far end swings by d * angle
    sc = score_relations(t, est, rel)
    d = math.hypot(*(p[21, :2] - p[20, :2]))
    assert sc.rot_mean_deg == pytest.approx(2.0)
    assert sc.trans_mean_m == pytest.approx(2 * d * math.sin(math.radians(1.0)))


def test_relations_whose_times_are_not_scans_are_counted_unmatched():
    t, p = _truth()
    rel = _relations_of(t, p, [(1, 2), (5, 6)])
    rel = Relations(np.array([t[1], t[5] + 0.01]), rel.t2_s, rel.dx_m, rel.dy_m, rel.dyaw_rad)
    sc = score_relations(t, p, rel)
    assert sc.scored == 1 and sc.unmatched == 1 and "1 more have an end" in sc.summary()


def test_read_relations_takes_the_planar_part_and_refuses_bad_lines(tmp_path):
    f = tmp_path / "r.relations"
    f.write_text("# t1 t2 dx dy dz roll pitch yaw\n1.5 3.25 0.4 0.01 0.3 0.2 0.1 -0.05\n\n")
    rel = read_relations(f)
    assert len(rel) == 1 and rel.dx_m[0] == 0.4 and rel.dyaw_rad[0] == -0.05 and rel.t2_s[0] == 3.25
    f.write_text("1 2 3\n")
    with pytest.raises(RelationsError, match="line 1: expected 8 numbers"):
        read_relations(f)
    f.write_text("1 2 3 4 5 6 7 x\n")
    with pytest.raises(RelationsError, match="not a number"):
        read_relations(f)
