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

import numpy as np

from ..types import Circles, FloatArray, Segments

TWO_PI = 2.0 * math.pi


def _wrap(a: FloatArray) -> FloatArray:
    return (a + math.pi) % TWO_PI - math.pi


def _beam_pairs(start_rel: FloatArray, width: FloatArray, rel: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Beam indices covered by angular intervals.

    ``start_rel`` (k,) interval starts relative to the scan's centre direction, in [-pi, pi);
    ``width`` (k,) interval widths in rad (0..2pi); ``rel`` (n,) ascending beam angles relative to the
    same centre, inside [-pi, pi]. Returns (object index, beam index) arrays of all covered pairs.
    """
    n = len(rel)
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
    angles = angle_min_rad + angle_inc_rad * np.arange(n_beams)
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
            a1 = _wrap(np.arctan2(sy0, sx0) - centre_abs)
            a2 = _wrap(np.arctan2(sy0 + ey, sx0 + ex) - centre_abs)
            w = _wrap(a2 - a1)
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
            start = _wrap(np.arctan2(cy, cx) - centre_abs - half)
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
