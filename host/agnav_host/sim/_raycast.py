"""Vectorised planar ray casting against segments and circles.

Rays share one origin (a sensor) and have uniformly spaced angles. Instead of testing every
(beam, object) pair, each object's angular extent as seen from the origin is turned into a
contiguous range of beam indices, and only those pairs are intersected analytically:

* ray/segment: solve ``o + t d = p + s e`` with 2-D cross products, hit when t >= 0, 0 <= s <= 1;
* ray/circle: smallest t >= 0 of ``|o + t d - c| = r`` (the far root when the origin is inside).

Objects farther than the maximum range are dropped first. The nearest hit per beam is reduced with
``np.minimum.at``.
"""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np
import numpy.typing as npt

from ..types import Circles, FloatArray, Segments, norm_angle_rad

TWO_PI = 2.0 * math.pi
IndexArray: TypeAlias = npt.NDArray[np.int64]


def _beam_pairs(start_rel: FloatArray, width: FloatArray, rel: FloatArray) -> tuple[IndexArray, IndexArray]:
    """Beam indices covered by angular intervals.

    ``start_rel`` (k,) interval starts relative to the scan's centre direction, in [-pi, pi);
    ``width`` (k,) interval widths in rad (0..2pi); ``rel`` (n,) ascending beam angles relative to the
    same centre, inside [-pi, pi]. Returns (object index, beam index) arrays of all covered pairs.
    """
    end_rel = start_rel + width
    full = width >= TWO_PI - 1e-12
    # piece 1: [start, min(end, pi)]; piece 2 (wrap): [-pi, end - 2pi] when end > pi
    s1 = np.where(full, -math.pi, start_rel)
    e1 = np.where(full, math.pi, np.minimum(end_rel, math.pi))
    wraps = (~full) & (end_rel > math.pi)
    e2 = end_rel[wraps] - TWO_PI
    eps = 1e-9
    lo = np.concatenate((np.searchsorted(rel, s1 - eps, "left"), np.zeros(len(e2), dtype=np.int64)))
    hi = np.concatenate((np.searchsorted(rel, e1 + eps, "right"), np.searchsorted(rel, e2 + eps, "right"))) - 1
    obj = np.concatenate((np.arange(len(start_rel)), np.nonzero(wraps)[0]))
    counts = hi - lo + 1
    counts[counts < 0] = 0
    total = int(counts.sum())
    if total == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    obj_rep = np.repeat(obj, counts)
    offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    beam = np.repeat(lo, counts) + offsets
    return obj_rep, beam


def cast_rays(
    origin_x: float,
    origin_y: float,
    heading_rad: float,
    angle_min_rad: float,
    angle_inc_rad: float,
    n_beams: int,
    max_range_m: float,
    segments: Segments,
    circles: Circles,
) -> FloatArray:
    """Distance to the first object along each of n uniformly spaced beams.

    Beam i leaves (origin_x, origin_y) at world angle ``heading_rad + angle_min_rad + i*angle_inc_rad``.
    ``segments`` (ns, 4) as x0, y0, x1, y1 and ``circles`` (nc, 3) as cx, cy, r, all in m.
    Returns (n_beams,) ranges in m; ``inf`` where nothing is hit within ``max_range_m``.
    Requires ``(n_beams - 1) * angle_inc_rad < 2*pi``.
    """
    angles = angle_min_rad + angle_inc_rad * np.arange(n_beams, dtype=np.float64)
    return cast_rays_at(origin_x, origin_y, heading_rad, angles, max_range_m, segments, circles)


def cast_rays_at(
    origin_x: float,
    origin_y: float,
    heading_rad: float,
    angles_rad: FloatArray,
    max_range_m: float,
    segments: Segments,
    circles: Circles,
) -> FloatArray:
    """Like :func:`cast_rays` for arbitrary ascending beam angles (n,), rad, spanning less than 2 pi."""
    angles_rad = np.asarray(angles_rad, dtype=float)
    n_beams = len(angles_rad)
    out = np.full(n_beams, np.inf)
    if n_beams == 0:
        return out
    centre_rel = 0.5 * (angles_rad[0] + angles_rad[-1])
    centre_abs = heading_rad + centre_rel
    rel = angles_rad - centre_rel
    beam_abs = heading_rad + angles_rad
    dcos = np.cos(beam_abs)
    dsin = np.sin(beam_abs)

    if len(segments):
        sx0 = segments[:, 0] - origin_x
        sy0 = segments[:, 1] - origin_y
        sx1 = segments[:, 2] - origin_x
        sy1 = segments[:, 3] - origin_y
        # coarse prefilter: distance from origin to the segment must be within range
        ex = sx1 - sx0
        ey = sy1 - sy0
        l2 = ex * ex + ey * ey
        u = np.clip(-(sx0 * ex + sy0 * ey) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
        dmin2 = (sx0 + u * ex) ** 2 + (sy0 + u * ey) ** 2
        keep = np.nonzero(dmin2 <= max_range_m * max_range_m)[0]
        if len(keep):
            sx0, sy0, ex, ey = sx0[keep], sy0[keep], ex[keep], ey[keep]
            a1 = norm_angle_rad(np.arctan2(sy0, sx0) - centre_abs)
            a2 = norm_angle_rad(np.arctan2(sy0 + ey, sx0 + ex) - centre_abs)
            w = norm_angle_rad(a2 - a1)
            start = np.where(w >= 0, a1, a2)
            width = np.abs(w)
            # origin on the segment's line between its ends: the segment covers half a turn
            obj, beam = _beam_pairs(start, width, rel)
            if len(obj):
                dx = dcos[beam]
                dy = dsin[beam]
                px, py, qx, qy = sx0[obj], sy0[obj], ex[obj], ey[obj]
                denom = dx * qy - dy * qx
                ok = np.abs(denom) > 1e-12
                inv = 1.0 / np.where(ok, denom, 1.0)
                t = (px * qy - py * qx) * inv
                s = (px * dy - py * dx) * inv
                hit = ok & (t >= 0.0) & (s >= -1e-9) & (s <= 1.0 + 1e-9)
                np.minimum.at(out, beam[hit], t[hit])

    if len(circles):
        cx = circles[:, 0] - origin_x
        cy = circles[:, 1] - origin_y
        r = circles[:, 2]
        d = np.hypot(cx, cy)
        keep = np.nonzero(d - r <= max_range_m)[0]
        if len(keep):
            cx, cy, r, d = cx[keep], cy[keep], r[keep], d[keep]
            inside = d <= r
            half = np.arcsin(np.clip(r / np.where(inside, 1.0, d), 0.0, 1.0))
            half = np.where(inside, math.pi, half)
            start = norm_angle_rad(np.arctan2(cy, cx) - centre_abs - half)
            obj, beam = _beam_pairs(start, 2.0 * half, rel)
            if len(obj):
                dx = dcos[beam]
                dy = dsin[beam]
                fx, fy, rr = -cx[obj], -cy[obj], r[obj]
                b = fx * dx + fy * dy
                c = fx * fx + fy * fy - rr * rr
                disc = b * b - c
                hit = disc >= 0.0
                sq = np.sqrt(np.where(hit, disc, 0.0))
                t = np.where(c > 0.0, -b - sq, -b + sq)  # c <= 0: origin inside, take far root
                hit &= t >= 0.0
                np.minimum.at(out, beam[hit], t[hit])

    out[out > max_range_m] = np.inf
    return out


def distance_to_objects(px: FloatArray, py: FloatArray, segments: Segments, circles: Circles) -> FloatArray:
    """Distance from each point (k,) to the nearest segment or circle boundary, m.

    Points inside a circle get a negative distance (penetration depth). Returns inf with no objects.
    """
    px = np.atleast_1d(np.asarray(px, dtype=float))
    py = np.atleast_1d(np.asarray(py, dtype=float))
    best = np.full(px.shape, np.inf)
    if len(segments):
        x0 = segments[None, :, 0]
        y0 = segments[None, :, 1]
        ex = segments[None, :, 2] - x0
        ey = segments[None, :, 3] - y0
        l2 = np.where(ex * ex + ey * ey > 0, ex * ex + ey * ey, 1.0)
        qx = px[:, None] - x0
        qy = py[:, None] - y0
        u = np.clip((qx * ex + qy * ey) / l2, 0.0, 1.0)
        dseg = np.hypot(qx - u * ex, qy - u * ey)
        best = np.minimum(best, dseg.min(axis=1))
    if len(circles):
        dc = np.hypot(px[:, None] - circles[None, :, 0], py[:, None] - circles[None, :, 1]) - circles[None, :, 2]
        best = np.minimum(best, dc.min(axis=1))
    return best


class RayBundle:
    """Brute-force caster for small bundles of rays with their own origins (a sonar trigger group:
    ~28 rays) against one world's objects: every (ray, object) pair is intersected with numpy
    broadcasting, which for a few dozen rays beats the angular-interval method of
    :func:`cast_rays_at` (whose bookkeeping is made for hundreds of beams from one origin).

    The static objects' arrays are prepared once. With many static objects (``> near_after``),
    each call only tests the objects near the bundle: per ``cell_m`` grid cell of the given centre,
    the objects that could be hit within ``max_range_m + reach_m`` of it (cached per cell); a hit
    beyond the maximum range is "no hit" anyway, so the result is the same.

    Ray/segment: ``t = (q x e) / (d x e)``, ``u = (q x d) / (d x e)`` with ``q = p0 - o``, hit
    when t >= 0 and 0 <= u <= 1; ray/circle: the nearest root t >= 0 of ``|o + t d - c| = r``.
    """

    def __init__(self, segments: Segments, circles: Circles, max_range_m: float, reach_m: float = 0.0,
                 cell_m: float = 0.5, near_after: int = 48) -> None:
        seg = np.asarray(segments, dtype=float).reshape(-1, 4)
        circ = np.asarray(circles, dtype=float).reshape(-1, 3)
        self.segments, self.circles = segments, circles  # the arrays this bundle was built from
        self.max_range_m = float(max_range_m)
        self._seg = seg
        self._circ = circ
        self._px, self._py = seg[:, 0][None, :], seg[:, 1][None, :]
        self._ex, self._ey = (seg[:, 2] - seg[:, 0])[None, :], (seg[:, 3] - seg[:, 1])[None, :]
        self._near = len(seg) + len(circ) > near_after
        self._cell = float(cell_m)
        self._reach = self.max_range_m + float(reach_m) + math.sqrt(0.5) * self._cell + 1e-3
        self._cells: dict[tuple[int, int], tuple[tuple[FloatArray, ...], FloatArray]] = {}

    def _objects_near(self, x: float, y: float) -> tuple[tuple[FloatArray, ...], FloatArray]:
        key = (math.floor(x / self._cell), math.floor(y / self._cell))
        hit = self._cells.get(key)
        if hit is None:
            cx, cy = (key[0] + 0.5) * self._cell, (key[1] + 0.5) * self._cell
            seg, circ = self._seg, self._circ
            ks = np.nonzero(_seg_dist(seg, cx, cy) <= self._reach)[0]
            kc = np.nonzero(np.hypot(circ[:, 0] - cx, circ[:, 1] - cy) - circ[:, 2] <= self._reach)[0]
            s = seg[ks]
            hit = ((s[:, 0][None, :], s[:, 1][None, :], (s[:, 2] - s[:, 0])[None, :], (s[:, 3] - s[:, 1])[None, :]),
                   circ[kc])
            self._cells[key] = hit
        return hit

    def cast(self, ox: FloatArray, oy: FloatArray, dx: FloatArray, dy: FloatArray, extra_circles: Circles | None = None,
             centre: tuple[float, float] | None = None) -> FloatArray:
        """Nearest hit of rays from (ox, oy) along unit (dx, dy) (arrays broadcast to the rays'
        shape, e.g. origins (n, 1) and directions (n, k)); inf beyond the maximum range.
        ``extra_circles`` (m, 3): moving circles, always tested. ``centre``: a point within
        ``reach_m`` of every origin (needed for the nearby-object filter)."""
        if self._near and centre is not None:
            (px, py, ex, ey), circ = self._objects_near(*centre)
        else:
            px, py, ex, ey, circ = self._px, self._py, self._ex, self._ey, self._circ
        if extra_circles is not None and len(extra_circles):
            circ = np.vstack((circ, extra_circles)) if len(circ) else np.asarray(extra_circles, dtype=float)
        best: FloatArray | None = None
        oxc, oyc = ox[..., None], oy[..., None]
        dxc, dyc = dx[..., None], dy[..., None]
        if px.shape[1]:
            qx, qy = px - oxc, py - oyc
            den = dxc * ey - dyc * ex
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (qx * ey - qy * ex) / den
                u = (qx * dyc - qy * dxc) / den
            # den == 0 needs no test of its own: u is then +-inf or NaN and fails 0 <= u <= 1
            best = np.where((t >= 0.0) & (u >= 0.0) & (u <= 1.0), t, np.inf).min(axis=-1)
        if len(circ):
            wx, wy = oxc - circ[:, 0], oyc - circ[:, 1]
            r = circ[:, 2]
            bb = dxc * wx + dyc * wy
            cc = wx * wx + wy * wy - r * r
            disc = bb * bb - cc
            sq = np.sqrt(np.maximum(disc, 0.0))
            t1, t2 = -bb - sq, -bb + sq
            t = np.where(t1 >= 0.0, t1, np.where(t2 >= 0.0, t2, np.inf))
            bc = np.where(disc >= 0.0, t, np.inf).min(axis=-1)
            best = bc if best is None else np.minimum(best, bc)
        if best is None:
            return np.full(np.broadcast(ox, oy, dx, dy).shape, np.inf)
        best[best > self.max_range_m] = np.inf
        return best


def _seg_dist(seg: Segments, x: float, y: float) -> FloatArray:
    """Distance (ns,) from the point (x, y) to each segment."""
    x0, y0 = seg[:, 0], seg[:, 1]
    ex, ey = seg[:, 2] - x0, seg[:, 3] - y0
    l2 = ex * ex + ey * ey
    u = np.clip(((x - x0) * ex + (y - y0) * ey) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
    return np.hypot(x - x0 - u * ex, y - y0 - u * ey)
