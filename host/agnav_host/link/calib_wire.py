"""Calibration tables as the firmware holds them and AGNAV_CALIB_TABLE carries them.

A :class:`WireTable` is the firmware's ``calib_table_t`` in host form: a neutral PWM (value 0) and
two sides of integer points (pwm, value) listed from neutral outwards, values in cdeg (steering,
positive left) or mm/s (speed, positive forward). The PWM unit is the firmware's table unit (the
ref-003 command byte on the reference car). Rules mirrored from ``firmware/lib/calib/calib.c``
(:func:`validate` returns the same AGNAV_CALIB_RESULT the robot would answer):

* each side has 0 or 2..8 points; the positive side needs >= 2, steering needs both sides;
* along a side, |pwm - neutral| and |value| strictly increase; only a first point may sit at the
  neutral PWM and then with value 0; positive side values >= 0, negative side values <= 0;
* the positive side lies entirely above or entirely below neutral, the negative side opposite;
* pwm <= 3000, |steering| <= 4500 cdeg, |speed| <= 10000 mm/s.

Conversions: :func:`from_calib_table` / :meth:`WireTable.to_calib_table` to and from the SI tables
of :mod:`agnav_host.calib`; :meth:`WireTable.to_message` / :func:`from_message` to and from the
MAVLink message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..calib import CalibTable
from ..units import cdeg_to_rad, milli_to_si

__all__ = ["CALIB_IN_PROGRESS", "WireTable", "TABLE_STEER", "TABLE_SPEED", "TABLE_SPEED_RIGHT", "TABLE_NAMES", "RESULT_NAMES",
           "validate", "from_message", "from_calib_table", "MAX_SIDE_POINTS", "round_trips", "split_points"]

TABLE_STEER, TABLE_SPEED, TABLE_SPEED_RIGHT = 0, 1, 2
TABLE_NAMES = {TABLE_STEER: "steer", TABLE_SPEED: "speed", TABLE_SPEED_RIGHT: "speed_right"}
CALIB_IN_PROGRESS = 6  # AGNAV_CALIB_IN_PROGRESS: a save under way, its result follows in a second ack
RESULT_NAMES = {0: "ACCEPTED", 1: "NON_MONOTONE", 2: "OUT_OF_RANGE", 3: "TOO_FEW_POINTS", 4: "BAD_TABLE",
                5: "STORAGE_ERROR", 6: "IN_PROGRESS"}
MAX_SIDE_POINTS = 8
MAX_WIRE_POINTS = 16
PWM_MAX = 3000
ANGLE_LIMIT_CDEG = 4500
SPEED_LIMIT_MM_S = 10000


@dataclass(frozen=True)
class WireTable:
    table_id: int
    neutral_pwm: int
    pos: tuple[tuple[int, int], ...]  # (pwm, value >= 0), outward from neutral
    neg: tuple[tuple[int, int], ...]  # (pwm, value <= 0), outward from neutral

    # ---- shape -------------------------------------------------------------------------------
    @property
    def pos_above(self) -> bool:
        """True if the positive side (left / forward) lies above the neutral PWM."""
        return bool(self.pos) and self.pos[-1][0] > self.neutral_pwm

    @property
    def dead_band(self) -> tuple[int, int]:
        """(low, high) PWM edges of the dead band: the innermost point of each side (neutral if none)."""
        lo = hi = self.neutral_pwm
        for side in (self.pos, self.neg):
            if side:
                p = side[0][0]
                if p < self.neutral_pwm:
                    lo = p
                elif p > self.neutral_pwm:
                    hi = p
        return lo, hi

    def points(self) -> list[tuple[int, int]]:
        """All points sorted by PWM (the wire order)."""
        return sorted(list(self.pos) + list(self.neg), key=lambda p: p[0])

    # ---- lookups mirrored from calib.c ---------------------------------------------------------
    def value(self, pwm: int) -> int:
        """Forward lookup pwm -> cdeg or mm/s, as ``calib_table_value()`` (integer, rounded)."""
        pwm = int(pwm)
        if pwm == self.neutral_pwm:
            return 0
        above = pwm > self.neutral_pwm
        side = self.pos if above == self.pos_above else self.neg
        d = abs(pwm - self.neutral_pwm)
        if not side or d < abs(side[0][0] - self.neutral_pwm):
            return 0
        for (p0, v0), (p1, v1) in zip(side, side[1:]):
            d0, d1 = abs(p0 - self.neutral_pwm), abs(p1 - self.neutral_pwm)
            if d < d1:
                return v0 + _div_round((v1 - v0) * (d - d0), d1 - d0)
        return side[-1][1]

    def pwm(self, value: int) -> int:
        """Inverse lookup cdeg or mm/s -> pwm, as ``calib_table_pwm()``."""
        value = int(value)
        if value == 0:
            return self.neutral_pwm
        side = self.pos if value > 0 else self.neg
        mag = abs(value)
        if not side:
            side = self.pos
            if not side:
                return self.neutral_pwm
        if mag < abs(side[0][1]):
            return self.neutral_pwm
        for (p0, v0), (p1, v1) in zip(side, side[1:]):
            m0, m1 = abs(v0), abs(v1)
            if mag < m1:
                return p0 + _div_round((p1 - p0) * (mag - m0), m1 - m0)
        return side[-1][0]

    # ---- conversions ---------------------------------------------------------------------------
    def to_message(self, mav: Any, target_system: int = 0, target_component: int = 0) -> Any:
        pts = self.points()
        if len(pts) > MAX_WIRE_POINTS:
            raise ValueError(f"table has {len(pts)} points; the message carries {MAX_WIRE_POINTS}")
        pwm = [p for p, _ in pts] + [0] * (MAX_WIRE_POINTS - len(pts))
        val = [v for _, v in pts] + [0] * (MAX_WIRE_POINTS - len(pts))
        lo, hi = self.dead_band
        return mav.agnav_calib_table_encode(target_system, target_component, self.table_id, len(pts), pwm, val,
                                            self.neutral_pwm, lo, hi)

    def to_calib_table(self, pwm_min: float = 0.0, pwm_max: float = 255.0) -> CalibTable:
        """The SI table of :mod:`agnav_host.calib` (rad or m/s). Needs the positive side above
        neutral (that module's convention); a neutral-PWM zero point is dropped (it is implied)."""
        if self.pos and not self.pos_above:
            raise ValueError("CalibTable needs the positive side above neutral; this table is mirrored")
        steer = self.table_id == TABLE_STEER
        k = cdeg_to_rad(1.0) if steer else milli_to_si(1.0)
        # points in PWM and wire units; a dead-band edge sits half a step off neutral
        pos: list[tuple[float, float]] = [(p, v) for p, v in self.pos if p != self.neutral_pwm]
        neg: list[tuple[float, float]] = [(p, v) for p, v in self.neg if p != self.neutral_pwm]
        if len(pos) == 1:  # the zero point carried the side: give it back as the dead-band edge
            pos = [(self.neutral_pwm + 0.5, 0.0)] + pos if self.pos[0][0] == self.neutral_pwm else pos
        if len(neg) == 1:
            neg = [(self.neutral_pwm - 0.5, 0.0)] + neg if self.neg[0][0] == self.neutral_pwm else neg
        vmax = max([abs(v) for _, v in pos + neg] or [1]) * k
        return CalibTable(
            name=TABLE_NAMES.get(self.table_id, str(self.table_id)), unit="rad" if steer else "m_s",
            neutral_pwm=float(self.neutral_pwm),
            pos_pwm=tuple(float(p) for p, _ in pos), pos_value=tuple(abs(v) * k for _, v in pos),
            neg_pwm=tuple(float(p) for p, _ in neg), neg_value=tuple(abs(v) * k for _, v in neg),
            pwm_min=pwm_min, pwm_max=max(pwm_max, max([p for p, _ in pos + neg] or [0])), value_max=vmax)

    def describe(self) -> str:
        unit = "cdeg" if self.table_id == TABLE_STEER else "mm/s"
        lo, hi = self.dead_band
        pts = " ".join(f"{p}:{v}" for p, v in self.points())
        return (f"{TABLE_NAMES.get(self.table_id, self.table_id)}: neutral {self.neutral_pwm}, dead band "
                f"{lo}..{hi}, points (pwm:{unit}) {pts}")


def _div_round(num: int, den: int) -> int:
    return (num + den // 2) // den if num >= 0 else -((-num + den // 2) // den)


def validate(t: WireTable) -> tuple[int, str]:
    """(AGNAV_CALIB_RESULT, message) the firmware would answer for writing ``t``."""
    if t.table_id not in TABLE_NAMES:
        return 4, f"unknown table id {t.table_id}"
    steer = t.table_id == TABLE_STEER
    limit = ANGLE_LIMIT_CDEG if steer else SPEED_LIMIT_MM_S
    if len(t.points()) > MAX_WIRE_POINTS or len(t.pos) > MAX_SIDE_POINTS or len(t.neg) > MAX_SIDE_POINTS:
        return 4, f"too many points (max {MAX_SIDE_POINTS} a side, {MAX_WIRE_POINTS} in all)"
    if not 0 <= t.neutral_pwm <= PWM_MAX:
        return 2, f"neutral pwm {t.neutral_pwm} outside 0..{PWM_MAX}"
    if len(t.pos) < 2 or (steer and len(t.neg) < 2):
        return 3, "positive side needs >= 2 points" + (" and so does the negative side" if steer else "")
    if t.pos[-1][0] == t.neutral_pwm:
        return 4, "positive side ends at neutral"
    above = t.pos_above
    for name, side, sign, side_above in (("pos", t.pos, 1, above), ("neg", t.neg, -1, not above)):
        if len(side) == 1:
            return 3, f"{name} side has 1 point"
        prev_d = prev_m = -1
        for i, (p, v) in enumerate(side):
            if not 0 <= p <= PWM_MAX:
                return 2, f"{name}[{i}] pwm {p} outside 0..{PWM_MAX}"
            if abs(v) > limit:
                return 2, f"{name}[{i}] value {v} beyond +-{limit}"
            if (sign > 0 and v < 0) or (sign < 0 and v > 0):
                return 4, f"{name}[{i}] value {v} has the wrong sign"
            if p == t.neutral_pwm:
                if i != 0 or v != 0:
                    return 4, f"{name}[{i}] sits at neutral with a non-zero value"
            elif (p > t.neutral_pwm) != side_above:
                return 4, f"{name}[{i}] pwm {p} on the wrong side of neutral {t.neutral_pwm}"
            d, m = abs(p - t.neutral_pwm), abs(v)
            if d <= prev_d or m <= prev_m:
                return 1, f"{name}[{i}] ({p}, {v}) not strictly monotone"
            prev_d, prev_m = d, m
    return 0, "ok"


def from_message(m: Any) -> WireTable:
    """AGNAV_CALIB_TABLE -> WireTable, split into sides as ``link_calib_from_msg()`` does."""
    n = min(int(m.n_points), MAX_WIRE_POINTS)
    return split_points(int(m.table_id), int(m.neutral_pwm), [(int(m.pwm[i]), int(m.value[i])) for i in range(n)])


def round_trips(t: WireTable) -> bool:
    """True if the robot rebuilds exactly ``t`` from its wire form (zero points can be ambiguous)."""
    try:
        return split_points(t.table_id, t.neutral_pwm, t.points()) == t
    except ValueError:
        return False


def split_points(table_id: int, neutral: int, pts: list[tuple[int, int]]) -> WireTable:
    """Wire points (sorted by pwm) -> sides, with the firmware's rules for zero-valued points."""
    pos_above = neg_above = 0
    for p, v in pts:
        above = 1 if p > neutral else -1
        if v > 0 and pos_above == 0:
            pos_above = above
        elif v < 0 and neg_above == 0:
            neg_above = above
    pos: list[tuple[int, int]] = []
    neg: list[tuple[int, int]] = []
    for p, v in pts:
        above = 1 if p > neutral else -1
        if v == 0 and p == neutral:
            side = neg if (pos and pos[0][0] == neutral) else pos
        elif v > 0 or (v == 0 and pos_above == above):
            side = pos
        elif v < 0 or (v == 0 and neg_above == above):
            side = neg
        else:
            raise ValueError(f"point ({p}, {v}) fits neither side")
        side.append((p, v))
    pos.sort(key=lambda q: abs(q[0] - neutral))
    neg.sort(key=lambda q: abs(q[0] - neutral))
    return WireTable(table_id, neutral, tuple(pos), tuple(neg))


def from_calib_table(t: CalibTable, table_id: int) -> WireTable:
    """SI table (rad or m/s, possibly fractional PWM) -> firmware integer table.

    PWM is rounded to integers; a dead-band edge at a half count moves outward (never into the
    dead band); points that rounding makes non-monotone are dropped; sides longer than 8 points
    keep the points that best preserve the curve."""
    steer = table_id == TABLE_STEER
    k = 100.0 * 180.0 / math.pi if steer else 1000.0
    neutral = int(round(t.neutral_pwm))

    def side(pwms: tuple[float, ...], vals: tuple[float, ...], sign: int, up: bool) -> tuple[tuple[int, int], ...]:
        out: list[tuple[int, int]] = []
        for i, (p, v) in enumerate(zip(pwms, vals)):
            ip = (math.ceil(p) if up else math.floor(p)) if i == 0 else int(round(p))
            iv = sign * int(round(v * k))
            if out and (abs(ip - neutral) <= abs(out[-1][0] - neutral) or abs(iv) <= abs(out[-1][1])):
                continue
            if ip == neutral and iv != 0:
                ip += 1 if up else -1
            out.append((ip, iv))
        return tuple(_simplify(out, MAX_SIDE_POINTS))

    return WireTable(table_id, neutral, side(t.pos_pwm, t.pos_value, 1, True), side(t.neg_pwm, t.neg_value, -1, False))


def _simplify(pts: list[tuple[int, int]], k: int) -> list[tuple[int, int]]:
    """Keep at most k points: the ends, then greedily the point farthest from the current polyline."""
    if len(pts) <= k:
        return pts
    keep = {0, len(pts) - 1}
    while len(keep) < k:
        idx = sorted(keep)
        best, best_err = None, -1.0
        for a, b in zip(idx, idx[1:]):
            (p0, v0), (p1, v1) = pts[a], pts[b]
            for j in range(a + 1, b):
                p, v = pts[j]
                interp = v0 + (v1 - v0) * (p - p0) / (p1 - p0)
                err = abs(v - interp)
                if err > best_err:
                    best, best_err = j, err
        if best is None:
            break
        keep.add(best)
    return [pts[i] for i in sorted(keep)]
