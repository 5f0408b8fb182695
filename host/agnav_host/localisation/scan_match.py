"""Planar scan matching: a correlative search over a likelihood grid, refined by point-to-line ICP.

Poses are numpy arrays ``(x_m, y_m, yaw_rad)``; points are (k, 2) arrays in metres.

* :func:`icp_point_to_line` aligns a scan's points to a reference :class:`PointMap` (the points of nearby scans
  with their surface normals) from a first guess: Gauss-Newton on the distances of the points to the
  reference's local lines, Huber-weighted, with a shrinking association distance. It returns the pose, the
  share of points that found a partner (the overlap), their RMS distance and the Hessian of the last step
  (J^T W J, the information the match holds in x, y and yaw: small along a corridor, large across it).
* :class:`LikelihoodGrid` and :func:`correlative_search` (Olson's correlative scan matching, two
  resolutions): every pose of a window around a guess is scored by the sum of the grid's likelihood at
  the points; a coarse grid whose cells hold the maximum of the fine cells under them bounds the score, so
  only the best coarse cells are searched finely. It finds the match when the guess is metres and degrees
  off, where ICP alone would settle in the nearest local minimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..types import FloatArray

__all__ = ["compose", "relative", "inverse", "transform_points", "scan_points", "PointMap", "IcpResult",
           "icp_point_to_line", "LikelihoodGrid", "SearchResult", "correlative_search", "voxel_filter"]


def compose(a: FloatArray, b: FloatArray) -> FloatArray:
    """a (+) b: ``b`` given in ``a``'s frame, brought to ``a``'s parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], math.remainder(a[2] + b[2], 2 * math.pi)])


def relative(a: FloatArray, b: FloatArray) -> FloatArray:
    """``b`` seen from ``a`` (a^-1 (+) b), so that compose(a, relative(a, b)) = b."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.remainder(b[2] - a[2], 2 * math.pi)])


def inverse(a: FloatArray) -> FloatArray:
    """a^-1: the parent frame seen from ``a``."""
    return relative(a, np.zeros(3))


def transform_points(pose: FloatArray, pts: FloatArray) -> FloatArray:
    """The points (k, 2) given in ``pose``'s frame, in its parent frame."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    out = np.empty_like(pts)
    out[:, 0] = pose[0] + c * pts[:, 0] - s * pts[:, 1]
    out[:, 1] = pose[1] + s * pts[:, 0] + c * pts[:, 1]
    return out


def scan_points(ranges_m: FloatArray, angle_min_rad: float, angle_increment_rad: float, mount: FloatArray,
                min_range_m: float = 0.05, max_range_m: float = math.inf) -> FloatArray:
    """The returns of a scan (NaN / out-of-range beams dropped) as points in the robot's frame, (k, 2) m;
    ``mount`` is the laser's pose on the robot."""
    r = np.asarray(ranges_m, dtype=float)
    a = angle_min_rad + angle_increment_rad * np.arange(len(r))
    ok = np.isfinite(r) & (r >= min_range_m) & (r <= max_range_m)
    pts = np.column_stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])])
    return transform_points(mount, pts)


def voxel_filter(pts: FloatArray, cell_m: float) -> FloatArray:
    """One point per ``cell_m`` square (the first of each), in input order."""
    if len(pts) == 0:
        return pts
    keys = np.floor(pts / cell_m).astype(np.int64)
    _, first = np.unique(keys[:, 0] * 2_000_003 + keys[:, 1], return_index=True)
    out: FloatArray = pts[np.sort(first)]
    return out


class PointMap:
    """Reference points (k, 2) with a KD-tree and a unit normal per point (the smallest principal direction
    of its ``neighbours`` nearest points); ``planar`` is False where the neighbourhood is no line (a corner,
    a lone point), and those points are matched point to point."""

    def __init__(self, pts: FloatArray, neighbours: int = 7, max_spread_m: float = 2.0) -> None:
        self.pts = np.asarray(pts, dtype=float)
        self.tree = cKDTree(self.pts)
        n = len(self.pts)
        k = min(neighbours, n)
        self.normals = np.zeros((n, 2))
        self.planar = np.zeros(n, dtype=bool)
        if k >= 3:
            d, idx = self.tree.query(self.pts, k=k)
            nb = self.pts[idx]  # (n, k, 2)
            mu = nb.mean(axis=1, keepdims=True)
            q = nb - mu
            cxx = (q[..., 0] ** 2).mean(axis=1)
            cyy = (q[..., 1] ** 2).mean(axis=1)
            cxy = (q[..., 0] * q[..., 1]).mean(axis=1)
            tr, det = cxx + cyy, cxx * cyy - cxy**2
            disc = np.sqrt(np.maximum(tr**2 / 4 - det, 0.0))
            lmin, lmax = tr / 2 - disc, tr / 2 + disc
            # eigenvector of the smaller eigenvalue
            vx, vy = cxy, lmin - cxx
            alt = np.hypot(vx, vy) < 1e-12
            vx = np.where(alt, lmin - cyy, vx)
            vy = np.where(alt, cxy, vy)
            norm = np.hypot(vx, vy)
            good = norm > 1e-12
            self.normals[good, 0] = vx[good] / norm[good]
            self.normals[good, 1] = vy[good] / norm[good]
            self.planar = good & (lmin < 0.04 * np.maximum(lmax, 1e-12)) & (d[:, -1] < max_spread_m)


@dataclass(frozen=True)
class IcpResult:
    """An ICP alignment: the pose, the share of points within the final association distance
    (``overlap``), their RMS distance to the reference, m, the Hessian J^T W J of the last step (3, 3;
    per unit point variance) and the number of points used."""

    pose: FloatArray
    overlap: float
    rms_m: float
    hessian: FloatArray
    n_points: int


def icp_point_to_line(src: FloatArray, ref: PointMap, init: FloatArray, iterations: int = 30,
                      max_dist_m: float = 0.5, final_dist_m: float = 0.15, huber_m: float = 0.05,
                      prior: FloatArray | None = None, prior_info: FloatArray | None = None) -> IcpResult:
    """Align ``src`` (k, 2, in the frame of the pose sought) to ``ref`` (in the parent frame) from ``init``.

    The association distance shrinks from ``max_dist_m`` to ``final_dist_m`` over the iterations; residuals
    beyond ``huber_m`` get Huber's weight. ``prior`` / ``prior_info`` (3, 3; in units of one point's
    squared residual): a pose the result is drawn to (the odometry's prediction), which holds the
    directions the scan leaves open (along a corridor)."""
    pose = np.array(init, dtype=float)
    n = len(src)
    h = np.zeros((3, 3))
    if n < 3 or len(ref.pts) < 3:
        return IcpResult(pose, 0.0, math.inf, h, n)
    dist = max_dist_m
    for it in range(iterations):
        p = transform_points(pose, src)
        d, idx = ref.tree.query(p, k=1, distance_upper_bound=dist)
        ok = np.isfinite(d)
        if ok.sum() < 3:
            return IcpResult(pose, float(ok.mean()), math.inf, h, n)
        pi, qi = p[ok], ref.pts[idx[ok]]
        nrm, planar = ref.normals[idx[ok]], ref.planar[idx[ok]]
        lever = pi - pose[:2]
        # point-to-line rows (planar partners) and point-to-point rows (the others, x and y)
        diff = pi - qi
        r_l = np.einsum("ij,ij->i", nrm, diff)
        j_l = np.column_stack([nrm[:, 0], nrm[:, 1], nrm[:, 0] * -lever[:, 1] + nrm[:, 1] * lever[:, 0]])
        r_l = np.where(planar, r_l, 0.0)
        j_l = j_l * planar[:, None]
        npl = ~planar
        r_p = np.concatenate([diff[npl, 0], diff[npl, 1]])
        j_p = np.concatenate([np.column_stack([np.ones(npl.sum()), np.zeros(npl.sum()), -lever[npl, 1]]),
                              np.column_stack([np.zeros(npl.sum()), np.ones(npl.sum()), lever[npl, 0]])])
        r = np.concatenate([r_l[planar], r_p])
        jac = np.concatenate([j_l[planar], j_p])
        a = np.abs(r)
        w = np.where(a <= huber_m, 1.0, huber_m / np.maximum(a, 1e-12))
        h = jac.T @ (jac * w[:, None])
        g = jac.T @ (w * r)
        h_all = h
        if prior is not None and prior_info is not None:
            dp = pose - prior
            dp[2] = math.remainder(dp[2], 2 * math.pi)
            h_all = h + prior_info
            g = g + prior_info @ dp
        try:
            delta = -np.linalg.solve(h_all + 1e-9 * np.eye(3), g)
        except np.linalg.LinAlgError:
            break
        pose = np.array([pose[0] + delta[0], pose[1] + delta[1], math.remainder(pose[2] + delta[2], 2 * math.pi)])
        frac = (it + 1) / max(iterations * 0.5, 1)
        dist = max(final_dist_m, max_dist_m + (final_dist_m - max_dist_m) * min(frac, 1.0))
        if np.hypot(delta[0], delta[1]) < 1e-4 and abs(delta[2]) < 1e-5 and dist <= final_dist_m:
            break
    p = transform_points(pose, src)
    d, idx = ref.tree.query(p, k=1, distance_upper_bound=final_dist_m)
    ok = np.isfinite(d)
    if ok.any():
        nrm, planar = ref.normals[idx[ok]], ref.planar[idx[ok]]
        diff = p[ok] - ref.pts[idx[ok]]
        e = np.where(planar, np.einsum("ij,ij->i", nrm, diff), np.hypot(diff[:, 0], diff[:, 1]))
        rms = float(np.sqrt(np.mean(e**2)))
    else:
        rms = math.inf
    return IcpResult(pose, float(ok.mean()), rms, h, n)


class LikelihoodGrid:
    """A likelihood field of reference points: exp(-d^2 / (2 sigma^2)) of each cell's distance d to the
    nearest point (fine cells of ``res_m``), and a coarse copy (``coarse`` fine cells a side) whose cells
    hold the maximum of the fine ones they cover (the bound of :func:`correlative_search`)."""

    def __init__(self, pts: FloatArray, res_m: float = 0.05, sigma_m: float = 0.07, coarse: int = 6,
                 margin_m: float = 1.0) -> None:
        pts = np.asarray(pts, dtype=float)
        self.res_m, self.coarse = res_m, coarse
        lo = pts.min(axis=0) - margin_m
        hi = pts.max(axis=0) + margin_m
        shape = np.ceil((hi - lo) / res_m).astype(int) + 1
        ny = int(math.ceil(shape[1] / coarse) * coarse)
        nx = int(math.ceil(shape[0] / coarse) * coarse)
        self.origin = lo
        occ = np.full((ny, nx), 255, dtype=np.uint8)
        ij = np.floor((pts - lo) / res_m).astype(int)
        occ[ij[:, 1], ij[:, 0]] = 0
        d_m = cv2.distanceTransform(occ, cv2.DIST_L2, 5).astype(np.float64) * res_m
        self.fine = np.exp(-0.5 * (d_m / sigma_m) ** 2).astype(np.float32)
        self.coarse_grid = self.fine.reshape(ny // coarse, coarse, nx // coarse, coarse).max(axis=(1, 3))
        # a point anywhere in a coarse cell's window: dilate so the bound holds for any sub-cell offset
        self.coarse_grid = cv2.dilate(self.coarse_grid, np.ones((2, 2), np.uint8), anchor=(0, 0))

    def score_fine(self, pts_world: FloatArray) -> float:
        ij = np.floor((pts_world - self.origin) / self.res_m).astype(int)
        ny, nx = self.fine.shape
        ok = (ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)
        return float(self.fine[ij[ok, 1], ij[ok, 0]].sum()) / max(len(pts_world), 1)


@dataclass(frozen=True)
class SearchResult:
    """The best pose of a correlative search, its score (mean likelihood of the points, 0..1) and its
    ambiguity: the best coarse score at least ``separation_m`` away from the best coarse cell, as a share of
    that cell's (near 1: another place fits as well, as along a corridor)."""

    pose: FloatArray
    score: float
    ambiguity: float


def _gather(grid: np.ndarray, ij: np.ndarray) -> np.ndarray:
    ny, nx = grid.shape
    i = np.clip(ij[..., 0], 0, nx - 1)
    j = np.clip(ij[..., 1], 0, ny - 1)
    out: np.ndarray = grid[j, i]
    out[(ij[..., 0] < 0) | (ij[..., 0] >= nx) | (ij[..., 1] < 0) | (ij[..., 1] >= ny)] = 0.0
    return out


def correlative_search(src: FloatArray, grid: LikelihoodGrid, init: FloatArray, xy_window_m: float,
                       yaw_window_rad: float, yaw_step_rad: float = math.radians(1.0), keep: int = 8,
                       separation_m: float = 1.0) -> SearchResult:
    """The pose within ``+-xy_window_m`` and ``+-yaw_window_rad`` of ``init`` where ``src`` (k, 2, in the
    pose's frame) best fits ``grid``: every yaw step and coarse cell scored by the bound, then the ``keep``
    best coarse cells searched on the fine grid."""
    res, c = grid.res_m, grid.coarse
    cres = res * c
    yaws = init[2] + np.arange(-yaw_window_rad, yaw_window_rad + 1e-12, yaw_step_rad)
    nc = int(math.ceil(xy_window_m / cres))
    offs = np.arange(-nc, nc + 1)
    gx, gy = np.meshgrid(offs, offs, indexing="xy")
    ox, oy = gx.ravel(), gy.ravel()
    k = max(len(src), 1)
    scores_c = np.empty((len(yaws), len(ox)), dtype=np.float32)
    base = np.array(init[:2]) - grid.origin
    for a, yaw in enumerate(yaws):
        cs, sn = math.cos(yaw), math.sin(yaw)
        p = np.column_stack([cs * src[:, 0] - sn * src[:, 1], sn * src[:, 0] + cs * src[:, 1]]) + base
        cij = np.floor(p / cres).astype(int)  # (k, 2)
        ij = cij[:, None, :] + np.stack([ox, oy], axis=-1)[None, :, :]
        scores_c[a] = _gather(grid.coarse_grid, ij).sum(axis=0) / k
    order = np.argsort(scores_c, axis=None)[::-1]
    top = order[: keep * 4]
    best = [(float(scores_c.flat[t]), int(t // len(ox)), int(t % len(ox))) for t in top]  # (bound, yaw, offset)
    # ambiguity: the best coarse score (any yaw) at least ``separation_m`` from the best coarse cell
    per_off = scores_c.max(axis=0)
    b0 = best[0][2]
    far = np.hypot(ox - ox[b0], oy - oy[b0]) * cres >= separation_m
    runner_c = float(per_off[far].max()) if far.any() else 0.0
    # fine search inside the best coarse cells, best bound first; stop when the bound cannot beat the best
    found: list[tuple[float, FloatArray]] = []
    best_score = -1.0
    fo = np.arange(c)
    hx, hy = np.meshgrid(fo, fo, indexing="xy")
    fx, fy = hx.ravel(), hy.ravel()
    for n, (bound, a, o) in enumerate(best):
        if n >= keep and bound <= best_score:
            break
        yaw = yaws[a]
        cs, sn = math.cos(yaw), math.sin(yaw)
        p = np.column_stack([cs * src[:, 0] - sn * src[:, 1], sn * src[:, 0] + cs * src[:, 1]]) + base
        shift = np.array([ox[o] * c, oy[o] * c])
        fij = np.floor(p / res).astype(int) + shift
        # the fine offsets inside the coarse cell
        ij = fij[:, None, :] + np.stack([fx, fy], axis=-1)[None, :, :]
        sc = _gather(grid.fine, ij).sum(axis=0) / k
        m = int(np.argmax(sc))
        t = (shift + np.array([fx[m], fy[m]])) * res
        pose = np.array([init[0] + t[0], init[1] + t[1], math.remainder(yaw, 2 * math.pi)])
        found.append((float(sc[m]), pose))
        best_score = max(best_score, float(sc[m]))
    found.sort(key=lambda f: -f[0])
    top_score, top_pose = found[0]
    return SearchResult(top_pose, top_score, runner_c / max(best[0][0], 1e-12))
