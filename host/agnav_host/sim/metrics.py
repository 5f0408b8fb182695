"""Run metrics written to summary.json.

Path length and bending energy follow ref 000 (its eqs. 4-11), which compares planners by the total
path length and the bending energy of the driven path. Ref 000 gets the curvature of each triple of
consecutive path points from the circle through them and sums the squared curvatures (its eq. 11,
reconstructed: ``BE = sum_i kappa_i^2``). A plain sum depends on how densely the path was sampled, so
AgNav uses the integral form ``BE = integral kappa(s)^2 ds``: the path is first resampled at equal arc
length ``ds``, each interior point gets the circumcircle (Menger) curvature
``kappa = 4 * area(P1, P2, P3) / (|P1P2| |P2P3| |P1P3|)``, and ``BE = sum kappa_i^2 * ds``. A circle
of radius R then gives length / R^2 and a straight line 0, whatever the sample rate.

A reversal (a cusp: the robot backs off along, or nearly along, the way it came) has no finite
curvature: the circle through the tip and its two neighbours has a radius of about ``ds / 2`` when the
legs are a fraction of a degree apart, and of infinity when they are exactly collinear. Such vertices
(consecutive resampled chords turning by more than :data:`CUSP_TURN_DEG`) are left out of the bending
energy and counted apart, in ``reversals`` (:func:`count_reversals`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..types import FloatArray, norm_angle_rad

if TYPE_CHECKING:
    from .world import Hole

__all__ = [
    "signed_offset_m",
    "RowDistance",
    "row_distance",
    "PLANTED_WINDOW_M",
    "along_and_offset_m",
    "disc_clearance_to_hole_m",
    "SUMMARY_KEYS",
    "FIELD_SUMMARY_KEYS",
    "path_length_m",
    "bending_energy",
    "count_reversals",
    "CUSP_TURN_DEG",
    "resample_path",
    "count_stops",
    "count_heading_oscillations",
    "RunMetrics",
]

SUMMARY_KEYS = (
    "success",
    "time_s",
    "path_length_m",
    "bending_energy",
    "min_clearance_m",
    "stops",
    "heading_oscillations",
    "reversals",
    "final_position_error_m",
    "final_heading_error_deg",
    "arrival_time_error_s",
    "rows_completed",
    "pattern_completed",
    "plants_touched",
    "field_distance_m",
    "field_time_s",
    "field_score_m",
)
#: The whole-field keys of SUMMARY_KEYS (a scenario with a ``[field]``; None elsewhere): the lanes driven in the
#: pattern's order, whether the pattern was finished, the stems run over, and the Field Robot Event's distance in
#: rows, time and score (sim.field_gen)
FIELD_SUMMARY_KEYS = SUMMARY_KEYS[-6:]


CUSP_TURN_DEG = 150.0  # consecutive chords turning by more than this: a reversal (cusp), deg


def path_length_m(xy: FloatArray) -> float:
    """Sum of distances between consecutive points (n, 2), m (ref 000 eq. 4)."""
    xy = np.asarray(xy, dtype=float)
    if len(xy) < 2:
        return 0.0
    d = np.diff(xy, axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def resample_path(xy: FloatArray, ds_m: float) -> FloatArray:
    """Points (k, 2) every ``ds_m`` of arc length along a path (n, 2); stationary samples drop out."""
    xy = np.asarray(xy, dtype=float)
    d = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
    keep = np.concatenate(([True], d > 1e-12)) if len(xy) else np.zeros(0, dtype=bool)
    xy = xy[keep]
    if len(xy) < 2:
        return xy
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    s = np.arange(0.0, cum[-1] + 1e-12, ds_m)
    return np.column_stack((np.interp(s, cum, xy[:, 0]), np.interp(s, cum, xy[:, 1])))


def menger_curvature(xy: FloatArray) -> FloatArray:
    """Curvature (n-2,) in 1/m of the circle through each triple of consecutive points (n, 2)."""
    p1, p2, p3 = xy[:-2], xy[1:-1], xy[2:]
    a = np.hypot(*(p2 - p1).T)
    b = np.hypot(*(p3 - p2).T)
    c = np.hypot(*(p3 - p1).T)
    cross = (p2[:, 0] - p1[:, 0]) * (p3[:, 1] - p1[:, 1]) - (p2[:, 1] - p1[:, 1]) * (p3[:, 0] - p1[:, 0])
    den = a * b * c
    return np.where(den > 1e-15, 2.0 * np.abs(cross) / np.where(den > 1e-15, den, 1.0), 0.0)


def _bending_samples(xy: FloatArray, ds_m: float) -> tuple[FloatArray, float]:
    """The path resampled for the bending energy and the step used: ``ds_m``, raised to the median
    input spacing when that is coarser (never resample finer than the input: chords would concentrate
    the curvature)."""
    xy = np.asarray(xy, dtype=float)
    if len(xy) > 1:
        seg = np.hypot(*np.diff(xy, axis=0).T)
        seg = seg[seg > 1e-12]
        if len(seg):
            ds_m = max(ds_m, float(np.median(seg)))
    return resample_path(xy, ds_m), ds_m


def _cusps(p: FloatArray) -> tuple[np.ndarray, int]:
    """Reversals of a resampled path p (n, 2): a mask (n-2,) of the interior vertices that belong to a
    cusp, and the number of cusps.

    A vertex whose two chords turn by more than CUSP_TURN_DEG is a cusp. When the tip falls between
    two samples the chord joining them cuts the tip and splits the turn over two vertices (each can be
    well under the threshold, e.g. 90 + 90 deg); so two neighbouring vertices whose outer chords turn by
    more than CUSP_TURN_DEG are one cusp too (whatever the sampling phase, a reversal is then found
    from the angle between its two legs alone)."""
    n = len(p)
    mask = np.zeros(max(n - 2, 0), dtype=bool)
    if n < 3:
        return mask, 0
    d = np.diff(p, axis=0)
    length = np.hypot(d[:, 0], d[:, 1])
    u = d / np.where(length > 1e-12, length, 1.0)[:, None]  # chord directions
    cos_cusp = math.cos(math.radians(CUSP_TURN_DEG))
    cusps = 0
    j = 0
    while j < n - 2:  # vertex j + 1, between chords j and j + 1
        if float(u[j] @ u[j + 1]) < cos_cusp:
            mask[j] = True
            cusps += 1
            j += 1
            continue
        if j + 2 < n - 1 and float(u[j] @ u[j + 2]) < cos_cusp:
            mask[j] = mask[j + 1] = True
            cusps += 1
            j += 2
            continue
        j += 1
    return mask, cusps


def bending_energy(xy: FloatArray, ds_m: float = 0.05) -> float:
    """Integral of squared curvature along a path (n, 2), 1/m. See the module docstring.

    ``ds_m`` is the resampling step; it is raised to the median input spacing when that is coarser.
    Reversals (cusps, see :func:`count_reversals`) contribute nothing: they are counted apart, in the
    ``reversals`` metric, so a back-off along the same line and one a fraction of a degree off it score
    the same. A path without reversals gets the plain integral.
    """
    p, ds_m = _bending_samples(xy, ds_m)
    if len(p) < 3:
        return 0.0
    k = menger_curvature(p)
    cusp, _ = _cusps(p)
    k = np.where(cusp, 0.0, k)
    return float(np.sum(k * k) * ds_m)


def count_reversals(xy: FloatArray, ds_m: float = 0.05) -> int:
    """Direction reversals (cusps) of a path (n, 2): on the path resampled as for :func:`bending_energy`,
    consecutive chords turning by more than CUSP_TURN_DEG (150 deg), e.g. a back-off, a three-point turn's
    two reversals."""
    p, _ = _bending_samples(xy, ds_m)
    return _cusps(p)[1]


def count_stops(speed_m_s: FloatArray, moving_m_s: float = 0.05, stopped_m_s: float = 0.01) -> int:
    """Times the robot came to rest after moving (hysteresis between the two thresholds).

    A final stop at the end of the record is not counted (arriving is not a stop)."""
    stops = 0
    moving = False
    pending = False
    for v in np.abs(np.asarray(speed_m_s, dtype=float)):
        if moving and v < stopped_m_s:
            moving, pending = False, True
        elif not moving and v > moving_m_s:
            if pending:
                stops += 1
                pending = False
            moving = True
    return stops


def count_heading_oscillations(yaw_rate_rad_s: FloatArray, threshold_rad_s: float = 0.1) -> int:
    """Sign reversals of the yaw rate among samples with |rate| above threshold (left-right sway)."""
    w = np.asarray(yaw_rate_rad_s, dtype=float)
    s = np.sign(w[np.abs(w) > threshold_rad_s])
    return int(np.count_nonzero(s[1:] != s[:-1])) if len(s) > 1 else 0


@dataclass(frozen=True)
class RunMetrics:
    """The summary.json metrics. ``None`` means the metric does not apply to the run."""

    success: bool
    time_s: float
    path_length_m: float
    bending_energy: float
    min_clearance_m: float | None
    stops: int
    heading_oscillations: int
    reversals: int  # direction reversals (cusps) of the driven path, left out of bending_energy
    final_position_error_m: float
    final_heading_error_deg: float | None
    arrival_time_error_s: float | None
    rows_completed: int | None = None
    pattern_completed: bool | None = None
    plants_touched: int | None = None
    field_distance_m: float | None = None
    field_time_s: float | None = None
    field_score_m: float | None = None
    # the whole FieldScore behind the field keys (lanes, times; field.json), None off a field; not in summary.json
    field_detail: Any = dc_field(default=None, repr=False, compare=False)

    @staticmethod
    def compute(
        t_s: FloatArray,
        xy: FloatArray,
        yaw_rad: FloatArray,
        speed_m_s: FloatArray,
        yaw_rate_rad_s: FloatArray,
        clearance_m: FloatArray,
        goal_xy: tuple[float, float],
        goal_yaw_rad: float | None,
        goal_arrival_s: float | None,
        success: bool,
        arrival_s: float | None,
        field: Any = None,
    ) -> "RunMetrics":
        """Metrics of a recorded run (arrays indexed by sample). ``arrival_s`` is when the final goal was
        reached (None if never); ``time_s`` is that time, or the run's end when not reached. ``field``: the run's
        :class:`~agnav_host.sim.field_gen.FieldScore` (the referee's ``field_score()``), None off a field."""
        xy = np.asarray(xy, dtype=float)
        end = xy[-1]
        fpe = math.hypot(end[0] - goal_xy[0], end[1] - goal_xy[1])
        fhe = None if goal_yaw_rad is None else math.degrees(abs(norm_angle_rad(float(yaw_rad[-1]) - goal_yaw_rad)))
        ate = None if goal_arrival_s is None or arrival_s is None else arrival_s - goal_arrival_s
        clear = np.asarray(clearance_m, dtype=float)
        clear = clear[np.isfinite(clear)]
        return RunMetrics(
            success=bool(success),
            time_s=float(arrival_s if arrival_s is not None else t_s[-1]),
            path_length_m=path_length_m(xy),
            bending_energy=bending_energy(xy),
            min_clearance_m=float(clear.min()) if len(clear) else None,
            stops=count_stops(speed_m_s),
            heading_oscillations=count_heading_oscillations(yaw_rate_rad_s),
            reversals=count_reversals(xy),
            final_position_error_m=fpe,
            final_heading_error_deg=fhe,
            arrival_time_error_s=ate,
            **(field.summary() if field is not None else {}),
            field_detail=field,
        )

    def to_dict(self, ndigits: int = 6) -> dict[str, Any]:
        """Keys in SUMMARY_KEYS order; floats rounded so files are stable across platforms."""
        out: dict[str, Any] = {}
        for k in SUMMARY_KEYS:
            v = getattr(self, k)
            out[k] = round(v, ndigits) if isinstance(v, float) else v
        return out


def signed_offset_m(px: FloatArray, py: FloatArray, line: FloatArray) -> FloatArray:
    """Signed distance (m) of points (px[i], py[i]) from a polyline line (k, 2), positive left of
    its direction: how far a robot runs beside a row, a rut's midline or a planned path."""
    return along_and_offset_m(px, py, line)[1]


def along_and_offset_m(px: FloatArray, py: FloatArray, line: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Row coordinates of points (px[i], py[i]) against a polyline line (k, 2): the arc length (m) from
    the line's first point to each point's foot on it, and the signed distance (m, positive left of the
    line's direction) from the foot."""
    a, d = line[:-1], np.diff(line, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    s0 = np.concatenate(([0.0], np.cumsum(seg)[:-1]))
    qx, qy = px[:, None] - a[None, :, 0], py[:, None] - a[None, :, 1]
    u = np.clip((qx * d[None, :, 0] + qy * d[None, :, 1]) / (d**2).sum(axis=1)[None, :], 0.0, 1.0)
    ex, ey = qx - u * d[None, :, 0], qy - u * d[None, :, 1]
    j = np.argmin(np.hypot(ex, ey), axis=1)
    i = np.arange(len(j))
    n = np.sign(d[j, 0] * qy[i, j] - d[j, 1] * qx[i, j]) * np.hypot(ex[i, j], ey[i, j])
    return s0[j] + u[i, j] * seg[j], n


@dataclass(frozen=True)
class RowDistance:
    """How far a run kept from the nearest plant row's design line (proximity following), m: every sample once
    the robot has driven ``settle_m``; ``within`` is the share of those samples within ``band_m`` of ``set_m``.
    ``travel_m`` and ``distance_m`` are the samples themselves (for a plot).

    ``planted_m``: the same samples measured against the row *as planted* (None without the plants' stems): at
    each sample's foot on the design line, the row runs where the stems (each plant's centre) within
    ``planted_window_m`` / 2 along the line stand on average, across it; the distance is taken from there."""

    set_m: float
    band_m: float
    settle_m: float
    mean_m: float
    sd_m: float
    min_m: float
    max_m: float
    within: float
    travel_m: FloatArray
    distance_m: FloatArray
    planted_m: FloatArray | None = None
    planted_window_m: float = 0.0

    def planted(self) -> dict[str, float] | None:
        """Mean, sd, min, max and the share within the band of the distances to the row as planted (None without)."""
        d = self.planted_m
        if d is None or not len(d):
            return None
        return {"window_m": self.planted_window_m, "mean_m": float(d.mean()), "sd_m": float(d.std()),
                "min_m": float(d.min()), "max_m": float(d.max()),
                "within_band": float(np.mean(np.abs(d - self.set_m) <= self.band_m))}

    def to_dict(self, ndigits: int = 4) -> dict[str, Any]:
        out: dict[str, Any] = {
            "set_m": self.set_m, "band_m": self.band_m, "settle_m": self.settle_m, "samples": int(len(self.distance_m)),
            "mean_m": round(self.mean_m, ndigits), "sd_m": round(self.sd_m, ndigits), "min_m": round(self.min_m, ndigits),
            "max_m": round(self.max_m, ndigits), "within_band": round(self.within, ndigits)}
        pl = self.planted()
        if pl is not None:
            out["planted"] = {k: round(v, ndigits) for k, v in pl.items()}
        return out


ROW_SETTLE_M = 2.0  # row_distance: the travel (m) left out at the start, while the follower settles
PLANTED_WINDOW_M = 3.0  # row_distance: the row as planted is the stems' mean over this length of row


def row_distance(px: FloatArray, py: FloatArray, lines: list[FloatArray], set_m: float, settle_m: float = ROW_SETTLE_M,
                 band_m: float = 0.05, plants: list[FloatArray] | None = None,
                 planted_window_m: float = PLANTED_WINDOW_M) -> RowDistance | None:
    """:class:`RowDistance` of a driven path (px, py) against the row design lines ``lines`` (each (k, 2)):
    at each sample the distance to the nearest line; with ``plants`` (each line's stems (k, 2), as
    ``World.row_plants``) also the distance to the row as planted. None when there is no line or the robot never
    drove ``settle_m``."""
    px, py = np.asarray(px, dtype=float), np.asarray(py, dtype=float)
    if not lines or len(px) < 2:
        return None
    d = np.full(len(px), np.inf)
    near = np.zeros(len(px), dtype=int)
    s_near = np.zeros(len(px))
    n_near = np.zeros(len(px))
    for j, ln in enumerate(np.asarray(ln, dtype=float) for ln in lines):
        for i in range(0, len(px), 2000):  # in pieces: a (samples x segments) array per piece, not per run
            part = slice(i, i + 2000)
            s, n = along_and_offset_m(px[part], py[part], ln)
            closer = np.abs(n) < d[part]
            d[part] = np.where(closer, np.abs(n), d[part])
            near[part] = np.where(closer, j, near[part])
            s_near[part] = np.where(closer, s, s_near[part])
            n_near[part] = np.where(closer, n, n_near[part])
    travel = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(px), np.diff(py)))))
    keep = travel >= settle_m
    if not keep.any():
        return None
    dk = d[keep]
    planted = None
    if plants is not None and len(plants) == len(lines):
        planted = np.abs(n_near - _planted_offset_m(s_near, near, lines, plants, planted_window_m))[keep]
    return RowDistance(float(set_m), float(band_m), float(settle_m), float(dk.mean()), float(dk.std()), float(dk.min()),
                       float(dk.max()), float(np.mean(np.abs(dk - set_m) <= band_m)), travel[keep], dk, planted,
                       float(planted_window_m) if planted is not None else 0.0)


def _planted_offset_m(s: FloatArray, line_of: np.ndarray, lines: list[FloatArray], plants: list[FloatArray],
                      window_m: float) -> FloatArray:
    """Where the row as planted runs, as an offset (m, left of the design line) at arc lengths ``s`` along line
    ``line_of[i]``: the mean offset of that row's stems within +-window/2 along it (0 where none is)."""
    out = np.zeros(len(s))
    for j, (ln, st) in enumerate(zip(lines, plants)):
        m = line_of == j
        st = np.asarray(st, dtype=float).reshape(-1, 2)
        if not m.any() or not len(st):
            continue
        sb, nb = along_and_offset_m(st[:, 0], st[:, 1], np.asarray(ln, dtype=float))
        order = np.argsort(sb)
        sb, cum = sb[order], np.concatenate(([0.0], np.cumsum(nb[order])))
        lo = np.searchsorted(sb, s[m] - 0.5 * window_m, side="left")
        hi = np.searchsorted(sb, s[m] + 0.5 * window_m, side="right")
        cnt = hi - lo
        out[m] = np.where(cnt > 0, (cum[hi] - cum[lo]) / np.maximum(cnt, 1), 0.0)
    return out


def disc_clearance_to_hole_m(px: FloatArray, py: FloatArray, radius_m: float, hole: Hole, grid_m: float = 0.02) -> float:
    """Smallest distance from the disc's edge (centre (px, py), radius) to any point of the hole, m
    (negative: the disc overlaps the hole) over a path of disc centres. The hole is sampled on a ``grid_m`` grid."""
    xs = np.arange(-hole.size_x_m / 2, hole.size_x_m / 2 + 1e-9, grid_m)
    ys = np.arange(-hole.size_y_m / 2, hole.size_y_m / 2 + 1e-9, grid_m)
    lx, ly = (a.ravel() for a in np.meshgrid(xs, ys))
    if hole.elliptic:
        m = (lx / (hole.size_x_m / 2)) ** 2 + (ly / (hole.size_y_m / 2)) ** 2 <= 1.0
        lx, ly = lx[m], ly[m]
    c, s = math.cos(hole.yaw_rad), math.sin(hole.yaw_rad)
    hx, hy = hole.x_m + c * lx - s * ly, hole.y_m + s * lx + c * ly
    # only the samples near the path matter: thin both out first
    best = math.inf
    for k in range(0, len(px), 200):
        d = np.hypot(px[k:k + 200, None] - hx[None, :], py[k:k + 200, None] - hy[None, :])
        best = min(best, float(d.min()))
    return best - radius_m
