"""Obstacles: clustering of scan points into objects, and tracking them across scans.

Clustering splits the beam-ordered points wherever two consecutive returns are more than
``gap_m`` apart. A cluster's size (radius) is half its end-to-end extent; its centre lies on the
bearing of the points' mean, one radius beyond the nearest point (a laser sees only the near side of
a round object, so the plain mean of its points sits in front of the centre).

Tracks are constant-velocity Kalman filters in the world frame (state x, y, vx, vy), associated to
clusters by nearest neighbour within a Mahalanobis gate. :class:`Track` is the small typed record the
planners consume.

Static or moving: from a moving robot the centre of a static object wanders (another face comes into
view, the object slides out of the laser's range), which gives it a spurious velocity. Two rules keep
such objects static: a cluster with a return near the end of the laser's range is cut by the range
or the first or last beams of the scan, or next to a beam that hit something well in front of it
(partly hidden) or that hit something nearer and was split off by the gap (a surface seen at a grazing
angle: it falls apart into fragments that change with every scan's noise), is cut and is not used at
all (a wall leaving the range, a box leaving the field of view, a walker coming out from behind a post
would "move" with the robot or too fast), and a track is moving only when its speed is well above its
uncertainty *and* it has travelled ``Track.MIN_TRAVEL_M`` (or its own radius, if larger) from where it
was first seen; a track is confirmed only by ``confirm_hits`` scans with no more than
``TrackerParams.confirm_max_misses`` misses in a row between them (not by three fragments seen over
half a second). Through an occlusion (a walker behind a box) a track coasts on its velocity
for up to ``TrackerParams.max_coast_s`` (its covariance growing) and is picked up again by the gate. A walker
who turns round leaves that gate; with ``TrackerParams.reacquire_m`` his track, missed, takes a free cluster
near where it was last seen instead and restarts its velocity (opt-in).
Two objects seen as one cluster (a walker passing a box) would drag both tracks: with
``max_grow_m`` a confirmed track does not take a cluster much larger than itself and coasts instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..types import FloatArray, LaserScan, Pose2D, ScanXY
from ._scan import ScanParams, points_from_scan

__all__ = ["Cluster", "cluster_points", "clusters_from_scan", "Track", "TrackerParams", "ObstacleTracker"]


@dataclass(frozen=True)
class Cluster:
    """One object in one scan: centre (m), radius (m), point count, in the frame of the points."""

    x_m: float
    y_m: float
    radius_m: float
    n_points: int
    cut: bool = False  # near the end of the laser's range or field of view, or partly hidden: the object may extend beyond what was seen


def cluster_points(xy: ScanXY, sensor_xy: tuple[float, float] = (0.0, 0.0), gap_m: float = 0.2,
                   min_points: int = 2, max_radius_m: float = 1.5, range_max_m: float = math.inf,
                   range_edge_m: float = 0.15, at_view_edge: npt.NDArray[np.bool_] | None = None) -> list[Cluster]:
    """Split beam-ordered points (k, 2) into clusters (module docstring); clusters with fewer than
    ``min_points`` points or a radius above ``max_radius_m`` (walls, rows) are dropped. A cluster with
    a point farther than ``range_max_m - range_edge_m`` from the sensor, or one of the points marked in
    ``at_view_edge`` (k,) (the first and last beams of a scan, beams beside a nearer return), is
    flagged ``cut``."""
    if len(xy) == 0:
        return []
    xy = np.asarray(xy, dtype=float)
    d = np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1]))
    start = np.concatenate(([0], np.flatnonzero(d > gap_m) + 1))  # first point of each part
    count = np.diff(np.append(start, len(xy)))
    edge = np.zeros(len(xy), dtype=bool) if at_view_edge is None else np.asarray(at_view_edge, dtype=bool)
    # every part at once: its extent (end to end, and from its first point to any), mean, nearest and
    # farthest range from the sensor
    first = np.repeat(xy[start], count, axis=0)
    from_first = np.hypot(xy[:, 0] - first[:, 0], xy[:, 1] - first[:, 1])
    last = xy[start + count - 1]
    r = 0.5 * np.maximum(np.hypot(last[:, 0] - xy[start, 0], last[:, 1] - xy[start, 1]),
                         np.maximum.reduceat(from_first, start))
    m = np.add.reduceat(xy, start, axis=0) / count[:, None]
    sx, sy = float(sensor_xy[0]), float(sensor_xy[1])
    rng = np.hypot(xy[:, 0] - sx, xy[:, 1] - sy)
    near = np.minimum.reduceat(rng, start)
    far = np.maximum.reduceat(rng, start)
    cut = (far > range_max_m - range_edge_m) | np.logical_or.reduceat(edge, start)
    out = []
    for k in np.flatnonzero((count >= min_points) & (r <= max_radius_m)):
        ux, uy = float(m[k, 0]) - sx, float(m[k, 1]) - sy
        nu = math.hypot(ux, uy)
        rk = float(r[k])
        if nu > 1e-9:
            f = (float(near[k]) + rk) / nu
            cx, cy = sx + f * ux, sy + f * uy
        else:
            cx, cy = float(m[k, 0]), float(m[k, 1])
        out.append(Cluster(cx, cy, rk, int(count[k]), bool(cut[k])))
    return out


def clusters_from_scan(scan: LaserScan, gap_m: float = 0.2, min_points: int = 2, max_radius_m: float = 1.5,
                       world: bool = True) -> list[Cluster]:
    """Clusters of a scan, in the world frame when the scan carries its pose (and ``world``), else the sensor frame."""
    pose = scan.pose if (world and scan.pose is not None) else Pose2D()
    pts = points_from_scan(scan, pose, ScanParams())
    n = len(scan.ranges_m)
    # a full-circle laser has no edge of view: its last beam sits beside its first
    full_circle = scan.full_circle
    at_edge = np.zeros(len(pts.index), dtype=bool) if full_circle else (pts.index <= 1) | (pts.index >= n - 2)
    # a neighbouring beam returned from nearer, either well in front (0.3 m: the object is partly hidden
    # behind another) or split off by the gap (a surface seen at a grazing angle falls apart into
    # fragments whose extent, and so centre, changes with every scan's noise; a stationary robot beside
    # a box saw such fragments as walkers at 0.5-1.7 m/s)
    r = np.where(np.isfinite(scan.ranges_m) & (scan.ranges_m > 0), scan.ranges_m, np.inf)
    a = scan.angles_rad + pose.yaw_rad
    with np.errstate(invalid="ignore"):  # inf (no return) times cos 0: nan, never nearer
        bx, by = pose.x_m + r * np.cos(a), pose.y_m + r * np.sin(a)
    for step in (-1, 1):
        nb = pts.index + step
        if full_circle:
            nb = nb % n
        inside = (nb >= 0) & (nb < n)
        nbc = np.clip(nb, 0, n - 1)
        r_nb = r[nbc]
        with np.errstate(invalid="ignore"):
            split = np.hypot(bx[nbc] - pts.xy[:, 0], by[nbc] - pts.xy[:, 1]) > gap_m
        at_edge |= inside & (r_nb < pts.ranges_m) & (split | (r_nb < pts.ranges_m - 0.3))
    xy = pts.xy
    if full_circle and len(xy) > 2 and float(np.hypot(*(xy[0] - xy[-1]))) <= gap_m:
        # an object across the seam: start the beam order after the widest gap instead, so it stays whole
        k = int(np.argmax(np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1])))) + 1
        xy, at_edge = np.roll(xy, -k, axis=0), np.roll(at_edge, -k)
    return cluster_points(xy, (pose.x_m, pose.y_m), gap_m, min_points, max_radius_m, scan.range_max_m,
                          at_view_edge=at_edge)


@dataclass(frozen=True)
class Track:
    """A tracked obstacle: position (m), velocity (m/s), radius (m) in the world frame; ``speed_sigma_m_s``
    is the 1-sigma uncertainty of the speed; ``covariance`` the 4 x 4 of (x, y, vx, vy)."""

    id: int
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    radius_m: float
    speed_sigma_m_s: float
    covariance: tuple[tuple[float, ...], ...]
    age_s: float
    hits: int
    travel_m: float = math.inf  # farthest the estimate has been from where the object was first seen
    unseen_s: float = 0.0  # time since the last scan that saw it (> 0: coasting on its velocity)

    MIN_TRAVEL_M = 0.3  # a moving object has gone at least this far from where it was first seen

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.vx_m_s, self.vy_m_s)

    @property
    def moving(self) -> bool:
        """Speed more than twice its uncertainty and above 0.1 m/s, and ``MIN_TRAVEL_M`` or its own radius
        travelled, whichever is more (module docstring): the centre of a large static object wanders by
        about its radius as a passing robot sees other faces of it (a 1.5 x 0.8 m box passed at 2 m/s
        "moved" 0.32 m at up to 0.56 m/s)."""
        return (self.speed_m_s > max(0.1, 2.0 * self.speed_sigma_m_s)
                and self.travel_m >= max(self.MIN_TRAVEL_M, self.radius_m))


@dataclass(frozen=True)
class TrackerParams:
    gate_sigma: float = 3.5  # Mahalanobis gate
    max_gate_m: float = 1.0
    accel_std_m_s2: float = 1.0  # process noise of the constant-velocity model
    meas_std_m: float = 0.05
    max_misses: int = 5
    confirm_hits: int = 3
    # scans in a row a track may miss before it is confirmed (then it is dropped): three hits spread over
    # 0.5 s can be three fragments of a box face seen each time from a different part of it, a phantom
    # with a velocity. 1 keeps a walker seen in every other scan (legs at the range's end)
    confirm_max_misses: int = 1
    cluster_gap_m: float = 0.2
    max_radius_m: float = 1.0
    # > 0: a track is kept this long after it was last seen, however many scans missed it (occlusions);
    # max_misses applies only to tracks not yet confirmed
    max_coast_s: float = 0.0
    # a confirmed track does not take a cluster this much larger than itself: two objects seen as one
    # (a walker passing a box) would drag the track between them
    max_grow_m: float = math.inf
    # ... nor one this much smaller: a two-point fragment of a box face is not the face the track has
    # followed, and its centre lies elsewhere (taken, it gave a static face a velocity)
    max_shrink_m: float = math.inf
    # > 0: a confirmed track that has travelled (a walker) and is missed this scan takes a free cluster within
    # this distance of where it was last seen, restarting its velocity from that displacement: a walker who
    # turns round leaves the gate of its own prediction (which coasts on the old way) and was otherwise
    # only found again as a new track, "moving" after some 0.8 s. 0: off
    reacquire_m: float = 0.0
    reacquire_speed_std_m_s: float = 0.3  # the restarted velocity's uncertainty
    max_speed_m_s: float = 2.5  # ... capped at this speed


def _inv2(S: FloatArray) -> FloatArray:
    """Inverses of a stack (n, 2, 2) of symmetric positive definite matrices (the innovation covariances):
    in closed form, a tenth of the cost of ``np.linalg.inv`` on the few matrices of a scan."""
    a, b, d = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
    det = a * d - b * b
    out = np.empty_like(S)
    out[:, 0, 0] = d / det
    out[:, 1, 1] = a / det
    out[:, 0, 1] = out[:, 1, 0] = -b / det
    return out


def _sized(p: TrackerParams, r: FloatArray, cr: FloatArray) -> npt.NDArray[np.bool_]:
    """(tracks, clusters): the cluster's radius ``cr`` within ``max_shrink_m`` below and ``max_grow_m`` above
    the track's ``r``."""
    return (r[:, None] - p.max_shrink_m <= cr[None, :]) & (cr[None, :] <= r[:, None] + p.max_grow_m)


def _greedy_pairs(cost: FloatArray, ok: npt.NDArray[np.bool_]) -> tuple[list[int], list[int]]:
    """Greedy matching of rows to columns among the ``ok`` pairs, lowest ``cost`` first (ties by row, then
    column), each row and column at most once: (rows, their columns)."""
    ii, jj = np.nonzero(ok)
    rows: list[int] = []
    cols: list[int] = []
    taken_r: set[int] = set()
    taken_c: set[int] = set()
    for _, i, j in sorted(zip(cost[ii, jj].tolist(), ii.tolist(), jj.tolist())):
        if i in taken_r or j in taken_c:
            continue
        taken_r.add(i)
        taken_c.add(j)
        rows.append(i)
        cols.append(j)
    return rows, cols


# columns of ObstacleTracker._s, one row per track (floats), and of ObstacleTracker._n (integers)
_X = slice(0, 4)  # state x, y (m), vx, vy (m/s), world frame
_R, _T0, _SEEN = 4, 5, 6  # radius (m), first seen and last seen (s)
_START_X, _START_Y = 7, 8  # where the track was first seen (m)
_START = slice(_START_X, _START_Y + 1)
_TRAVEL = 9  # farthest the estimate has been from there (m)
_SEEN_X, _SEEN_Y = 10, 11  # the position it was last seen at (m)
_SEEN_XY = slice(_SEEN_X, _SEEN_Y + 1)
_WIDTH = 12
_ID, _HITS, _MISSES = 0, 1, 2


class ObstacleTracker:
    """Multi-object tracker over laser scans (module docstring). ``update(scan)`` returns the confirmed tracks.

    The tracks live in arrays, one row per track: ``_s`` (state, radius, clocks, start, travel: the column
    constants above), ``_n`` (id, hits, misses) and ``_P`` (4 x 4 covariances of the state). Every step
    predicts, gates, corrects, drops and starts tracks on all rows at once; all rows are predicted to the
    last scan's time."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params or TrackerParams()
        self.reset()

    def reset(self) -> None:
        self._s = np.zeros((0, _WIDTH))
        self._n = np.zeros((0, 3), dtype=np.int64)
        self._P = np.zeros((0, 4, 4))
        self._next = 1
        self._last_t: float | None = None
        self.stale_scans = 0  # scans older than the last one processed, skipped

    def update(self, scan: LaserScan, t_s: float | None = None) -> list[Track]:
        p = self.params
        t = scan.stamp_s if t_s is None else t_s
        cl = clusters_from_scan(scan, p.cluster_gap_m, 2, p.max_radius_m)
        return self.update_clusters([c for c in cl if not c.cut], t)

    def _predict(self, dt: float) -> None:
        """Every track ``dt`` s on: constant velocity, white acceleration of std ``accel_std_m_s2``."""
        if len(self._s) == 0 or dt <= 0.0:
            return
        qq = self.params.accel_std_m_s2**2
        F = np.array([[1.0, 0.0, dt, 0.0], [0.0, 1.0, 0.0, dt], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        a, b, c = 0.25 * dt**4 * qq, 0.5 * dt**3 * qq, dt * dt * qq  # G G^T q^2, G = (dt^2/2, dt^2/2, dt, dt)
        Q = np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])
        self._s[:, _X] = self._s[:, _X] @ F.T
        self._P = F @ self._P @ F.T + Q

    def _associate(self, clusters: list[Cluster], R: FloatArray) -> tuple[list[int], list[int]]:
        """Greedy nearest-neighbour association, best pairs first, every (track, cluster) pair gated at once:
        (track rows, their clusters)."""
        p = self.params
        if len(self._s) == 0 or not clusters:
            return [], []
        X, P, r = self._s[:, _X], self._P, self._s[:, _R]
        cz = np.array([(c.x_m, c.y_m) for c in clusters])
        cr = np.array([c.radius_m for c in clusters])
        confirmed = self._n[:, _HITS] >= p.confirm_hits
        Si = _inv2(P[:, :2, :2] + R)  # (T, 2, 2)
        dx = cz[None, :, 0] - X[:, None, 0]
        dy = cz[None, :, 1] - X[:, None, 1]
        # dz @ Si @ dz, term by term in the same order
        m2 = ((dx * Si[:, None, 0, 0] + dy * Si[:, None, 1, 0]) * dx
              + (dx * Si[:, None, 0, 1] + dy * Si[:, None, 1, 1]) * dy)
        ok = np.hypot(dx, dy) <= p.max_gate_m
        ok &= ~confirmed[:, None] | _sized(p, r, cr)
        ok &= m2 <= p.gate_sigma**2
        return _greedy_pairs(m2, ok)

    def _correct(self, rows: list[int], clusters: list[Cluster], R: FloatArray, t: float) -> None:
        """Kalman update of the tracks in ``rows`` with their clusters' centres (position-only measurement,
        noise ``R``) and radii (smoothed), seen at ``t``."""
        if not rows:
            return
        idx = np.array(rows)
        s, P = self._s[idx], self._P[idx]
        z = np.array([(c.x_m, c.y_m) for c in clusters])
        K = P[:, :, :2] @ _inv2(P[:, :2, :2] + R)  # (M, 4, 2): position-only measurement
        s[:, _X] += np.einsum("mij,mj->mi", K, z - s[:, :2])
        s[:, _R] = 0.7 * s[:, _R] + 0.3 * np.array([c.radius_m for c in clusters])
        s[:, _SEEN] = t
        s[:, _SEEN_XY] = z
        s[:, _TRAVEL] = np.maximum(s[:, _TRAVEL], np.hypot(s[:, 0] - s[:, _START_X], s[:, 1] - s[:, _START_Y]))
        self._s[idx] = s
        self._P[idx] = P - K @ P[:, :2, :]
        self._n[idx, _HITS] += 1
        self._n[idx, _MISSES] = 0

    def update_clusters(self, clusters: list[Cluster], t_s: float) -> list[Track]:
        """Fold one scan's clusters in at time ``t_s``; a scan older than the last one folded in (late,
        out of order) is skipped and counted in ``stale_scans``: predicting back in time would wind
        the tracks' clocks back and count the next interval twice."""
        p = self.params
        if self._last_t is not None and t_s < self._last_t:
            self.stale_scans += 1
            return self.tracks()
        self._predict(0.0 if self._last_t is None else t_s - self._last_t)
        self._last_t = t_s
        R = np.eye(2) * p.meas_std_m**2
        rows, cols = self._associate(clusters, R)
        self._correct(rows, [clusters[j] for j in cols], R, t_s)
        if p.reacquire_m > 0.0:
            more_rows, more_cols = self._reacquire(clusters, rows, cols, t_s)
            rows, cols = rows + more_rows, cols + more_cols
        missed = np.ones(len(self._s), dtype=bool)
        missed[rows] = False
        self._n[missed, _MISSES] += 1
        # tentative tracks go after a few misses; confirmed ones after max_coast_s unseen, or max_misses
        misses = self._n[:, _MISSES]
        if p.max_coast_s > 0:
            keep_confirmed = t_s - self._s[:, _SEEN] <= p.max_coast_s
        else:
            keep_confirmed = misses <= p.max_misses
        keep = np.where(self._n[:, _HITS] < p.confirm_hits, misses <= min(p.max_misses, p.confirm_max_misses), keep_confirmed)
        taken = set(cols)
        self._keep_and_start(keep, [c for j, c in enumerate(clusters) if j not in taken], t_s)
        return self.tracks()

    def _reacquire(self, clusters: list[Cluster], rows: list[int], cols: list[int], t: float) -> tuple[list[int], list[int]]:
        """Confirmed tracks that have travelled (``Track.MIN_TRAVEL_M`` or their radius) and were missed this
        scan take the nearest free cluster of about their size within ``reacquire_m`` of where they were last
        seen, greedily; each restarts there with the velocity of that displacement (capped at
        ``max_speed_m_s``, uncertainty ``reacquire_speed_std_m_s``). Returns (rows, clusters) taken."""
        p = self.params
        free = sorted(set(range(len(clusters))) - set(cols))
        if not free or len(self._s) == 0:
            return [], []
        s = self._s
        walker = ((self._n[:, _HITS] >= p.confirm_hits) & (s[:, _TRAVEL] >= np.maximum(Track.MIN_TRAVEL_M, s[:, _R]))
                  & (s[:, _SEEN] < t))
        walker[rows] = False
        cand = np.flatnonzero(walker)
        if len(cand) == 0:
            return [], []
        cz = np.array([(clusters[j].x_m, clusters[j].y_m) for j in free])
        cr = np.array([clusters[j].radius_m for j in free])
        d = np.hypot(cz[None, :, 0] - s[cand, _SEEN_X][:, None], cz[None, :, 1] - s[cand, _SEEN_Y][:, None])  # from where last seen
        pairs = _greedy_pairs(d, (d <= p.reacquire_m) & _sized(p, s[cand, _R], cr))
        out_rows = [int(cand[i]) for i in pairs[0]]
        out_cols = [free[j] for j in pairs[1]]
        for row, col in zip(out_rows, out_cols):
            c = clusters[col]
            v = (np.array([c.x_m, c.y_m]) - s[row, _SEEN_XY]) / max(t - s[row, _SEEN], 1e-3)
            sp = float(np.hypot(v[0], v[1]))
            if sp > p.max_speed_m_s:
                v *= p.max_speed_m_s / sp
            s[row, _X] = (c.x_m, c.y_m, v[0], v[1])
            s[row, _R] = 0.7 * s[row, _R] + 0.3 * c.radius_m
            s[row, _SEEN] = t
            s[row, _SEEN_XY] = (c.x_m, c.y_m)
            s[row, _TRAVEL] = max(s[row, _TRAVEL], float(np.hypot(c.x_m - s[row, _START_X], c.y_m - s[row, _START_Y])))
            vm, vv = p.meas_std_m**2, p.reacquire_speed_std_m_s**2
            self._P[row] = np.diag([vm, vm, vv, vv])
            self._n[row, _HITS] += 1
            self._n[row, _MISSES] = 0
        return out_rows, out_cols

    def _keep_and_start(self, keep: npt.NDArray[np.bool_], new: list[Cluster], t: float) -> None:
        """Drop the rows not kept and start a track for each cluster in ``new``, seen at ``t``."""
        if not new:
            if not keep.all():
                self._s, self._n, self._P = self._s[keep], self._n[keep], self._P[keep]
            return
        m = len(new)
        s0 = np.zeros((m, _WIDTH))
        s0[:, :2] = s0[:, _START] = s0[:, _SEEN_XY] = [(c.x_m, c.y_m) for c in new]
        s0[:, _R] = [c.radius_m for c in new]
        s0[:, _T0] = s0[:, _SEEN] = t
        n0 = np.zeros((m, 3), dtype=np.int64)
        n0[:, _ID] = np.arange(self._next, self._next + m)
        n0[:, _HITS] = 1
        self._next += m
        v = self.params.meas_std_m**2
        self._s = np.concatenate((self._s[keep], s0))
        self._n = np.concatenate((self._n[keep], n0))
        self._P = np.concatenate((self._P[keep], np.broadcast_to(np.diag([v, v, 1.0, 1.0]), (m, 4, 4))))

    def tracks(self, confirmed_only: bool = True) -> list[Track]:
        sel = self._n[:, _HITS] >= self.params.confirm_hits if confirmed_only else np.ones(len(self._s), dtype=bool)
        if not sel.any():
            return []
        s, n, P = self._s[sel], self._n[sel], self._P[sel]
        # speed sigma along the velocity direction (isotropic fallback when at rest)
        sp = np.hypot(s[:, 2], s[:, 3])
        moving = sp > 1e-6
        k = np.where(moving, sp, 1.0)
        ux, uy = np.where(moving, s[:, 2] / k, 1.0), np.where(moving, s[:, 3] / k, 0.0)
        along = (ux * P[:, 2, 2] + uy * P[:, 3, 2]) * ux + (ux * P[:, 2, 3] + uy * P[:, 3, 3]) * uy
        sig = np.sqrt(np.maximum(np.where(moving, along, 0.5 * (P[:, 2, 2] + P[:, 3, 3])), 0.0)).tolist()
        now = self._last_t if self._last_t is not None else 0.0
        return [Track(i, x, y, vx, vy, r, sg, tuple(map(tuple, cv)), now - t0, h, tv, now - seen)
                for (x, y, vx, vy, r, t0, seen, _sx, _sy, tv, _lx, _ly), (i, h, _m), sg, cv
                in zip(s.tolist(), n.tolist(), sig, P.tolist())]
