"""The relative-pose error of a SLAM trajectory against ground-truth relations (Kuemmerle et al. 2009, "On
measuring the accuracy of SLAM algorithms", Autonomous Robots 27:387-407).

A relation (i, j, d*) is the true motion from the pose at time t_i to the pose at time t_j, in the frame of
the pose at t_i. The estimate of it is d = x_i^-1 x_j (the pose at t_j seen from the pose at t_i). The error
of one relation is the pose difference e = d*^-1 d: its translation's norm (m; |t - t*|, the same in either
frame) and its rotation angle (rad, wrapped to [-pi, pi), taken absolute). The paper's tables give the
mean and standard deviation of these absolute errors over every relation (the metric itself, epsilon, is
the mean of their squares; both are reported here).

Relation files hold one relation a line: ``t1 t2 dx dy dz roll pitch yaw`` (s, s, m, m, m, rad, rad, rad);
the planar part (dx, dy, yaw) is used. A relation is scored when both its times are scan times of the
trajectory (within :data:`MATCH_TOLERANCE_S`); the others are counted as unmatched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..types import FloatArray

__all__ = ["RelationsError", "Relations", "RelationScore", "read_relations", "score_relations",
           "MATCH_TOLERANCE_S"]

#: Largest difference between a relation's time and a scan's time that still names that scan, s (the
#: benchmark's times are written to the microsecond)
MATCH_TOLERANCE_S = 5e-4


class RelationsError(ValueError):
    """A relations file that cannot be read; the message names the file, the line and what is wrong."""


@dataclass(frozen=True)
class Relations:
    """Ground-truth relations: times ``t1_s``, ``t2_s`` (n,) and the motion ``dx_m``, ``dy_m``, ``dyaw_rad``
    (n,) from the pose at t1 to the pose at t2 in t1's frame."""

    t1_s: FloatArray
    t2_s: FloatArray
    dx_m: FloatArray
    dy_m: FloatArray
    dyaw_rad: FloatArray

    def __len__(self) -> int:
        return len(self.t1_s)


@dataclass(frozen=True)
class RelationScore:
    """The error over the scored relations: absolute translational error (m) and rotational error (rad),
    their means, standard deviations (population) and maxima, the metric's mean squares (m^2, rad^2), and
    how many relations were scored and unmatched. ``trans_m`` / ``rot_rad``: each scored relation's error."""

    scored: int
    unmatched: int
    trans_m: FloatArray
    rot_rad: FloatArray

    @property
    def trans_mean_m(self) -> float:
        return float(np.mean(self.trans_m)) if self.scored else math.nan

    @property
    def trans_sd_m(self) -> float:
        return float(np.std(self.trans_m)) if self.scored else math.nan

    @property
    def trans_max_m(self) -> float:
        return float(np.max(self.trans_m)) if self.scored else math.nan

    @property
    def trans_sq_mean_m2(self) -> float:
        return float(np.mean(self.trans_m**2)) if self.scored else math.nan

    @property
    def rot_mean_deg(self) -> float:
        return math.degrees(float(np.mean(self.rot_rad))) if self.scored else math.nan

    @property
    def rot_sd_deg(self) -> float:
        return math.degrees(float(np.std(self.rot_rad))) if self.scored else math.nan

    @property
    def rot_max_deg(self) -> float:
        return math.degrees(float(np.max(self.rot_rad))) if self.scored else math.nan

    @property
    def rot_sq_mean_deg2(self) -> float:
        return float(np.mean(np.degrees(self.rot_rad) ** 2)) if self.scored else math.nan

    def summary(self) -> str:
        """``translational 0.052 +- 0.061 m (max 0.41), rotational 0.61 +- 0.70 deg (max 4.1), 658 relations``."""
        if not self.scored:
            return f"no relation scored ({self.unmatched} have an end that is not a scan time of the trajectory)"
        text = (f"translational {self.trans_mean_m:.3f} +- {self.trans_sd_m:.3f} m (max {self.trans_max_m:.3f}), "
                f"rotational {self.rot_mean_deg:.2f} +- {self.rot_sd_deg:.2f} deg (max {self.rot_max_deg:.2f}), "
                f"{self.scored} relations")
        if self.unmatched:
            text += f" ({self.unmatched} more have an end that is not a scan time)"
        return text

    def as_dict(self) -> dict[str, float | int]:
        return {"scored": self.scored, "unmatched": self.unmatched,
                "trans_mean_m": self.trans_mean_m, "trans_sd_m": self.trans_sd_m, "trans_max_m": self.trans_max_m,
                "trans_sq_mean_m2": self.trans_sq_mean_m2, "rot_mean_deg": self.rot_mean_deg,
                "rot_sd_deg": self.rot_sd_deg, "rot_max_deg": self.rot_max_deg,
                "rot_sq_mean_deg2": self.rot_sq_mean_deg2}


def read_relations(path: str | Path) -> Relations:
    """Read a relations file (``t1 t2 dx dy dz roll pitch yaw`` a line; blank lines and ``#`` comments
    allowed). Raises OSError, or :class:`RelationsError` for a line that is not eight finite numbers."""
    rows: list[list[float]] = []
    p = Path(path)
    with open(p, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            toks = line.split("#", 1)[0].split()
            if not toks:
                continue
            if len(toks) != 8:
                raise RelationsError(f"{p}: line {number}: expected 8 numbers (t1 t2 dx dy dz roll pitch yaw), "
                                     f"got {len(toks)} fields")
            try:
                vals = [float(t) for t in toks]
            except ValueError:
                raise RelationsError(f"{p}: line {number}: a field is not a number") from None
            if not all(math.isfinite(v) for v in vals):
                raise RelationsError(f"{p}: line {number}: a field is not finite")
            rows.append(vals)
    if not rows:
        raise RelationsError(f"{p}: no relation in the file")
    a = np.array(rows)
    return Relations(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 7])


def _index_of(times_s: FloatArray, t: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(times_s)
    ts = times_s[order]
    k = np.clip(np.searchsorted(ts, t), 1, max(len(ts) - 1, 1))
    lo = np.clip(k - 1, 0, len(ts) - 1)
    hi = np.clip(k, 0, len(ts) - 1)
    pick = np.where(np.abs(ts[hi] - t) < np.abs(ts[lo] - t), hi, lo)
    ok = np.abs(ts[pick] - t) <= MATCH_TOLERANCE_S
    return order[pick], ok


def score_relations(times_s: FloatArray, poses: FloatArray, rel: Relations) -> RelationScore:
    """Score the trajectory (``times_s`` (n,), s; ``poses`` (n, 3): x m, y m, yaw rad) against ``rel``."""
    times_s = np.asarray(times_s, dtype=float)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if len(times_s) == 0:
        return RelationScore(0, len(rel), np.zeros(0), np.zeros(0))
    i, ok_i = _index_of(times_s, rel.t1_s)
    j, ok_j = _index_of(times_s, rel.t2_s)
    ok = ok_i & ok_j
    i, j = i[ok], j[ok]
    a, b = poses[i], poses[j]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    ex = c * dx + s * dy - rel.dx_m[ok]  # the estimated relation's translation minus the true one, in t1's frame
    ey = -s * dx + c * dy - rel.dy_m[ok]
    eth = (b[:, 2] - a[:, 2] - rel.dyaw_rad[ok] + math.pi) % (2.0 * math.pi) - math.pi
    return RelationScore(int(ok.sum()), int((~ok).sum()), np.hypot(ex, ey), np.abs(eth))
