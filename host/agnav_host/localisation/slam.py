"""Offline laser SLAM: scan-matching odometry fused with wheel odometry, loop closure on a pose graph.

Every scan is a node of a pose graph (the robot's pose at the scan's time).

Front end (per scan). The wheel odometry's increment since the last scan predicts the pose; point-to-line
ICP aligns the scan to a local map (the points of the last :attr:`SlamParams.local_scans` scans, placed by
their current estimates) with the prediction as a prior, so the odometry holds what the scan leaves open
(the direction along a corridor). When the ICP overlap is poor (the odometry far off, a jump), a
correlative search over a window around the prediction finds the start for ICP again. One edge joins the
scan to the one before it: the matched increment, with the information of the ICP Hessian plus the
odometry's (a motion model: error grows with the distance and the angle), since the match holds the
odometry as its prior; a scan that could not be matched gets the odometry increment alone.

Loop closure (every :attr:`SlamParams.loop_every` scans). The scans that are near in the estimate but far
along the graph (graph distance: the path length along odometry edges, zero across loop closures; the
estimate's relative error grows with it) are candidates; the nearest one, far enough along the graph, is
matched: the current scan and the ones just before it, as one query, against the points of the
candidate's neighbours, by a correlative search whose window grows with the graph distance, then ICP. A
match that overlaps well, fits tightly and is not ambiguous (no pose of the window far from it scores
nearly as well) is kept; when a second kept match within a few scans implies the same correction of the
map, both become loop edges and the graph is optimised (:mod:`.pose_graph`). If the optimised map leaves
any loop edge off by more than :attr:`SlamParams.loop_verify_m` or ``loop_verify_rad``, the new edges
conflict with it and are taken back.

Scans without odometry are predicted by the pose of the scan before them and found by the correlative
search alone.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from ..types import FloatArray
from .pose_graph import PoseGraph
from .scan_match import (
    IcpResult,
    LikelihoodGrid,
    PointMap,
    compose,
    correlative_search,
    icp_point_to_line,
    relative,
    scan_points,
    transform_points,
    voxel_filter,
)

__all__ = ["SlamScan", "SlamParams", "SlamResult", "Slam", "run_slam"]


@dataclass(frozen=True)
class SlamScan:
    """One scan for SLAM: time (s, and as written in the log), the beams (``ranges_m`` (n,), NaN for no
    return), the laser's pose on the robot (``mount``: x m, y m, yaw rad) and the robot's odometry pose
    (x m, y m, yaw rad; None when the log has none)."""

    t_s: float
    t_text: str
    angle_min_rad: float
    angle_increment_rad: float
    ranges_m: FloatArray
    range_max_m: float
    mount: FloatArray
    odom: FloatArray | None


@dataclass(frozen=True)
class SlamParams:
    """The tuning of :class:`Slam` (lengths m, angles rad)."""

    min_range_m: float = 0.1
    max_range_m: float = 40.0
    scan_voxel_m: float = 0.05  # the scan's points thinned to one per cell before matching
    local_scans: int = 20  # the front end's local map: the last N scans
    local_voxel_m: float = 0.03
    icp_max_dist_m: float = 0.4
    icp_final_dist_m: float = 0.15
    point_sigma_m: float = 0.03  # one return's error in the ICP information
    point_dof: float = 8.0  # independent points a match's information is worth in the graph (correlated returns)
    # the same for weighing the odometry prior inside the front end's ICP; a scan of fewer returns gets the prior
    # as for prior_dof returns, so that a handful of returns cannot turn the pose against the odometry
    prior_dof: float = 100.0
    min_overlap: float = 0.55  # below: the prediction is re-found by the correlative search
    reloc_xy_m: float = 1.0
    reloc_yaw_rad: float = math.radians(15.0)
    odom_trans_frac: float = 0.05  # odometry error per metre travelled, m/m
    odom_rot_frac: float = 0.05  # rad per rad turned
    odom_rot_per_m: float = math.radians(1.0)  # rad per metre travelled
    odom_floor_m: float = 0.01
    odom_floor_rad: float = math.radians(0.5)
    loop_every: int = 3
    loop_min_graph_m: float = 15.0  # a candidate is at least this far along the graph
    loop_radius_m: float = 1.0  # search radius at zero graph distance
    loop_radius_per_m: float = 0.03  # growth of the radius with the graph distance, m/m
    loop_max_radius_m: float = 15.0
    loop_wide_m: float = 3.0  # a wider search runs on coarser cells, every third try only
    loop_yaw_rad: float = math.radians(5.0)
    loop_yaw_per_m: float = math.radians(0.04)
    loop_max_yaw_rad: float = math.radians(30.0)
    loop_submap_scans: int = 12  # the candidate's neighbours on either side
    loop_query_scans: int = 10  # the current scan and the ones before it, matched as one
    loop_query_voxel_m: float = 0.1
    loop_confirm_scans: int = 12  # a closure is taken when another within this many scans agrees with it
    loop_confirm_m: float = 0.3
    loop_confirm_rad: float = math.radians(2.0)
    loop_min_score: float = 0.5
    loop_max_ambiguity: float = 0.95  # runner-up / best score of the search
    loop_min_overlap: float = 0.6
    loop_max_rms_m: float = 0.05
    loop_dof: float = 8.0
    loop_verify_m: float = 0.3  # after optimising, every loop edge must hold to within this
    loop_verify_rad: float = math.radians(2.0)
    optimise_iterations: int = 15


@dataclass
class SlamResult:
    """The trajectory (``t_s`` (n,), ``t_text``, ``poses`` (n, 3): x m, y m, yaw rad of the robot at each
    scan), each scan's points in the robot frame (for the map), counts and timing."""

    t_s: FloatArray
    t_text: list[str]
    poses: FloatArray
    points: list[FloatArray]
    origins: list[FloatArray]
    loops_tried: int = 0
    loops_accepted: int = 0
    loops_conflicting: int = 0
    relocalised: int = 0
    no_odometry: int = 0
    seconds: float = 0.0
    per_scan_ms: list[float] = field(default_factory=list)


def _odom_info(dz: FloatArray, p: SlamParams) -> FloatArray:
    d = math.hypot(dz[0], dz[1])
    st = max(p.odom_floor_m, p.odom_trans_frac * d)
    sr = max(p.odom_floor_rad, p.odom_rot_frac * abs(dz[2]) + p.odom_rot_per_m * d)
    return np.diag([1.0 / st**2, 1.0 / st**2, 1.0 / sr**2])


def _scan_info(h: FloatArray, n: int, dof: float, p: SlamParams) -> FloatArray:
    scale = min(1.0, dof / max(n, 1)) / p.point_sigma_m**2
    info = 0.5 * (h + h.T) * scale
    w, v = np.linalg.eigh(info)
    w = np.clip(w, 1e-6, 1e6)
    out: FloatArray = (v * w) @ v.T
    return out


class Slam:
    """Incremental SLAM over :class:`SlamScan` records: :meth:`add` each scan in time order, then
    :meth:`result`."""

    def __init__(self, params: SlamParams | None = None) -> None:
        self.p = params or SlamParams()
        self.graph = PoseGraph()
        self.points: list[FloatArray] = []
        self.origins: list[FloatArray] = []
        self.t_s: list[float] = []
        self.t_text: list[str] = []
        self.path_m: list[float] = []
        self._odom: list[FloatArray | None] = []
        self._adj_rows: list[int] = []
        self._adj_cols: list[int] = []
        self._adj_w: list[float] = []
        self.loops_tried = 0
        self.loops_accepted = 0
        self.relocalised = 0
        self.no_odometry = 0
        self.per_scan_ms: list[float] = []
        self._last_loop_try = -10**9
        self._pending: list[tuple[int, int, FloatArray, FloatArray]] = []
        self._accepted: set[tuple[int, int]] = set()
        self._wide_tries = 0
        self.loops_conflicting = 0
        # every loop match tried: (k, j, search score, ambiguity[, fine score, overlap, rms m, x, y, yaw])
        self.loop_log: list[tuple[float, ...]] = []
        self.last_match: IcpResult | None = None  # the front end's match of the last scan (None: none tried)

    # ---- front end --------------------------------------------------------------------------------------

    def _local_map(self, k: int) -> PointMap | None:
        if k < 1:
            return None
        return PointMap(voxel_filter(self.local_points(k), self.p.local_voxel_m))

    def local_points(self, k: int) -> FloatArray:
        """The points of the :attr:`SlamParams.local_scans` nodes before node ``k``, placed by their current
        estimates (world frame), (n, 2) m; ``k`` >= 1."""
        lo = max(0, k - self.p.local_scans)
        out: FloatArray = np.concatenate([transform_points(self.graph.poses[i], self.points[i]) for i in range(lo, k)])
        return out

    def _link(self, i: int, j: int, w: float) -> None:
        self._adj_rows += [i, j]
        self._adj_cols += [j, i]
        self._adj_w += [w, w]

    def add(self, scan: SlamScan) -> FloatArray:
        """Add one scan; returns its pose estimate (x m, y m, yaw rad) before any later loop closure."""
        t0 = time.perf_counter()
        p = self.p
        pts = scan_points(scan.ranges_m, scan.angle_min_rad, scan.angle_increment_rad, scan.mount,
                          p.min_range_m, min(p.max_range_m, scan.range_max_m))
        pts = voxel_filter(pts, p.scan_voxel_m)
        return self.add_points(pts, scan.t_s, scan.t_text, scan.mount[:2], scan.odom, t0=t0)

    def add_points(self, pts: FloatArray, t_s: float, t_text: str, origin: FloatArray, odom: FloatArray | None,
                   guess: FloatArray | None = None, t0: float | None = None) -> FloatArray:
        """Add one scan as its points in the robot frame (thinned), the laser's position on the robot
        (``origin``) and the odometry pose (None: none); returns its pose estimate. ``guess``: a pose found by
        another search (re-localising) that replaces the odometry's prediction; the odometry then neither
        draws the match nor enters the edge."""
        t0 = time.perf_counter() if t0 is None else t0
        p = self.p
        k = len(self.graph.poses)
        odom = None if odom is None else np.asarray(odom, dtype=float)
        self.last_match = None
        if odom is None:
            self.no_odometry += 1
        if k == 0:
            pose = np.zeros(3) if odom is None else odom.copy()
            self.graph.add_node(pose)
            self.path_m.append(0.0)
        else:
            prev = self.graph.poses[k - 1]
            prev_odom = self._odom[k - 1]
            dz = relative(prev_odom, odom) if odom is not None and prev_odom is not None else None
            pred = compose(prev, dz) if dz is not None else prev.copy()
            if guess is not None:
                pred, dz = np.asarray(guess, dtype=float), None
            ref = self._local_map(k)
            pose = pred
            matched = None
            if ref is not None and len(pts) >= 10:
                prior_info = None
                if dz is not None:
                    prior_info = _odom_info(dz, p) * p.point_sigma_m**2 * max(len(pts) / p.prior_dof, 1.0)
                res = icp_point_to_line(pts, ref, pred, max_dist_m=p.icp_max_dist_m, final_dist_m=p.icp_final_dist_m,
                                        prior=pred if dz is not None else None, prior_info=prior_info)
                if res.overlap < p.min_overlap or dz is None:
                    grid = LikelihoodGrid(ref.pts, res_m=0.05, sigma_m=0.1, coarse=4)
                    xy = p.reloc_xy_m if dz is not None else 2.0 * p.reloc_xy_m
                    sr = correlative_search(pts, grid, pred, xy, p.reloc_yaw_rad)
                    res2 = icp_point_to_line(pts, ref, sr.pose, max_dist_m=p.icp_max_dist_m,
                                             final_dist_m=p.icp_final_dist_m)
                    if res2.overlap > res.overlap:
                        res = res2
                        self.relocalised += 1
                self.last_match = res
                if res.overlap >= 0.3:
                    matched = res
                    pose = res.pose
            self.graph.add_node(pose)
            self.path_m.append(self.path_m[-1] + math.hypot(*(pose[:2] - prev[:2])))
            step = math.hypot(*(pose[:2] - prev[:2]))
            if matched is not None:
                # the match already holds the odometry (its prior): one edge with both informations
                info = _scan_info(matched.hessian, matched.n_points, p.point_dof, p)
                if dz is not None:
                    info = info + _odom_info(dz, p)
                self.graph.add_edge(k - 1, k, relative(prev, pose), info)
            elif dz is not None:
                self.graph.add_edge(k - 1, k, dz, _odom_info(dz, p))
            else:  # neither odometry nor a match: keep the graph connected, loosely
                self.graph.add_edge(k - 1, k, np.zeros(3), np.diag([1.0, 1.0, 1.0]))
            self._link(k - 1, k, max(step, 1e-3))
        self.points.append(pts)
        self.origins.append(np.array(origin, dtype=float))
        self.t_s.append(t_s)
        self.t_text.append(t_text)
        self._odom.append(odom)
        if k > 0 and k - self._last_loop_try >= p.loop_every:
            self._last_loop_try = k
            self._try_loop(k)
        self.per_scan_ms.append(1e3 * (time.perf_counter() - t0))
        out: FloatArray = self.graph.poses[k].copy()
        return out

    # ---- loop closure -----------------------------------------------------------------------------------

    def _graph_distance(self, k: int) -> FloatArray:
        n = len(self.graph.poses)
        adj = csr_matrix((self._adj_w, (self._adj_rows, self._adj_cols)), shape=(n, n))
        return np.asarray(dijkstra(adj, directed=False, indices=k, limit=np.inf))

    def _try_loop(self, k: int) -> None:
        p = self.p
        x = self.graph.poses
        if self.path_m[k] < p.loop_min_graph_m:
            return
        gd = self._graph_distance(k)
        far = np.isfinite(gd) & (gd >= p.loop_min_graph_m)
        far[k] = False
        if not far.any():
            return
        radius = np.minimum(p.loop_max_radius_m, p.loop_radius_m + p.loop_radius_per_m * gd)
        dist = np.hypot(x[:, 0] - x[k, 0], x[:, 1] - x[k, 1])
        cand = np.flatnonzero(far & (dist <= radius))
        if len(cand) == 0:
            return
        j = int(cand[np.argmin(dist[cand])])
        if p.loop_radius_m + p.loop_radius_per_m * gd[j] > p.loop_wide_m:
            self._wide_tries += 1
            if self._wide_tries % 3 != 1:
                return
        self.loops_tried += 1
        match = self._match_loop(k, j, float(gd[j]))
        if match is None:
            return
        z, info = match
        self._pending = [m for m in self._pending if k - m[0] <= p.loop_confirm_scans]
        corr = compose(compose(x[j], z), relative(x[k], np.zeros(3)))
        confirmed = []
        for m in self._pending:
            k2, j2, z2, _ = m
            corr2 = compose(compose(x[j2], z2), relative(x[k2], np.zeros(3)))
            d = relative(corr, corr2)
            if math.hypot(d[0], d[1]) <= p.loop_confirm_m and abs(d[2]) <= p.loop_confirm_rad:
                confirmed.append(m)
        self._pending.append((k, j, z, info))
        if not confirmed:
            return
        new = [m for m in [*confirmed, (k, j, z, info)] if (m[0], m[1]) not in self._accepted]
        if not new:
            return
        saved = self.graph.poses.copy()
        n_edges = len(self.graph.edges)
        for k2, j2, z2, info2 in new:
            self.graph.add_edge(j2, k2, z2, info2, loop=True)
        self.graph.optimise(iterations=p.optimise_iterations)
        if self._loop_residual_max() > 1.0:  # the closure conflicts with the map: take it back
            del self.graph.edges[n_edges:]
            self.graph.poses = saved
            self.loops_conflicting += len(new)
            return
        for k2, j2, _, _ in new:
            self._accepted.add((k2, j2))
            self._link(j2, k2, 0.0)
            self.loops_accepted += 1

    def _loop_residual_max(self) -> float:
        """The largest residual of the loop edges, as a share of the allowed one (:attr:`SlamParams.loop_verify_m`
        / ``loop_verify_rad``)."""
        x = self.graph.poses
        worst = 0.0
        for e in self.graph.edges:
            if not e.loop:
                continue
            d = relative(e.z, relative(x[e.i], x[e.j]))
            worst = max(worst, math.hypot(d[0], d[1]) / self.p.loop_verify_m, abs(d[2]) / self.p.loop_verify_rad)
        return worst

    def _match_loop(self, k: int, j: int, graph_m: float) -> tuple[FloatArray, FloatArray] | None:
        """The pose of scan ``k`` in scan ``j``'s frame and its information, or None when the match fails a test."""
        p = self.p
        x = self.graph.poses
        lo, hi = max(0, j - p.loop_submap_scans), min(k - 1, j + p.loop_submap_scans + 1)
        near_k = self.path_m[k] - p.loop_min_graph_m
        ref_pts = np.concatenate([transform_points(relative(x[j], x[i]), self.points[i]) for i in range(lo, hi)
                                  if self.path_m[i] < near_k])
        ref_pts = voxel_filter(ref_pts, p.local_voxel_m)
        if len(ref_pts) < 50:
            return None
        q0 = max(0, k - p.loop_query_scans)
        src = np.concatenate([transform_points(relative(x[k], x[i]), self.points[i]) for i in range(q0, k + 1)])
        src = voxel_filter(src, p.loop_query_voxel_m)
        guess = relative(x[j], x[k])
        xy = min(p.loop_max_radius_m, p.loop_radius_m + p.loop_radius_per_m * graph_m)
        yaw = min(p.loop_max_yaw_rad, p.loop_yaw_rad + p.loop_yaw_per_m * graph_m)
        wide = xy > p.loop_wide_m
        coarse = 8 if wide else 4
        grid = LikelihoodGrid(ref_pts, res_m=0.05, sigma_m=0.08, coarse=coarse)
        coarse_src = voxel_filter(src, 0.4 if wide else 0.15)
        sr = correlative_search(coarse_src, grid, guess, xy, yaw, yaw_step_rad=math.radians(1.5 if wide else 1.0),
                                keep=12, separation_m=max(1.5, 3 * 0.05 * coarse))
        self.loop_log.append((k, j, sr.score, sr.ambiguity))
        if sr.score < p.loop_min_score * 0.8 or sr.ambiguity > p.loop_max_ambiguity:
            return None
        ref = PointMap(ref_pts)
        res = icp_point_to_line(src, ref, sr.pose, max_dist_m=p.icp_max_dist_m, final_dist_m=p.icp_final_dist_m)
        score = grid.score_fine(transform_points(res.pose, src))
        self.loop_log[-1] = (k, j, sr.score, sr.ambiguity, score, res.overlap, res.rms_m, *res.pose)
        if res.overlap < p.loop_min_overlap or res.rms_m > p.loop_max_rms_m or score < p.loop_min_score:
            return None
        return res.pose, _scan_info(res.hessian, res.n_points, p.loop_dof, p)

    # ---- result -----------------------------------------------------------------------------------------

    def result(self, final_iterations: int = 30) -> SlamResult:
        """Optimise the whole graph once more and return the trajectory."""
        t0 = time.perf_counter()
        self.graph.optimise(iterations=final_iterations)
        extra = time.perf_counter() - t0
        return SlamResult(np.array(self.t_s), list(self.t_text), self.graph.poses.copy(), self.points, self.origins,
                          self.loops_tried, self.loops_accepted, self.loops_conflicting, self.relocalised,
                          self.no_odometry, float(sum(self.per_scan_ms)) / 1e3 + extra, list(self.per_scan_ms))


def run_slam(scans: Iterable[SlamScan], params: SlamParams | None = None,
             progress: Callable[[int], None] | None = None) -> SlamResult:
    """SLAM over ``scans`` (in time order); ``progress(k)`` after each scan."""
    slam = Slam(params)
    for k, s in enumerate(scans):
        slam.add(s)
        if progress is not None:
            progress(k + 1)
    return slam.result()
