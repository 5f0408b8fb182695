"""The simulated world: static geometry, moving obstacles and a ground height map.

Everything that blocks a horizontal beam is a segment (walls, box and polygon edges) or a circle
(posts, balls, plant stems, people). Ground features (holes, steps, ruts) only change the ground
height and are seen by a tilted laser, not by a horizontal one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..types import Circles, FloatArray, Segments
from ._raycast import cast_rays, distance_to_objects

__all__ = [
    "Mover",
    "Hole",
    "Step",
    "Rut",
    "World",
    "box_segments",
    "polyline_segments",
    "polyline_length_m",
    "resample_polyline",
    "sine_curve",
    "plants_along",
]


def polyline_segments(points: FloatArray, closed: bool = False) -> Segments:
    """Segments (k, 4) joining consecutive points (n, 2); ``closed`` adds the last-to-first edge."""
    p = np.asarray(points, dtype=float)
    if closed:
        p = np.vstack((p, p[:1]))
    return np.column_stack((p[:-1], p[1:]))


def box_segments(cx_m: float, cy_m: float, size_x_m: float, size_y_m: float, yaw_rad: float = 0.0) -> Segments:
    """The four edges (4, 4) of a rectangle centred at (cx, cy), sides size_x by size_y, rotated by yaw."""
    hx, hy = size_x_m / 2.0, size_y_m / 2.0
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    pts = local @ np.array([[c, s], [-s, c]]) + (cx_m, cy_m)
    return polyline_segments(pts, closed=True)


def polyline_length_m(points: FloatArray) -> float:
    """Total length of a polyline (n, 2), m."""
    d = np.diff(np.asarray(points, dtype=float), axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def resample_polyline(points: FloatArray, s_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Positions (k, 2) and unit tangents (k, 2) at arc lengths ``s_m`` (k,) along a polyline."""
    p = np.asarray(points, dtype=float)
    seg = np.diff(p, axis=0)
    ln = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate(([0.0], np.cumsum(ln)))
    s = np.clip(np.asarray(s_m, dtype=float), 0.0, cum[-1])
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    f = (s - cum[i]) / np.where(ln[i] > 0, ln[i], 1.0)
    pos = p[i] + f[:, None] * seg[i]
    tan = seg[i] / np.where(ln[i] > 0, ln[i], 1.0)[:, None]
    return pos, tan


def sine_curve(
    x0_m: float, y0_m: float, yaw_rad: float, length_m: float, amplitude_m: float, wavelength_m: float, step_m: float = 0.25
) -> FloatArray:
    """Polyline (n, 2) of a sine-shaped row: ``y' = A sin(2 pi x' / wavelength)`` in a frame at (x0, y0, yaw).

    ``length_m`` is measured along the baseline x'. A zero amplitude gives a straight line.
    """
    n = max(2, int(math.ceil(length_m / step_m)) + 1)
    xl = np.linspace(0.0, length_m, n)
    yl = amplitude_m * np.sin(2.0 * math.pi * xl / wavelength_m) if amplitude_m else np.zeros(n)
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.column_stack((x0_m + c * xl - s * yl, y0_m + s * xl + c * yl))


def plants_along(
    points: FloatArray,
    spacing_m: float,
    plant_radius_m: float,
    rng: np.random.Generator,
    cluster: int = 3,
    jitter_m: float = 0.02,
    gaps_m: list[tuple[float, float]] | None = None,
) -> Circles:
    """Plants along a row line as noisy clusters of small circles (k, 3).

    A plant every ``spacing_m`` of arc length, its centre displaced by N(0, jitter) in x and y; each
    plant is ``cluster`` circles of radius ``plant_radius_m / 2`` scattered within the plant radius
    (a stem plus leaves as a laser sees them). ``gaps_m`` lists [start, end] arc-length intervals with
    no plants (missing plants).
    """
    total = polyline_length_m(points)
    s = np.arange(0.0, total + 1e-9, spacing_m)
    for g0, g1 in gaps_m or []:
        s = s[(s < g0) | (s > g1)]
    pos, _ = resample_polyline(points, s)
    pos = pos + rng.normal(0.0, jitter_m, pos.shape)
    if cluster <= 1:
        return np.column_stack((pos, np.full(len(pos), plant_radius_m)))
    k = len(pos)
    ang = rng.uniform(0.0, 2.0 * math.pi, (k, cluster))
    rad = rng.uniform(0.0, plant_radius_m / 2.0, (k, cluster))
    cx = pos[:, :1] + rad * np.cos(ang)
    cy = pos[:, 1:] + rad * np.sin(ang)
    return np.column_stack((cx.ravel(), cy.ravel(), np.full(k * cluster, plant_radius_m / 2.0)))


@dataclass(frozen=True)
class Mover:
    """A moving circular obstacle (a walking person) following waypoints at constant speed.

    With ``loop`` the path closes back to the first waypoint and repeats; otherwise the mover stops at
    the last waypoint. ``start_s`` delays the start (the mover waits at its first waypoint).
    """

    radius_m: float
    speed_m_s: float
    waypoints: tuple[tuple[float, float], ...]
    loop: bool = True
    start_s: float = 0.0

    def position(self, t_s: float) -> tuple[float, float]:
        """Centre (x, y) in m at time t_s."""
        pts = np.asarray(self.waypoints, dtype=float)
        if len(pts) == 1:
            return float(pts[0, 0]), float(pts[0, 1])
        if self.loop:
            pts = np.vstack((pts, pts[:1]))
        total = polyline_length_m(pts)
        s = max(0.0, t_s - self.start_s) * self.speed_m_s
        s = s % total if self.loop and total > 0 else min(s, total)
        pos, _ = resample_polyline(pts, np.array([s]))
        return float(pos[0, 0]), float(pos[0, 1])


def _local(x: FloatArray, y: FloatArray, cx: float, cy: float, yaw: float) -> tuple[FloatArray, FloatArray]:
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = x - cx, y - cy
    return c * dx + s * dy, -s * dx + c * dy


@dataclass(frozen=True)
class Hole:
    """A rectangular (or elliptical) hole: ground at -depth inside, m; yaw rotates the footprint."""

    x_m: float
    y_m: float
    size_x_m: float
    size_y_m: float
    depth_m: float
    yaw_rad: float = 0.0
    elliptic: bool = False

    def height_m(self, x: FloatArray, y: FloatArray) -> FloatArray:
        lx, ly = _local(x, y, self.x_m, self.y_m, self.yaw_rad)
        ax, ay = self.size_x_m / 2.0, self.size_y_m / 2.0
        if self.elliptic:
            inside = (lx / ax) ** 2 + (ly / ay) ** 2 <= 1.0
        else:
            inside = (np.abs(lx) <= ax) & (np.abs(ly) <= ay)
        return np.where(inside, -self.depth_m, 0.0)


@dataclass(frozen=True)
class Step:
    """A straight ground step: beyond the edge through (x, y) facing yaw, the ground is at height_m.

    ``width_m`` limits the edge's extent (centred on (x, y)); ``depth_m`` limits how far the raised or
    lowered ground extends beyond the edge.
    """

    x_m: float
    y_m: float
    yaw_rad: float
    height_m: float
    width_m: float = math.inf
    depth_m: float = math.inf

    def height(self, x: FloatArray, y: FloatArray) -> FloatArray:
        lx, ly = _local(x, y, self.x_m, self.y_m, self.yaw_rad)
        inside = (lx >= 0.0) & (lx <= self.depth_m) & (np.abs(ly) <= self.width_m / 2.0)
        return np.where(inside, self.height_m, 0.0)


@dataclass(frozen=True)
class Rut:
    """Wheel ruts along a polyline: ``count`` grooves (1 or 2) ``spacing_m`` apart, each ``width_m``
    wide with a cosine cross-section ``depth_m`` deep at its centre line."""

    points: tuple[tuple[float, float], ...]
    width_m: float
    depth_m: float
    spacing_m: float = 0.0
    count: int = 1

    def height(self, x: FloatArray, y: FloatArray) -> FloatArray:
        pts = np.asarray(self.points, dtype=float)
        seg = polyline_segments(pts)
        # signed lateral offset from the centre line (positive = left of travel direction)
        x0, y0 = seg[None, :, 0], seg[None, :, 1]
        ex, ey = seg[None, :, 2] - x0, seg[None, :, 3] - y0
        l2 = np.maximum(ex * ex + ey * ey, 1e-12)
        qx, qy = x.reshape(-1)[:, None] - x0, y.reshape(-1)[:, None] - y0
        u = np.clip((qx * ex + qy * ey) / l2, 0.0, 1.0)
        d = np.hypot(qx - u * ex, qy - u * ey)
        j = np.argmin(d, axis=1)
        rows = np.arange(len(j))
        side = np.sign(ex[0, j] * qy[rows, j] - ey[0, j] * qx[rows, j])
        lateral = side * d[rows, j]
        offsets = [0.0] if self.count == 1 else [-self.spacing_m / 2.0, self.spacing_m / 2.0]
        h = np.zeros_like(lateral)
        for off in offsets:
            w = np.abs(lateral - off) / (self.width_m / 2.0)
            h = np.minimum(h, np.where(w < 1.0, -self.depth_m * 0.5 * (1.0 + np.cos(math.pi * w)), 0.0))
        depth: FloatArray = h.reshape(np.shape(x))
        return depth


@dataclass
class World:
    """Static geometry, moving obstacles and ground features.

    ``segments`` (ns, 4) and ``circles`` (nc, 3) are static, in m. ``bounds`` is (xmin, ymin, xmax, ymax)
    for plots and sampling.
    """

    segments: Segments = field(default_factory=lambda: np.zeros((0, 4)))
    circles: Circles = field(default_factory=lambda: np.zeros((0, 3)))
    movers: list[Mover] = field(default_factory=list)
    holes: list[Hole] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    ruts: list[Rut] = field(default_factory=list)
    bounds: tuple[float, float, float, float] = (-10.0, -10.0, 10.0, 10.0)
    # each plant row's design line (k, 2), m: the polyline its plants were laid along before their jitter
    row_lines: list[FloatArray] = field(default_factory=list)
    # each plant row's stems (k, 2), m, in planting order: the centre of each plant (the mean of its circles, where
    # a surveyor would mark it), one array per entry of row_lines
    row_plants: list[FloatArray] = field(default_factory=list)
    # circle kinds the robot may brush through (a field's ``plant`` and ``weed``): seen by the lasers, left out of
    # clearance_m, so that touching one is counted by the field's referee rather than ending the run
    soft_kinds: tuple[str, ...] = ()
    _solid_cache: tuple[tuple[int, tuple[str, ...], int], Circles] | None = field(default=None, repr=False, compare=False)
    # what each block of segments and circles is (``wall``, ``box``, ``polygon``; ``post``, ``plant``, ``weed``),
    # for drawings: (kind, first index, end index), one entry per add_segments / add_circles call
    segment_kinds: list[tuple[str, int, int]] = field(default_factory=list)
    circle_kinds: list[tuple[str, int, int]] = field(default_factory=list)

    def add_segments(self, seg: Segments, kind: str = "wall") -> None:
        n0 = len(self.segments)
        self.segments = np.vstack((self.segments, np.asarray(seg, dtype=float).reshape(-1, 4)))
        self.segment_kinds.append((kind, n0, len(self.segments)))

    def add_circles(self, circ: Circles, kind: str = "post") -> None:
        n0 = len(self.circles)
        self.circles = np.vstack((self.circles, np.asarray(circ, dtype=float).reshape(-1, 3)))
        self.circle_kinds.append((kind, n0, len(self.circles)))

    def circles_at(self, t_s: float) -> Circles:
        """Static circles plus the movers' positions at t_s, (nc + nm, 3)."""
        if not self.movers:
            return self.circles
        mv = np.array([(*m.position(t_s), m.radius_m) for m in self.movers])
        return np.vstack((self.circles, mv))

    def raycast(
        self,
        x_m: float,
        y_m: float,
        heading_rad: float,
        angle_min_rad: float,
        angle_inc_rad: float,
        n_beams: int,
        max_range_m: float,
        t_s: float = 0.0,
    ) -> FloatArray:
        """Exact ranges (n_beams,) in m from (x, y), inf where nothing is within range. See cast_rays."""
        return cast_rays(
            x_m, y_m, heading_rad, angle_min_rad, angle_inc_rad, n_beams, max_range_m, self.segments, self.circles_at(t_s)
        )

    def clearance_m(self, x_m: FloatArray | float, y_m: FloatArray | float, t_s: float = 0.0) -> FloatArray:
        """Distance from point(s) to the nearest obstacle boundary, m (negative inside a circle); circles of the
        ``soft_kinds`` do not count."""
        circ = self.circles_at(t_s)
        if self.soft_kinds:
            solid = self._solid_static()
            circ = np.vstack((solid, circ[len(self.circles):])) if len(circ) > len(self.circles) else solid
        return distance_to_objects(np.asarray(x_m), np.asarray(y_m), self.segments, circ)

    def _solid_static(self) -> Circles:
        """The static circles that are not of a soft kind (cached until circles or kinds change)."""
        key = (len(self.circles), self.soft_kinds, len(self.circle_kinds))
        cached = self._solid_cache
        if cached is None or cached[0] != key:
            keep = np.ones(len(self.circles), dtype=bool)
            for kind, a, b in self.circle_kinds:
                if kind in self.soft_kinds:
                    keep[a:b] = False
            cached = (key, self.circles[keep])
            self._solid_cache = cached
        return cached[1]

    def ground_height_m(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Ground height z (m) at points; 0 is the nominal ground plane. Features add up."""
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        h = np.zeros(np.broadcast(x, y).shape)
        for hole in self.holes:
            h = h + hole.height_m(x, y)
        for st in self.steps:
            h = h + st.height(x, y)
        for rut in self.ruts:
            h = h + rut.height(x, y)
        return h

    @property
    def has_ground_features(self) -> bool:
        return bool(self.holes or self.steps or self.ruts)
