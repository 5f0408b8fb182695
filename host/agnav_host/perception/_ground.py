"""Ground obstacles from a laser pitched down at the ground (ref 000, sections 4.8 and 5.5).

A beam at scan-plane angle ``alpha`` from a laser ``H`` above flat ground and pitched down by ``theta``
meets the ground at the slant range ``D = H / (sin(theta) cos(alpha))`` (ref 000's equation for the
flat-ground reading; the printed formula was lost, this is the geometry of its Fig. 5-9). A return
at range ``d`` lies at height ``z = H - d cos(alpha) sin(theta)``.

* hole (negative obstacle): ``d > D + hole_range_m`` (ref 000: a reading longer than the flat-ground
  reading by more than L; L = 0.2 m along the beam, which at 20 deg tilt is a dip of only 7 cm, so a
  hole short in the direction of travel, whose far wall stops the beam early, is still seen), or no return at all on a run of at least ``min_hole_run`` beams whose flat-ground range is within
  reach (the beam fell into something deeper than the laser's range);
* step / positive obstacle: ``z > step_height_m``, or two neighbouring returns whose heights differ
  by more than ``step_height_m`` (ref 000 eq. 30, L = 0.2 m);
* rough ground: the dispersion of the surface normals over a small window exceeds ``roughness_max``
  (ref 000 gives 0.2; see :func:`terrain_roughness`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np
import numpy.typing as npt

from ..types import DriveCommand, FloatArray, LaserScan, Observation, Pose2D, ScanXY

__all__ = [
    "TiltedMount",
    "GroundParams",
    "GroundObstacles",
    "expected_ground_range_m",
    "ground_points",
    "detect_ground_obstacles",
    "terrain_roughness",
    "GroundTracker",
    "GroundObstacleMap",
    "scan_with_virtual_obstacles",
    "GroundGuardParams",
    "GroundGuard",
]


@dataclass(frozen=True)
class TiltedMount:
    """Pose of a ground-seeing laser: height above the ground (m), pitch down (rad), pose on the robot."""

    height_m: float = 0.5
    tilt_rad: float = math.radians(20.0)
    mount: Pose2D = field(default_factory=Pose2D)

    def __post_init__(self) -> None:
        if not (self.height_m > 0 and 0 < self.tilt_rad < math.pi / 2):
            raise ValueError("TiltedMount needs height_m > 0 and 0 < tilt_rad < 90 deg")


@dataclass(frozen=True)
class GroundParams:
    """Thresholds (SI units; roughness is dimensionless)."""

    step_height_m: float = 0.2  # ref 000: L = 0.2 m
    hole_range_m: float = 0.2  # ref 000: L, the reading's excess over the flat-ground range
    roughness_max: float = 0.2  # ref 000: R > 0.2 is impassable
    neighbour_max_gap_m: float = 0.3  # two returns count as neighbours when this close horizontally
    usable_range_m: float = 3.9  # missing returns count as a hole only where flat ground is this close
    min_hole_run: int = 2
    min_hole_depth_m: float = 0.0  # a long reading is a hole only if its return lies this far below ground
    # (0: ref 000's range rule alone; a robot that can cross shallow dips such as ruts sets its wheels' limit)

    def __post_init__(self) -> None:
        if not (self.step_height_m > 0 and self.hole_range_m > 0 and self.roughness_max > 0 and self.min_hole_run >= 1
                and self.min_hole_depth_m >= 0):
            raise ValueError("GroundParams: thresholds must be > 0, min_hole_depth_m >= 0 and min_hole_run >= 1")


@dataclass(frozen=True)
class GroundObstacles:
    """Per-beam classification of one tilted scan (arrays (n,), one entry per beam) and the obstacle
    points in the robot frame (k, 2), m. Holes are placed where the beam would have met flat ground."""

    z_m: FloatArray
    expected_range_m: FloatArray
    hole: npt.NDArray[np.bool_]
    step: npt.NDArray[np.bool_]
    holes_xy: ScanXY
    steps_xy: ScanXY

    @property
    def any(self) -> bool:
        return bool(self.hole.any() or self.step.any())


def expected_ground_range_m(angles_rad: FloatArray, height_m: float, tilt_rad: float) -> FloatArray:
    """Slant range to flat ground ``D = H / (sin(theta) cos(alpha))`` per beam, m; inf where the beam
    does not point down (|alpha| >= 90 deg)."""
    ca = np.cos(np.asarray(angles_rad, dtype=float))
    with np.errstate(divide="ignore"):
        return np.where(ca > 1e-9, height_m / (math.sin(tilt_rad) * np.maximum(ca, 1e-12)), np.inf)


def _to_robot(x: FloatArray, y: FloatArray, mount: Pose2D) -> tuple[FloatArray, FloatArray]:
    c, s = math.cos(mount.yaw_rad), math.sin(mount.yaw_rad)
    return mount.x_m + c * x - s * y, mount.y_m + s * x + c * y


def ground_points(scan: LaserScan, tm: TiltedMount) -> FloatArray:
    """Returns as 3-D points (n, 3) in the robot frame (z = 0 on flat ground), m; NaN rows for no return."""
    r = np.asarray(scan.ranges_m, dtype=float)
    r = np.where(np.isfinite(r) & (r > 0), r, np.nan)
    a = scan.angles_rad
    ct, st = math.cos(tm.tilt_rad), math.sin(tm.tilt_rad)
    xs, ys = r * np.cos(a) * ct, r * np.sin(a)
    x, y = _to_robot(xs, ys, tm.mount)
    return np.column_stack((x, y, tm.height_m - r * np.cos(a) * st))


def detect_ground_obstacles(scan: LaserScan, tm: TiltedMount, params: GroundParams | None = None) -> GroundObstacles:
    """Holes and steps in one tilted scan (see the module docstring)."""
    p = params or GroundParams()
    a = scan.angles_rad
    D = expected_ground_range_m(a, tm.height_m, tm.tilt_rad)
    pts = ground_points(scan, tm)
    z = pts[:, 2]
    valid = np.isfinite(z)
    reach = D <= min(p.usable_range_m, scan.range_max_m)
    with np.errstate(invalid="ignore"):
        hole = valid & np.isfinite(D) & (np.asarray(scan.ranges_m, dtype=float) > D + p.hole_range_m)
        if p.min_hole_depth_m > 0:
            hole &= z < -p.min_hole_depth_m
        step = valid & (z > p.step_height_m)
    # runs of missing returns where flat ground was in reach
    miss = ~valid & reach
    if p.min_hole_run > 1 and miss.any():
        idx = np.flatnonzero(np.diff(np.concatenate(([0], miss.astype(np.int8), [0]))))
        starts, ends = idx[0::2], idx[1::2]
        keep = np.zeros_like(miss)
        for s0, e0 in zip(starts, ends):
            if e0 - s0 >= p.min_hole_run:
                keep[s0:e0] = True
        miss = keep
    hole |= miss
    # neighbouring returns with a height jump (ref 000 eq. 30): mark the higher one as a step
    vi = np.flatnonzero(valid)
    if len(vi) >= 2:
        i0, i1 = vi[:-1], vi[1:]
        gap = np.hypot(pts[i1, 0] - pts[i0, 0], pts[i1, 1] - pts[i0, 1])
        dz = z[i1] - z[i0]
        jump = (np.abs(dz) > p.step_height_m) & (gap < p.neighbour_max_gap_m)
        step[np.where(dz > 0, i1, i0)[jump]] = True
    ct = math.cos(tm.tilt_rad)
    Dh = np.where(np.isfinite(D), D, 0.0)
    hx, hy = _to_robot(Dh * np.cos(a) * ct, Dh * np.sin(a), tm.mount)
    holes_xy = np.column_stack((hx[hole], hy[hole]))
    steps_xy = pts[step][:, :2]
    return GroundObstacles(z, D, hole, step, holes_xy, steps_xy)


def terrain_roughness(grid: FloatArray, window: int = 3) -> FloatArray:
    """Roughness (m, n) of a grid of surface points (m, n, 3): scan lines x beams, any frame with z up.

    The normal at each point is the cross product of the two numerical tangents (along the beams and
    across the scan lines, ref 000 Fig. 4-15), turned to point up. Roughness is the root-mean-square
    deviation of the unit normals from their mean over a ``window`` x ``window`` neighbourhood:
    ``R = sqrt(sum_i |n_i - n_mean|^2 / n_p)``. Reconstruction: ref 000's equation was lost in the text;
    this dispersion is 0 on any plane, grows with unevenness, and is dimensionless (the reference
    states its 0.2 threshold in m). NaN where the neighbourhood has no valid normal.
    """
    g = np.asarray(grid, dtype=float)
    if g.ndim != 3 or g.shape[2] != 3 or g.shape[0] < 2 or g.shape[1] < 2:
        raise ValueError(f"grid must be (m >= 2, n >= 2, 3), got {g.shape}")
    tb = np.gradient(g, axis=1)
    tl = np.gradient(g, axis=0)
    n = np.cross(tb, tl)
    n = n * np.where(n[..., 2:3] < 0, -1.0, 1.0)
    nrm = np.linalg.norm(n, axis=2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / nrm
    ok = np.all(np.isfinite(n), axis=2)
    n0 = np.where(ok[..., None], n, 0.0)
    k = max(1, int(window))
    pad = k // 2

    def box(a: FloatArray) -> FloatArray:
        ap = np.pad(a, [(pad, k - 1 - pad), (pad, k - 1 - pad)] + [(0, 0)] * (a.ndim - 2))
        c = np.cumsum(np.cumsum(ap, axis=0), axis=1)
        c = np.pad(c, [(1, 0), (1, 0)] + [(0, 0)] * (a.ndim - 2))
        return np.asarray(c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k])

    cnt = box(ok.astype(float))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = box(n0) / cnt[..., None]
        sq = box((n0 * n0).sum(axis=2)) / cnt
        var = sq - (mean * mean).sum(axis=2)
    r = np.sqrt(np.maximum(var, 0.0))
    return np.where(cnt > 0, r, np.nan)


class GroundTracker:
    """Keeps the last ``lines`` tilted scans (as world-frame 3-D points through the robot pose) so the
    roughness of :func:`terrain_roughness` can be computed across scan lines as the robot moves.

    A scan becomes a new line only once the robot has moved ``min_line_m`` since the last line: two
    lines taken from one spot differ by range noise alone, which makes every normal the laser plane's
    own and the ground read as smooth whatever it is. Until the robot has moved, the roughness is NaN
    (unknown); while it stands, the last line's roughness is repeated."""

    def __init__(self, tm: TiltedMount, params: GroundParams | None = None, lines: int = 3, window: int = 3,
                 min_line_m: float = 0.02) -> None:
        if lines < 2:
            raise ValueError("GroundTracker needs at least 2 lines")
        self.tm, self.params, self.lines, self.window = tm, params or GroundParams(), lines, window
        self.min_line_m = min_line_m
        self.reset()

    def reset(self) -> None:
        self._hist: list[FloatArray] = []
        self._line_xy: tuple[float, float] | None = None  # robot position at the last line
        self._rough: FloatArray | None = None

    def update(self, scan: LaserScan, robot_pose: Pose2D) -> tuple[GroundObstacles, FloatArray]:
        """Classify ``scan`` and return it with the roughness (n,) of its line (NaN until the robot has
        moved over 2 lines, or for a scan of fewer than 2 beams)."""
        obs = detect_ground_obstacles(scan, self.tm, self.params)
        pts = ground_points(scan, self.tm)
        c, s = math.cos(robot_pose.yaw_rad), math.sin(robot_pose.yaw_rad)
        world = np.column_stack((robot_pose.x_m + c * pts[:, 0] - s * pts[:, 1], robot_pose.y_m + s * pts[:, 0] + c * pts[:, 1], pts[:, 2]))
        if len(world) < 2:
            return obs, np.full(len(world), np.nan)
        if self._hist and len(self._hist[-1]) != len(world):
            self.reset()
        xy = (robot_pose.x_m, robot_pose.y_m)
        if self._line_xy is None or math.hypot(xy[0] - self._line_xy[0], xy[1] - self._line_xy[1]) >= self.min_line_m:
            self._line_xy = xy
            self._hist = (self._hist + [world])[-self.lines:]
            self._rough = terrain_roughness(np.stack(self._hist), self.window)[-1] if len(self._hist) >= 2 else None
        if self._rough is None:
            return obs, np.full(len(world), np.nan)
        return obs, self._rough.copy()


class GroundObstacleMap:
    """Ground obstacles (holes, steps) seen by the tilted laser, remembered in the world frame.

    The tilted laser sees the ground only on one line ahead; a hole the robot has driven past that line is
    no longer in its scan. Each scan's obstacle points go, through the robot's pose, into cells of
    ``cell_m``; cells further than ``memory_m`` from the robot are forgotten."""

    def __init__(self, tm: TiltedMount, params: GroundParams | None = None, cell_m: float = 0.15,
                 memory_m: float = 15.0) -> None:
        if not (cell_m > 0 and memory_m > 0):
            raise ValueError("GroundObstacleMap needs cell_m > 0 and memory_m > 0")
        self.tm, self.params, self.cell_m, self.memory_m = tm, params or GroundParams(), cell_m, memory_m
        self._cells: set[tuple[int, int]] = set()

    def reset(self) -> None:
        self._cells = set()

    def update(self, scan: LaserScan, robot_pose: Pose2D) -> GroundObstacles:
        """Classify ``scan`` (robot at ``robot_pose``), add its obstacles, forget far cells; returns the classification."""
        g = detect_ground_obstacles(scan, self.tm, self.params)
        pts = np.vstack((g.holes_xy, g.steps_xy))
        if len(pts):
            c, s = math.cos(robot_pose.yaw_rad), math.sin(robot_pose.yaw_rad)
            wx = robot_pose.x_m + c * pts[:, 0] - s * pts[:, 1]
            wy = robot_pose.y_m + s * pts[:, 0] + c * pts[:, 1]
            ij = np.floor(np.column_stack((wx, wy)) / self.cell_m).astype(int)
            self._cells.update(map(tuple, ij.tolist()))
        if self._cells:
            xy = self.points_xy
            far = np.hypot(xy[:, 0] - robot_pose.x_m, xy[:, 1] - robot_pose.y_m) > self.memory_m
            if far.any():
                for ij in np.floor(xy[far] / self.cell_m).astype(int).tolist():
                    self._cells.discard(tuple(ij))
        return g

    @property
    def points_xy(self) -> ScanXY:
        """Centres (k, 2) of the remembered obstacle cells, world frame, m."""
        if not self._cells:
            return np.zeros((0, 2))
        return (np.array(sorted(self._cells), dtype=float) + 0.5) * self.cell_m


def scan_with_virtual_obstacles(scan: LaserScan, sensor_pose: Pose2D, points_xy: ScanXY, radius_m: float) -> LaserScan:
    """``scan`` with each world point of ``points_xy`` added as a post of ``radius_m``: every beam that would
    meet the post returns the post's near side if that is nearer than its own reading. This is how a planner
    that only reads a horizontal scan comes to avoid holes it cannot see (pure; ``sensor_pose`` is the
    horizontal laser's world pose at the scan)."""
    r = np.array(scan.ranges_m, dtype=float)
    n = len(r)
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    if n == 0 or len(pts) == 0:
        return scan
    c, s = math.cos(sensor_pose.yaw_rad), math.sin(sensor_pose.yaw_rad)
    dx, dy = pts[:, 0] - sensor_pose.x_m, pts[:, 1] - sensor_pose.y_m
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    dist = np.hypot(lx, ly)
    ok = (dist > radius_m) & (dist - radius_m < scan.range_max_m)
    lx, ly, dist = lx[ok], ly[ok], dist[ok]
    if len(dist) == 0:
        return scan
    bearing = np.arctan2(ly, lx)
    half = np.arcsin(np.clip(radius_m / dist, 0.0, 1.0))
    inc = scan.angle_increment_rad
    if inc == 0.0:
        return scan
    # each post's bearing from the first beam in the laser's sense of turn, and once more a turn lower and
    # a turn higher, so that a post across the scan's seam (a full-circle laser, or any start angle) gets
    # its beams on both sides
    rel0 = scan.from_first_beam_rad(bearing)
    rel = np.concatenate((rel0 - 2.0 * math.pi, rel0, rel0 + 2.0 * math.pi))
    half2 = np.tile(half, 3)
    post = np.tile(np.arange(len(bearing)), 3)
    step = abs(inc)
    lo = np.ceil((rel - half2) / step).astype(int)
    hi = np.floor((rel + half2) / step).astype(int)
    lo, hi = np.clip(lo, 0, n), np.clip(hi, -1, n - 1)
    width = np.maximum(hi - lo + 1, 0)
    if width.sum() == 0:
        return scan
    rows = np.repeat(np.arange(len(lo)), width)
    owner = post[rows]
    beam = lo[rows] + (np.arange(width.sum()) - np.repeat(np.cumsum(width) - width, width))
    # range to the post's near side along each beam: d cos(b) - sqrt(R^2 - d^2 sin^2(b)), b = beam - bearing
    db = scan.angle_min_rad + inc * beam - bearing[owner]
    along = dist[owner] * np.cos(db)
    across2 = (dist[owner] * np.sin(db)) ** 2
    hit = along - np.sqrt(np.maximum(radius_m * radius_m - across2, 0.0))
    virt = np.full(n, np.inf)
    np.minimum.at(virt, beam, hit)
    own = np.where(np.isfinite(r) & (r > 0), r, np.inf)
    merged = np.where(virt < own, virt, r)
    return replace(scan, ranges_m=merged)


class _Controller(Protocol):
    def reset(self) -> None: ...

    def step(self, obs: Observation) -> DriveCommand: ...


@dataclass(frozen=True)
class GroundGuardParams:
    """The tilted laser's pose, its thresholds (holes only where the return lies ``min_hole_depth_m`` below
    the ground: the robot drives through shallower dips), and the remembered obstacles' cells and posts."""

    tilted: TiltedMount = field(default_factory=TiltedMount)
    ground: GroundParams = field(default_factory=lambda: GroundParams(min_hole_depth_m=0.1))
    cell_m: float = 0.15
    post_radius_m: float = 0.2  # covers a cell (half its diagonal, 0.11 m) with 0.09 m to spare
    memory_m: float = 15.0


class GroundGuard:
    """Wraps a planner that reads only the horizontal scan so that it avoids holes and steps: the tilted scan
    (``obs.extras['tilted_scan']``) feeds a :class:`GroundObstacleMap`, and the planner gets ``obs.scan`` with
    the remembered obstacles added as posts (:func:`scan_with_virtual_obstacles`). ``detections`` counts the
    tilted scans that reported a hole or a step."""

    uses_tilted_laser = True

    def __init__(self, inner: _Controller, params: GroundGuardParams | None = None) -> None:
        self.inner = inner
        self.params = params or GroundGuardParams()
        p = self.params
        self.map = GroundObstacleMap(p.tilted, p.ground, p.cell_m, p.memory_m)
        self.detections = 0

    @property
    def uses_sonar(self) -> bool:
        return bool(getattr(self.inner, "uses_sonar", False))

    def reset(self) -> None:
        self.inner.reset()
        self.map.reset()
        self.detections = 0

    def step(self, obs: Observation) -> DriveCommand:
        ts = obs.extras.get("tilted_scan")
        if isinstance(ts, LaserScan):
            if self.map.update(ts, obs.pose).any:
                self.detections += 1
        scan = obs.scan
        pts = self.map.points_xy
        if scan is not None and len(pts):
            sensor = scan.pose if scan.pose is not None else obs.pose
            obs = replace(obs, scan=scan_with_virtual_obstacles(scan, sensor, pts, self.params.post_radius_m))
        return self.inner.step(obs)
