"""Fitting calibration tables from sweep measurements (ref 003, section 6.5, made automatic).

Measurements
    Steering (ref 003 drove circles at a constant PWM and measured their diameter): the angle of
    the virtual middle front wheel follows from the driven arc, phi = atan(L * yaw_rate / v)
    (:func:`steer_from_motion`; ref 003 eq. 6.2 is the small-angle form phi = L / R). The yaw rate
    comes from two rear-wheel encoders, yaw_rate = (v_right - v_left) / track
    (:func:`yaw_rate_from_wheels`), or, with a single encoder, from the circle diameter measured
    by hand (:func:`steer_from_diameter`).
    Speed: wheel-encoder speed (ref 003 timed a fixed distance instead).

Fit (:func:`fit_table`)
    Samples are pooled per PWM (median). The neutral PWM is the centre of the samples that do not
    move (|value| below the dead-band threshold), or the interpolated zero crossing. Each side of
    neutral is fitted separately: magnitudes against distance from neutral by isotonic regression
    (pool-adjacent-violators, so the table is monotone whatever the noise), then made strictly
    monotone on the integer wire grid and reduced to at most 8 points (the firmware's limit) by
    keeping the points that best preserve the curve. A side whose response starts with a jump (a
    motor that does not creep) starts at its first moving point; a side that ramps from zero starts
    with a zero point at the dead-band edge.

Everything here is pure (numpy only), so it is tested on synthetic data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..calib import CalibTable
from ..link.calib_wire import MAX_SIDE_POINTS, TABLE_STEER, WireTable, _simplify, round_trips, validate

__all__ = ["CalibFitError", "FitResult", "isotonic_increasing", "steer_from_motion", "yaw_rate_from_wheels",
           "steer_from_diameter", "fit_table", "pool_samples", "synthetic_sweep"]


class CalibFitError(ValueError):
    """The measurements cannot make a valid table (the message says what to check)."""


def isotonic_increasing(y: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Least-squares non-decreasing fit of ``y`` (pool adjacent violators), weights ``w``."""
    y = np.asarray(y, dtype=float)
    w = np.ones_like(y) if w is None else np.asarray(w, dtype=float)
    vals: list[float] = []
    wts: list[float] = []
    lens: list[int] = []
    for yi, wi in zip(y, w):
        vals.append(float(yi))
        wts.append(float(wi))
        lens.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            wsum = wts[-2] + wts[-1]
            v = (vals[-2] * wts[-2] + vals[-1] * wts[-1]) / wsum
            n = lens[-2] + lens[-1]
            vals[-2:], wts[-2:], lens[-2:] = [v], [wsum], [n]
    return np.repeat(vals, lens)


def yaw_rate_from_wheels(v_left_m_s: float, v_right_m_s: float, track_m: float) -> float:
    """Yaw rate (rad/s, CCW positive) of a rigid axle from its two wheel speeds."""
    return (v_right_m_s - v_left_m_s) / track_m


def steer_from_motion(speed_m_s: float, yaw_rate_rad_s: float, wheelbase_m: float) -> float:
    """Virtual middle front-wheel angle phi = atan(L * yaw_rate / v) (rad, positive left)."""
    if abs(speed_m_s) < 1e-6:
        raise ValueError("steering angle needs motion (v = 0)")
    return math.atan(wheelbase_m * yaw_rate_rad_s / speed_m_s)


def steer_from_diameter(diameter_m: float, wheelbase_m: float, left: bool) -> float:
    """Steering angle from the diameter of the driven circle (ref 003: phi = L / R, exact: atan(L / R))."""
    if not diameter_m > 0 or math.isinf(diameter_m):
        return 0.0
    phi = math.atan(wheelbase_m / (diameter_m / 2.0))
    return phi if left else -phi


def pool_samples(pwm: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(distinct pwm ascending, median value, sample count)."""
    pwm = np.asarray(pwm, dtype=float)
    value = np.asarray(value, dtype=float)
    ok = np.isfinite(pwm) & np.isfinite(value)
    pwm, value = pwm[ok], value[ok]
    if pwm.size == 0:
        raise CalibFitError("no valid samples")
    u = np.unique(pwm)
    med = np.array([np.median(value[pwm == p]) for p in u])
    cnt = np.array([np.count_nonzero(pwm == p) for p in u])
    return u, med, cnt


@dataclass
class FitResult:
    table: WireTable
    neutral_pwm: int
    rms: float                # RMS of (median per PWM - table), cdeg or mm/s
    max_abs_err: float        # largest |median per PWM - table|
    pwm: np.ndarray           # samples as measured
    value: np.ndarray
    warnings: list[str] = field(default_factory=list)
    noise: float = 0.0        # median per-PWM standard deviation of the samples

    def summary(self) -> str:
        unit = "cdeg" if self.table.table_id == TABLE_STEER else "mm/s"
        w = "".join(f"\n  warning: {x}" for x in self.warnings)
        return (f"{self.table.describe()}\n  fit RMS {self.rms:.1f} {unit}, max |error| {self.max_abs_err:.1f} {unit} "
                f"(per-PWM medians; sample noise {self.noise:.1f} {unit}){w}")


def _neutral(u: np.ndarray, med: np.ndarray, thr: float) -> float:
    still = np.abs(med) < thr
    if still.any():
        # the largest run of consecutive still PWMs (a stray zero far out must not move neutral)
        idx = np.flatnonzero(still)
        runs: list[list[int]] = [[idx[0]]]
        for j in idx[1:]:
            if j == runs[-1][-1] + 1:
                runs[-1].append(j)
            else:
                runs.append([j])
        run = max(runs, key=len)
        return float(np.mean(u[run]))
    s = np.sign(med)
    for i in range(len(u) - 1):
        if s[i] != s[i + 1]:
            a, b = med[i], med[i + 1]
            return float(u[i] + (u[i + 1] - u[i]) * (-a) / (b - a))
    raise CalibFitError("no sample stands still and the values never change sign: extend the sweep across neutral")


def _fit_side(d: np.ndarray, m: np.ndarray, cnt: np.ndarray, thr: float) -> list[tuple[float, float]]:
    """One side: distances d ascending (> 0), magnitudes m; returns [(d, m)] strictly increasing."""
    iso = isotonic_increasing(m, cnt)
    moving = np.flatnonzero(iso >= thr)
    if moving.size == 0:
        return []
    k = int(moving[0])
    pts: list[tuple[float, float]] = []
    # collapse PAVA blocks (equal fitted values) to their weighted centre
    i = k
    while i < len(d):
        j = i
        while j + 1 < len(d) and abs(iso[j + 1] - iso[i]) < 1e-9:
            j += 1
        ww = cnt[i:j + 1]
        pts.append((float(np.average(d[i:j + 1], weights=ww)), float(iso[i])))
        i = j + 1
    # ramp or jump at the dead-band edge
    last_dead = float(d[k - 1]) if k > 0 else 0.0
    if len(pts) >= 2:
        (d0, m0), (d1, m1) = pts[0], pts[1]
        crossing = d0 - m0 * (d1 - d0) / (m1 - m0) if m1 > m0 else d0
    else:
        crossing = 0.0
    # no still sample on this side: nothing shows a jump, ramp from the crossing (or neutral);
    # still samples: a ramp only if the line through the first moving points reaches zero past the
    # last still sample, else the actuator jumps (a motor that does not creep)
    if k == 0 or crossing >= last_dead - 0.5:
        pts.insert(0, (float(max(0.0, min(max(crossing, last_dead), pts[0][0] - 1.0))), 0.0))
    return pts


def fit_table(pwm: np.ndarray, value: np.ndarray, table_id: int, *, dead_band: float,
              neutral_pwm: float | None = None, require_both_sides: bool | None = None,
              max_side_points: int = MAX_SIDE_POINTS) -> FitResult:
    """Fit a firmware table to samples (pwm, value in cdeg or mm/s). See the module docstring.

    ``neutral_pwm`` fixes neutral (speed tables: 0, the ESC's stop); ``dead_band`` is the |value|
    below which a sample counts as not moving."""
    pwm = np.asarray(pwm, dtype=float)
    value = np.asarray(value, dtype=float)
    u, med, cnt = pool_samples(pwm, value)
    both = (table_id == TABLE_STEER) if require_both_sides is None else require_both_sides
    warnings: list[str] = []
    n = int(round(_neutral(u, med, dead_band) if neutral_pwm is None else neutral_pwm))
    sides: dict[int, tuple[int, list[tuple[int, int]]]] = {}
    for direction in (1, -1):
        sel = (u - n) * direction > 0
        if not sel.any():
            continue
        order = np.argsort((u[sel] - n) * direction)
        d = ((u[sel] - n) * direction)[order]
        v = med[sel][order]
        c = cnt[sel][order]
        moving = np.abs(v) >= dead_band
        if not moving.any():
            continue
        sign = 1 if np.median(v[moving]) > 0 else -1
        wrong = moving & (np.sign(v) != sign)
        if wrong.any():
            warnings.append(f"{int(wrong.sum())} sample PWM(s) on the {'upper' if direction > 0 else 'lower'} side "
                            f"move the wrong way (noise or a neutral far off); the monotone fit flattens them")
        pts = _fit_side(d, v * sign, c, dead_band)
        ipts: list[tuple[int, int]] = []
        for dd, mm in pts:
            p = int(round(n + direction * dd))
            mag = int(round(mm))
            if ipts and (abs(p - n) <= abs(ipts[-1][0] - n) or mag <= abs(ipts[-1][1])):
                continue
            if p == n and mag != 0:
                p += direction
            ipts.append((p, sign * mag))
        if len(ipts) >= 2:
            sides[direction] = (sign, _simplify(ipts, max_side_points))
    pos = [s for s in sides.values() if s[0] > 0]
    neg = [s for s in sides.values() if s[0] < 0]
    if len(pos) > 1 or len(neg) > 1:
        raise CalibFitError("both sides of neutral move the same way: check the linkage / ESC direction and the sweep")
    if not pos:
        raise CalibFitError("no side of neutral gives a positive value (left turn / forward): "
                            "sweep further or check the direction")
    if both and not neg:
        raise CalibFitError("only one side of neutral moves: steering needs a sweep to both sides")
    pos_pts = list(pos[0][1])
    neg_pts = list(neg[0][1]) if neg else []
    # A zero point at neutral on one side and a zero point off neutral on the other do not survive
    # the wire (the robot gives the neutral point to the positive side first): start both at neutral.
    for a, b in ((pos_pts, neg_pts), (neg_pts, pos_pts)):
        if a and b and a[0] == (n, 0) and b[0][1] == 0 and b[0][0] != n:
            b[0] = (n, 0)
    # The robot gives a lone zero point at neutral to the positive side. When the sweep put it on the
    # negative side (a trim a fraction of a count off: the positive side starts with a jump further
    # out), move it over: the positive side then ramps from neutral, which is what the samples between
    # neutral and its first moving point showed; integer lookups on the negative side do not change.
    if neg_pts and neg_pts[0] == (n, 0) and len(neg_pts) >= 3 and pos_pts and pos_pts[0][0] != n:
        pos_pts = _simplify([neg_pts.pop(0)] + pos_pts, max_side_points)
    table = WireTable(table_id, n, tuple(pos_pts), tuple(neg_pts))
    if not round_trips(table):
        raise CalibFitError(f"fitted table is ambiguous on the wire: {table.describe()}")
    code, why = validate(table)
    if code != 0:
        raise CalibFitError(f"fitted table would be refused by the firmware: {why}")
    # fit error on the per-PWM medians (the per-sample spread is measurement noise, reported apart)
    err = med - np.array([table.value(int(round(p))) for p in u], dtype=float)
    rms = float(np.sqrt(np.mean(err ** 2)))
    noise = [float(np.std(value[pwm == p])) for p in u if np.count_nonzero(pwm == p) > 1]
    res = FitResult(table, n, rms, float(np.max(np.abs(err))), pwm, value, warnings,
                    float(np.median(noise)) if noise else 0.0)
    return res


def synthetic_sweep(true: CalibTable, pwms: np.ndarray, unit_scale: float, noise: float = 0.0,
                    repeats: int = 3, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Samples of a car whose actuator is ``true`` (SI), scaled to wire units (100 * deg or 1000 * m/s),
    with Gaussian noise (wire units). For tests and dry runs."""
    rng = np.random.default_rng(seed)
    p = np.repeat(np.asarray(pwms, dtype=float), repeats)
    v = np.asarray(true.value_from_pwm(p), dtype=float) * unit_scale
    return p, v + (rng.normal(0.0, noise, v.shape) if noise > 0 else 0.0)
