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
was first seen, *and* it moves from sighting to sighting without jumps (``Track.pair_speed_m_s``), *and* the
place it is at has not had laser returns for long (``Track.standing_s``: a track hopping from plant to plant
along a crop row gathers a speed from its hops while every plant it takes stands still and has been seen
there all along); a track is confirmed only by ``confirm_hits`` scans with no more than
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
from typing import NamedTuple

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


class _Clusters(NamedTuple):
    """A scan's clusters as arrays, one row per cluster: centre (k, 2) (m), radius (k,) (m), point count (k,),
    cut (k,) (:class:`Cluster`'s fields; the tracker works on these, without one object per cluster)."""

    xy: FloatArray
    radius_m: FloatArray
    n_points: npt.NDArray[np.int64]
    cut: npt.NDArray[np.bool_]
    first: npt.NDArray[np.int64]  # index of its first point in the points clustered (-1: not known)

    def to_list(self) -> list[Cluster]:
        return [Cluster(x, y, r, n, c) for (x, y), r, n, c
                in zip(self.xy.tolist(), self.radius_m.tolist(), self.n_points.tolist(), self.cut.tolist())]

    def take(self, sel: npt.NDArray[np.bool_]) -> "_Clusters":
        return _Clusters(self.xy[sel], self.radius_m[sel], self.n_points[sel], self.cut[sel], self.first[sel])

    @staticmethod
    def of(clusters: list[Cluster]) -> "_Clusters":
        return _Clusters(np.array([(c.x_m, c.y_m) for c in clusters], dtype=float).reshape(-1, 2),
                         np.array([c.radius_m for c in clusters], dtype=float),
                         np.array([c.n_points for c in clusters], dtype=np.int64),
                         np.array([c.cut for c in clusters], dtype=bool), np.full(len(clusters), -1, dtype=np.int64))


_NO_CLUSTERS = _Clusters(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool),
                         np.zeros(0, dtype=np.int64))


def cluster_points(xy: ScanXY, sensor_xy: tuple[float, float] = (0.0, 0.0), gap_m: float = 0.2,
                   min_points: int = 2, max_radius_m: float = 1.5, range_max_m: float = math.inf,
                   range_edge_m: float = 0.15, at_view_edge: npt.NDArray[np.bool_] | None = None) -> list[Cluster]:
    """Split beam-ordered points (k, 2) into clusters (module docstring); clusters with fewer than
    ``min_points`` points or a radius above ``max_radius_m`` (walls, rows) are dropped. A cluster with
    a point farther than ``range_max_m - range_edge_m`` from the sensor, or one of the points marked in
    ``at_view_edge`` (k,) (the first and last beams of a scan, beams beside a nearer return), is
    flagged ``cut``."""
    return _cluster_arrays(xy, sensor_xy, gap_m, min_points, max_radius_m, range_max_m, range_edge_m,
                           at_view_edge).to_list()


def _cluster_arrays(xy: ScanXY, sensor_xy: tuple[float, float], gap_m: float, min_points: int,
                    max_radius_m: float, range_max_m: float, range_edge_m: float = 0.15,
                    at_view_edge: npt.NDArray[np.bool_] | None = None) -> _Clusters:
    """:func:`cluster_points` as arrays."""
    if len(xy) == 0:
        return _NO_CLUSTERS
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
    keep = (count >= min_points) & (r <= max_radius_m)
    m, near, r, count, cut, start = m[keep], near[keep], r[keep], count[keep], cut[keep], start[keep]
    # the centre: on the bearing of the points' mean, one radius beyond the nearest point
    ux, uy = m[:, 0] - sx, m[:, 1] - sy
    nu = np.hypot(ux, uy)
    away = nu > 1e-9
    f = (near + r) / np.where(away, nu, 1.0)
    c = np.where(away[:, None], np.column_stack((sx + f * ux, sy + f * uy)), m)
    return _Clusters(c, r, count.astype(np.int64), cut, start.astype(np.int64))


def clusters_from_scan(scan: LaserScan, gap_m: float = 0.2, min_points: int = 2, max_radius_m: float = 1.5,
                       world: bool = True) -> list[Cluster]:
    """Clusters of a scan, in the world frame when the scan carries its pose (and ``world``), else the sensor frame."""
    return _scan_clusters(scan, gap_m, min_points, max_radius_m, world)[1].to_list()


def _scan_clusters(scan: LaserScan, gap_m: float = 0.2, min_points: int = 2, max_radius_m: float = 1.5,
                   world: bool = True) -> tuple[FloatArray, _Clusters]:
    """:func:`clusters_from_scan` as arrays, with the scan's cleaned points (k, 2) in the same frame."""
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
    return xy, _cluster_arrays(xy, (pose.x_m, pose.y_m), gap_m, min_points, max_radius_m, scan.range_max_m,
                               at_view_edge=at_edge)


class _Standing:
    """How long each place has had laser returns without a break: cells of ``cell_m`` on a toroidal grid of
    ``CELLS`` x ``CELLS`` (a window of 51.2 m at 0.1 m, beyond any laser's reach: two places sharing a cell are
    never in view together), each with the first and the last time of its current run of returns (a run
    ends after ``gap_s`` without one)."""

    CELLS = 512

    def __init__(self, cell_m: float, gap_s: float) -> None:
        self.cell_m, self.gap_s = cell_m, gap_s
        self.first = np.full((self.CELLS, self.CELLS), -np.inf)
        self.last = np.full((self.CELLS, self.CELLS), -np.inf)

    def add(self, xy: FloatArray, t: float) -> None:
        """The returns (k, 2) of a scan at ``t``."""
        ij = np.floor(xy / self.cell_m).astype(np.int64) % self.CELLS
        i, j = ij[:, 0], ij[:, 1]
        self.first[i, j] = np.where(t - self.last[i, j] > self.gap_s, t, self.first[i, j])
        self.last[i, j] = t

    def held_s(self, xy: FloatArray, t: float) -> FloatArray:
        """For each place (n, 2): the longest run of returns, up to ``t``, among its cell and the eight around it
        (0 where none has had a return in the last ``gap_s``)."""
        ij = np.floor(xy / self.cell_m).astype(np.int64)
        d = np.arange(-1, 2)
        i = (ij[:, 0, None, None] + d[None, :, None]) % self.CELLS
        j = (ij[:, 1, None, None] + d[None, None, :]) % self.CELLS
        held = np.where(t - self.last[i, j] <= self.gap_s, t - self.first[i, j], 0.0)
        longest: FloatArray = held.reshape(len(xy), -1).max(axis=1)
        return longest


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
    # its speed from sighting to sighting (m/s): over its last PAIRS_KEPT pairs of sightings, those in
    # consecutive scans when there are MIN_PAIRS of them (else those with one scan missed at most), the
    # displacement along the estimated velocity per second; 0 with fewer than MIN_PAIRS pairs or when one
    # jumped (JUMP_M farther than the speed goes in that time)
    pair_speed_m_s: float = math.inf
    # how long the laser has had returns without a break (s) from the place it is at (its cell and the eight
    # around it, TrackerParams.standing_cell_m): a standing thing there, a plant or a post, when long
    standing_s: float = 0.0

    MIN_TRAVEL_M = 0.3  # a moving object has gone at least this far from where it was first seen
    MIN_PAIRS = 3
    PAIR_SPEED_SHARE = 0.5  # ... and moved from scan to scan at this share of its speed
    JUMP_M = 0.1
    STANDING_S = 1.5  # ... and where it is now has not had returns for longer than this (s)

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.vx_m_s, self.vy_m_s)

    @property
    def moving(self) -> bool:
        """Speed more than twice its uncertainty and above 0.1 m/s, and ``MIN_TRAVEL_M`` or its own radius
        travelled, whichever is more (module docstring): the centre of a large static object wanders by
        about its radius as a passing robot sees other faces of it (a 1.5 x 0.8 m box passed at 2 m/s
        "moved" 0.32 m at up to 0.56 m/s). And the object moves from sighting to sighting: between its recent
        sightings (in consecutive scans when it has enough such) it went at least ``PAIR_SPEED_SHARE`` of its
        speed along its velocity, without a jump (``pair_speed_m_s``). A track hopping from plant to plant
        along a crop row gathers a speed of 0.3-1.5 m/s from its hops alone: each plant stands still while
        it is seen (steps of 0.3-2 cm from scan to scan) and the next one, 0.2 m on, is taken at once (a
        jump) or after a scan or two missed. A walker seen only in every other scan is judged on those
        sightings."""
        sp = self.speed_m_s
        return (sp > max(0.1, 2.0 * self.speed_sigma_m_s)
                and self.travel_m >= max(self.MIN_TRAVEL_M, self.radius_m)
                and self.pair_speed_m_s >= self.PAIR_SPEED_SHARE * sp
                and self.standing_s <= self.STANDING_S)


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
    # Track.standing_s: the grid's cell (m) and the break (s) that ends a place's run of returns; 0: not kept
    standing_cell_m: float = 0.1
    standing_gap_s: float = 0.5


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
_WALKED = 3  # 1 once the track has been output as moving (by movers())
_NWIDTH = 4
PAIRS_KEPT = 5  # displacements between sightings kept per track (ObstacleTracker._pv)


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
        self._n = np.zeros((0, _NWIDTH), dtype=np.int64)
        self._P = np.zeros((0, 4, 4))
        # displacements between sightings: dx, dy (m), dt (s), scans missed in between; newest first, nan: none yet
        self._pv = np.zeros((0, PAIRS_KEPT, 4))
        self._next = 1
        self._last_t: float | None = None
        p = self.params
        self._standing = _Standing(p.standing_cell_m, p.standing_gap_s) if p.standing_cell_m > 0 else None
        self.stale_scans = 0  # scans older than the last one processed, skipped

    def update(self, scan: LaserScan, t_s: float | None = None, movers_only: bool = False) -> list[Track]:
        """Fold one scan in (at ``t_s``, default its stamp): the confirmed tracks, or with ``movers_only`` only
        :meth:`movers` (much cheaper among plant rows, where most tracks are plants)."""
        p = self.params
        t = scan.stamp_s if t_s is None else t_s
        xy, cl = _scan_clusters(scan, p.cluster_gap_m, 2, p.max_radius_m)
        used = cl.take(~cl.cut)
        fresh = self._last_t is None or t >= self._last_t
        walkers = self._fold(used, t)
        if self._standing is not None and fresh and scan.pose is not None:
            # the places of standing things: not the points of the walkers' clusters (people passing each
            # other, or one turning round on his own trail, would make their places look held)
            mine = np.zeros(len(xy) + 1, dtype=np.int64)
            np.add.at(mine, used.first[walkers], 1)
            np.add.at(mine, used.first[walkers] + used.n_points[walkers], -1)
            self._standing.add(xy[np.cumsum(mine[:-1]) == 0], t)
        return self.movers() if movers_only else self.tracks()

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

    def _associate(self, cz: FloatArray, cr: FloatArray, R: FloatArray) -> tuple[list[int], list[int]]:
        """Greedy nearest-neighbour association, best pairs first, every (track, cluster) pair gated at once:
        (track rows, their clusters: centres ``cz`` (k, 2), radii ``cr``)."""
        p = self.params
        if len(self._s) == 0 or len(cz) == 0:
            return [], []
        X, P, r = self._s[:, _X], self._P, self._s[:, _R]
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

    def _correct(self, rows: list[int], z: FloatArray, zr: FloatArray, R: FloatArray, t: float) -> None:
        """Kalman update of the tracks in ``rows`` with their clusters' centres ``z`` (position-only
        measurement, noise ``R``) and radii ``zr`` (smoothed), seen at ``t``."""
        if not rows:
            return
        idx = np.array(rows)
        s, P = self._s[idx], self._P[idx]
        dt = t - s[:, _SEEN]
        pair = dt > 0.0
        if pair.any():
            at = idx[pair]
            pv = self._pv[at]
            pv[:, 1:] = pv[:, :-1]
            pv[:, 0, :2] = z[pair] - s[pair, _SEEN_XY]
            pv[:, 0, 2] = dt[pair]
            pv[:, 0, 3] = self._n[at, _MISSES]  # scans missed in between
            self._pv[at] = pv
        K = P[:, :, :2] @ _inv2(P[:, :2, :2] + R)  # (M, 4, 2): position-only measurement
        s[:, _X] += np.einsum("mij,mj->mi", K, z - s[:, :2])
        s[:, _R] = 0.7 * s[:, _R] + 0.3 * zr
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
        self._fold(_Clusters.of(clusters), t_s)
        return self.tracks()

    def _fold(self, cl: _Clusters, t_s: float) -> npt.NDArray[np.intp]:
        """:meth:`update_clusters` without building the output: the clusters taken by tracks that have been
        output as moving (:meth:`movers`)."""
        p = self.params
        if self._last_t is not None and t_s < self._last_t:
            self.stale_scans += 1
            return np.zeros(0, dtype=np.intp)
        self._predict(0.0 if self._last_t is None else t_s - self._last_t)
        self._last_t = t_s
        R = np.eye(2) * p.meas_std_m**2
        cz, cr = cl.xy, cl.radius_m
        rows, cols = self._associate(cz, cr, R)
        self._correct(rows, cz[cols], cr[cols], R, t_s)
        if p.reacquire_m > 0.0:
            more_rows, more_cols = self._reacquire(cz, cr, rows, cols, t_s)
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
        new = np.ones(len(cz), dtype=bool)
        new[cols] = False
        walkers = np.array([c for r, c in zip(rows, cols) if self._n[r, _WALKED] == 1], dtype=np.intp)
        self._keep_and_start(keep, cz[new], cr[new], t_s)
        return walkers

    def _reacquire(self, cz: FloatArray, cr: FloatArray, rows: list[int], cols: list[int],
                   t: float) -> tuple[list[int], list[int]]:
        """Confirmed tracks that have travelled (``Track.MIN_TRAVEL_M`` or their radius) and were missed this
        scan take the nearest free cluster of about their size within ``reacquire_m`` of where they were last
        seen, greedily; each restarts there with the velocity of that displacement (capped at
        ``max_speed_m_s``, uncertainty ``reacquire_speed_std_m_s``). Returns (rows, clusters) taken."""
        p = self.params
        free = sorted(set(range(len(cz))) - set(cols))
        if not free or len(self._s) == 0:
            return [], []
        s = self._s
        walker = ((self._n[:, _HITS] >= p.confirm_hits) & (s[:, _TRAVEL] >= np.maximum(Track.MIN_TRAVEL_M, s[:, _R]))
                  & (s[:, _SEEN] < t))
        walker[rows] = False
        cand = np.flatnonzero(walker)
        if len(cand) == 0:
            return [], []
        fz, fr = cz[free], cr[free]
        d = np.hypot(fz[None, :, 0] - s[cand, _SEEN_X][:, None], fz[None, :, 1] - s[cand, _SEEN_Y][:, None])  # from where last seen
        pairs = _greedy_pairs(d, (d <= p.reacquire_m) & _sized(p, s[cand, _R], fr))
        out_rows = [int(cand[i]) for i in pairs[0]]
        out_cols = [free[j] for j in pairs[1]]
        for row, col in zip(out_rows, out_cols):
            cx, cy = cz[col].tolist()
            c_r = float(cr[col])
            v = (np.array([cx, cy]) - s[row, _SEEN_XY]) / max(t - s[row, _SEEN], 1e-3)
            sp = float(np.hypot(v[0], v[1]))
            if sp > p.max_speed_m_s:
                v *= p.max_speed_m_s / sp
            s[row, _X] = (cx, cy, v[0], v[1])
            s[row, _R] = 0.7 * s[row, _R] + 0.3 * c_r
            s[row, _SEEN] = t
            s[row, _SEEN_XY] = (cx, cy)
            s[row, _TRAVEL] = max(s[row, _TRAVEL], float(np.hypot(cx - s[row, _START_X], cy - s[row, _START_Y])))
            vm, vv = p.meas_std_m**2, p.reacquire_speed_std_m_s**2
            self._P[row] = np.diag([vm, vm, vv, vv])
            self._pv[row] = np.nan  # displacements of the other way
            self._n[row, _HITS] += 1
            self._n[row, _MISSES] = 0
        return out_rows, out_cols

    def _keep_and_start(self, keep: npt.NDArray[np.bool_], new_xy: FloatArray, new_r: FloatArray, t: float) -> None:
        """Drop the rows not kept and start a track for each new cluster (centres ``new_xy`` (m, 2), radii
        ``new_r``), seen at ``t``."""
        m = len(new_xy)
        if m == 0:
            if not keep.all():
                self._s, self._n, self._P, self._pv = self._s[keep], self._n[keep], self._P[keep], self._pv[keep]
            return
        s0 = np.zeros((m, _WIDTH))
        s0[:, :2] = s0[:, _START] = s0[:, _SEEN_XY] = new_xy
        s0[:, _R] = new_r
        s0[:, _T0] = s0[:, _SEEN] = t
        n0 = np.zeros((m, _NWIDTH), dtype=np.int64)
        n0[:, _ID] = np.arange(self._next, self._next + m)
        n0[:, _HITS] = 1
        self._next += m
        v = self.params.meas_std_m**2
        self._s = np.concatenate((self._s[keep], s0))
        self._n = np.concatenate((self._n[keep], n0))
        self._P = np.concatenate((self._P[keep], np.broadcast_to(np.diag([v, v, 1.0, 1.0]), (m, 4, 4))))
        self._pv = np.concatenate((self._pv[keep], np.full((m, PAIRS_KEPT, 4), np.nan)))

    def tracks(self, confirmed_only: bool = True) -> list[Track]:
        """The tracks at the last scan folded in (only the confirmed ones by default)."""
        sel = self._n[:, _HITS] >= self.params.confirm_hits if confirmed_only else np.ones(len(self._s), dtype=bool)
        return self._tracks(np.flatnonzero(sel))

    def movers(self) -> list[Track]:
        """The confirmed tracks that are :attr:`Track.moving` now or have been at an earlier call of this
        method (a walker who stops or turns round, slowing, stays among them until his track is dropped).
        Only tracks that could be moving are built: among plant rows a small part of :meth:`tracks`."""
        n = self._n
        idx = np.flatnonzero(n[:, _HITS] >= self.params.confirm_hits)
        if len(idx) == 0:
            return []
        c = self._columns(idx)
        s = self._s[idx]
        loose = 1.0 - 1e-9  # the test of Track.moving in arrays, a hair looser: the records decide
        could = ((c.speed > np.maximum(0.1, 2.0 * c.sigma) * loose)
                 & (s[:, _TRAVEL] >= np.maximum(Track.MIN_TRAVEL_M, s[:, _R]) * loose)
                 & (c.pair >= Track.PAIR_SPEED_SHARE * c.speed * loose - 1e-12)
                 & (c.held <= Track.STANDING_S / loose))
        pick = np.flatnonzero(could | (n[idx, _WALKED] == 1))
        out = self._build(idx[pick], _Columns(*(col[pick] for col in c)))
        for tr, row in zip(out, idx[pick].tolist()):
            if tr.moving:
                self._n[row, _WALKED] = 1
        return [tr for tr, row in zip(out, idx[pick].tolist()) if self._n[row, _WALKED] == 1]

    def _tracks(self, idx: npt.NDArray[np.intp]) -> list[Track]:
        """Track records of the rows ``idx``."""
        if len(idx) == 0:
            return []
        return self._build(idx, self._columns(idx))

    def _columns(self, idx: npt.NDArray[np.intp]) -> "_Columns":
        """The derived fields of the rows ``idx`` (:class:`_Columns`)."""
        s, P = self._s[idx], self._P[idx]
        # speed sigma along the velocity direction (isotropic fallback when at rest)
        sp = np.hypot(s[:, 2], s[:, 3])
        moving = sp > 1e-6
        k = np.where(moving, sp, 1.0)
        ux, uy = np.where(moving, s[:, 2] / k, 1.0), np.where(moving, s[:, 3] / k, 0.0)
        along = (ux * P[:, 2, 2] + uy * P[:, 3, 2]) * ux + (ux * P[:, 2, 3] + uy * P[:, 3, 3]) * uy
        sig = np.sqrt(np.maximum(np.where(moving, along, 0.5 * (P[:, 2, 2] + P[:, 3, 3])), 0.0))
        # speed from sighting to sighting along the estimated velocity (Track.pair_speed_m_s)
        pv = self._pv[idx]
        consecutive = pv[:, :, 3] == 0.0  # (nan compares false: no pair)
        have = np.where((np.count_nonzero(consecutive, axis=1) >= Track.MIN_PAIRS)[:, None], consecutive, pv[:, :, 3] <= 1.0)
        dts = np.where(have, pv[:, :, 2], 0.0)
        along = np.where(have, pv[:, :, 0] * ux[:, None] + pv[:, :, 1] * uy[:, None], 0.0)
        with np.errstate(invalid="ignore"):  # nan (no pair) is no jump
            jump = (have & (np.hypot(pv[:, :, 0], pv[:, :, 1]) > sp[:, None] * dts + Track.JUMP_M)).any(axis=1)
        ok = (np.count_nonzero(have, axis=1) >= Track.MIN_PAIRS) & ~jump
        pair = np.where(ok, along.sum(axis=1) / np.where(ok, dts.sum(axis=1), 1.0), 0.0)
        now = self._last_t if self._last_t is not None else 0.0
        held = self._standing.held_s(s[:, :2], now) if self._standing is not None else np.zeros(len(idx))
        return _Columns(sp, sig, pair, held)

    def _build(self, idx: npt.NDArray[np.intp], c: "_Columns") -> list[Track]:
        """Track records of the rows ``idx`` with their derived fields ``c``."""
        s, n, P = self._s[idx], self._n[idx], self._P[idx]
        now = self._last_t if self._last_t is not None else 0.0
        return [Track(i, x, y, vx, vy, r, sg, tuple(map(tuple, cv)), now - t0, h, tv, now - seen, ps, hd)
                for (x, y, vx, vy, r, t0, seen, _sx, _sy, tv, _lx, _ly), (i, h, _m, _w), sg, cv, ps, hd
                in zip(s.tolist(), n.tolist(), c.sigma.tolist(), P.tolist(), c.pair.tolist(), c.held.tolist())]


class _Columns(NamedTuple):
    """Derived fields of some tracks' rows: speed and its sigma (m/s), pair speed (m/s), standing (s)."""

    speed: FloatArray
    sigma: FloatArray
    pair: FloatArray
    held: FloatArray
