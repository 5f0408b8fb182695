"""Python mirror of the firmware actuator calibration tables (PWM <-> steering angle / speed).

A table maps a raw actuator command ("PWM", in whatever integer unit the board's output uses; the
defaults are the 8-bit ATmega compare values of ref 003) to a physical value, in SI units (rad for
steering, m/s for speed). It has two sides around a neutral command:

* the *positive* side: breakpoints with PWM ascending from the neutral band upwards, values are
  magnitudes, strictly increasing (positive steering = left, REP-103; positive speed = forward);
* the *negative* side: breakpoints with PWM descending from the neutral band downwards, values are
  magnitudes, strictly increasing (the physical value is their negative). A side may be empty: that
  direction is not available (e.g. no reverse on the RC car's speed controller).

The *dead band* is the open PWM interval between the first breakpoint of each side (an empty side
extends it to the end of the PWM range); any command inside it gives 0. The first breakpoint of a side
may have a non-zero value (a motor that does not creep below a minimum speed). Beyond the last
breakpoint the value saturates, and never exceeds ``value_max``.

Forward lookup :meth:`CalibTable.value_from_pwm` is what the actuator physically does; inverse lookup
:meth:`CalibTable.pwm_from_value` is what the controller (firmware ``lib/calib``) computes. Simulating a
miscalibrated robot means giving the robot one table and the controller another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "CalibError",
    "CalibTable",
    "check_table",
    "default_steering_table",
    "default_speed_table",
    "table_from_dict",
]


class CalibError(ValueError):
    """A calibration table was refused; the message gives the reason."""


@dataclass(frozen=True)
class CalibTable:
    """Monotone piecewise-linear PWM <-> physical value table. See the module docstring."""

    name: str
    unit: str  # "rad" or "m_s"
    neutral_pwm: float
    pos_pwm: tuple[float, ...]
    pos_value: tuple[float, ...]
    neg_pwm: tuple[float, ...]
    neg_value: tuple[float, ...]
    pwm_min: float
    pwm_max: float
    value_max: float
    quantum_pwm: float = 1.0  # output resolution of the PWM channel; 0 = continuous

    def __post_init__(self) -> None:
        check_table(self)

    # ---- forward: what the actuator does -----------------------------------------------------
    def value_from_pwm(self, pwm: float | npt.ArrayLike) -> Any:
        """Physical value (rad or m/s) produced by a PWM command; scalar in, float out."""
        p = np.clip(np.asarray(pwm, dtype=float), self.pwm_min, self.pwm_max)
        out = np.zeros_like(p)
        if self.pos_pwm:
            m = p >= self.pos_pwm[0]
            out[m] = np.interp(p[m], self.pos_pwm, self.pos_value)
        if self.neg_pwm:
            m = p <= self.neg_pwm[0]
            # np.interp needs ascending x: reverse the descending negative side
            out[m] = -np.interp(p[m], self.neg_pwm[::-1], self.neg_value[::-1])
        out = np.clip(out, -self.value_max, self.value_max)
        return float(out) if out.ndim == 0 else out

    # ---- inverse: what the controller commands -----------------------------------------------
    def pwm_from_value(self, value: float) -> float:
        """PWM the controller outputs for a wanted physical value (rad or m/s).

        0 gives the neutral PWM. A magnitude below the side's first value (slower, or a smaller angle,
        than the actuator can give) gives the neutral PWM too, as the firmware's ``calib_table_pwm``
        does: the car stops (or steers straight) rather than creeping at its smallest command. A
        magnitude beyond the table saturates. A direction whose side is empty gives the neutral PWM (the
        firmware would drive the other side's magnitude on a sign-magnitude output stage; an RC car's
        speed controller without reverse does nothing). The result is rounded to ``quantum_pwm`` and
        never falls back inside the dead band.
        """
        if not math.isfinite(value):
            raise CalibError(f"{self.name}: cannot look up non-finite value {value!r}")
        if value == 0.0:
            return self._quantise(self.neutral_pwm, 0)
        side_pwm, side_val, sign = (
            (self.pos_pwm, self.pos_value, 1) if value > 0 else (self.neg_pwm, self.neg_value, -1)
        )
        if not side_pwm:
            return self._quantise(self.neutral_pwm, 0)
        mag = min(abs(value), self.value_max, side_val[-1])
        if mag < side_val[0]:
            return self._quantise(self.neutral_pwm, 0)
        return self._quantise(float(np.interp(mag, side_val, side_pwm)), sign)

    def _quantise(self, pwm: float, sign: int) -> float:
        q = self.quantum_pwm
        if q <= 0:
            return float(pwm)
        out = round(pwm / q) * q
        # rounding must not push a moving command back into the dead band
        if sign > 0 and self.pos_pwm and out < self.pos_pwm[0]:
            out = math.ceil(self.pos_pwm[0] / q) * q
        elif sign < 0 and self.neg_pwm and out > self.neg_pwm[0]:
            out = math.floor(self.neg_pwm[0] / q) * q
        return float(min(max(out, self.pwm_min), self.pwm_max))

    # ---- variants --------------------------------------------------------------------------
    def miscalibrated(self, value_scale: float = 1.0, pwm_offset: float = 0.0) -> "CalibTable":
        """A copy whose values are scaled and whose breakpoints are shifted by ``pwm_offset``.

        Use it as the robot's *true* table while the controller keeps this one: e.g.
        ``value_scale=0.9`` is a servo that turns 10 % less than believed, ``pwm_offset=3`` a
        trim error of 3 counts. Breakpoints shifted out of the PWM range are refused.
        """
        return replace(
            self,
            name=f"{self.name}*",
            neutral_pwm=self.neutral_pwm + pwm_offset,
            pos_pwm=tuple(p + pwm_offset for p in self.pos_pwm),
            neg_pwm=tuple(p + pwm_offset for p in self.neg_pwm),
            pos_value=tuple(v * value_scale for v in self.pos_value),
            neg_value=tuple(v * value_scale for v in self.neg_value),
            value_max=self.value_max * max(value_scale, 1.0),
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (the scenario-file ``[robot.*_table]`` form, values in SI)."""
        return {
            "neutral_pwm": self.neutral_pwm,
            "pos_pwm": list(self.pos_pwm),
            "pos_value": list(self.pos_value),
            "neg_pwm": list(self.neg_pwm),
            "neg_value": list(self.neg_value),
            "pwm_min": self.pwm_min,
            "pwm_max": self.pwm_max,
            "value_max": self.value_max,
            "quantum_pwm": self.quantum_pwm,
        }


def check_table(t: CalibTable) -> None:
    """Raise :class:`CalibError` naming the first problem found in ``t``; return None if valid."""

    def bad(msg: str) -> CalibError:
        return CalibError(f"calibration table {t.name!r}: {msg}")

    scalars = {
        "neutral_pwm": t.neutral_pwm,
        "pwm_min": t.pwm_min,
        "pwm_max": t.pwm_max,
        "value_max": t.value_max,
        "quantum_pwm": t.quantum_pwm,
    }
    for key, v in scalars.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise bad(f"{key} must be a finite number, got {v!r}")
    if t.pwm_min >= t.pwm_max:
        raise bad(f"pwm_min {t.pwm_min} must be below pwm_max {t.pwm_max}")
    if t.value_max <= 0:
        raise bad(f"value_max must be > 0, got {t.value_max}")
    if t.quantum_pwm < 0:
        raise bad(f"quantum_pwm must be >= 0, got {t.quantum_pwm}")
    if not t.pwm_min <= t.neutral_pwm <= t.pwm_max:
        raise bad(f"neutral_pwm {t.neutral_pwm} outside [{t.pwm_min}, {t.pwm_max}]")
    if not t.pos_pwm and not t.neg_pwm:
        raise bad("both sides are empty")
    for side, pwm, val, up in (("pos", t.pos_pwm, t.pos_value, True), ("neg", t.neg_pwm, t.neg_value, False)):
        if len(pwm) != len(val):
            raise bad(f"{side}_pwm has {len(pwm)} points but {side}_value has {len(val)}")
        if len(pwm) == 1:
            raise bad(f"{side} side needs at least 2 breakpoints (or none)")
        for i, (p, v) in enumerate(zip(pwm, val)):
            if not (isinstance(p, (int, float)) and math.isfinite(p)):
                raise bad(f"{side}_pwm[{i}] is not a finite number: {p!r}")
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise bad(f"{side}_value[{i}] is not a finite number: {v!r}")
            if not t.pwm_min <= p <= t.pwm_max:
                raise bad(f"{side}_pwm[{i}] = {p} outside the PWM range [{t.pwm_min}, {t.pwm_max}]")
            if v < 0:
                raise bad(f"{side}_value[{i}] = {v} is negative (sides hold magnitudes)")
            if v > t.value_max * (1 + 1e-9):
                raise bad(f"{side}_value[{i}] = {v} exceeds value_max {t.value_max}")
        for i in range(1, len(pwm)):
            if up and not pwm[i] > pwm[i - 1]:
                raise bad(f"pos_pwm not strictly increasing at index {i} ({pwm[i - 1]} -> {pwm[i]})")
            if not up and not pwm[i] < pwm[i - 1]:
                raise bad(f"neg_pwm not strictly decreasing at index {i} ({pwm[i - 1]} -> {pwm[i]})")
            if not val[i] > val[i - 1]:
                raise bad(f"{side}_value not strictly increasing at index {i} ({val[i - 1]} -> {val[i]})")
    if t.pos_pwm and t.pos_pwm[0] < t.neutral_pwm:
        raise bad(f"pos side starts at {t.pos_pwm[0]}, below neutral_pwm {t.neutral_pwm}")
    if t.neg_pwm and t.neg_pwm[0] > t.neutral_pwm:
        raise bad(f"neg side starts at {t.neg_pwm[0]}, above neutral_pwm {t.neutral_pwm}")


def table_from_dict(name: str, unit: str, d: dict[str, Any]) -> CalibTable:
    """Build and validate a table from its dict form (see :meth:`CalibTable.to_dict`)."""
    known = {"neutral_pwm", "pos_pwm", "pos_value", "neg_pwm", "neg_value", "pwm_min", "pwm_max",
             "value_max", "quantum_pwm"}
    extra = set(d) - known
    if extra:
        raise CalibError(f"calibration table {name!r}: unknown key(s) {sorted(extra)}")
    missing = known - {"quantum_pwm"} - set(d)
    if missing:
        raise CalibError(f"calibration table {name!r}: missing key(s) {sorted(missing)}")
    try:
        return CalibTable(
            name=name,
            unit=unit,
            neutral_pwm=float(d["neutral_pwm"]),
            pos_pwm=tuple(float(x) for x in d["pos_pwm"]),
            pos_value=tuple(float(x) for x in d["pos_value"]),
            neg_pwm=tuple(float(x) for x in d["neg_pwm"]),
            neg_value=tuple(float(x) for x in d["neg_value"]),
            pwm_min=float(d["pwm_min"]),
            pwm_max=float(d["pwm_max"]),
            value_max=float(d["value_max"]),
            quantum_pwm=float(d.get("quantum_pwm", 1.0)),
        )
    except (TypeError, ValueError) as e:
        if isinstance(e, CalibError):
            raise
        raise CalibError(f"calibration table {name!r}: {e}") from e


# ---- defaults from ref 003 (RC car, ATmega 8-bit PWM compare values) ------------------------------
# Steering (ref 003 eq. 6.3/6.4, least-squares fits of table 6.1, phi in degrees):
#   left  (PWM above centre): |phi| = 0.6502 * PWM - 86.477
#   right (PWM below centre): |phi| = -0.6717 * PWM + 89.698
# Both fits cross zero near PWM 133 (133.0 and 133.5; the thesis drives straight at 132-133), so the
# default keeps a one-count servo dead band 132.5..133.5 and saturates at the measured 24.6 deg.
STEER_MAX_DEG = 24.6
STEER_NEUTRAL_PWM = 133.0
# Speed (ref 003 eq. 6.5, table 6.2): v[cm/s] = 2.038 * PWM - 22.636, measured from 43.5 to 200 cm/s;
# below 43.5 cm/s (PWM ~32.4) the car does not move (PWM 0x10 gave 0), no reverse was calibrated.
SPEED_MIN_CM_S = 43.5
SPEED_MAX_CM_S = 200.0


def default_steering_table() -> CalibTable:
    """Steering table of the ref-003 RC car: PWM counts -> virtual front-wheel angle, rad."""
    d2r = math.pi / 180.0
    lo_db, hi_db = STEER_NEUTRAL_PWM - 0.5, STEER_NEUTRAL_PWM + 0.5
    left_sat = (STEER_MAX_DEG + 86.477) / 0.6502  # PWM where the left fit reaches 24.6 deg
    right_sat = (89.698 - STEER_MAX_DEG) / 0.6717  # PWM where the right fit reaches 24.6 deg
    return CalibTable(
        name="steering",
        unit="rad",
        neutral_pwm=STEER_NEUTRAL_PWM,
        pos_pwm=(hi_db, left_sat),
        pos_value=((0.6502 * hi_db - 86.477) * d2r, STEER_MAX_DEG * d2r),
        neg_pwm=(lo_db, right_sat),
        neg_value=((-0.6717 * lo_db + 89.698) * d2r, STEER_MAX_DEG * d2r),
        pwm_min=0.0,
        pwm_max=255.0,
        value_max=STEER_MAX_DEG * d2r,
    )


def default_speed_table() -> CalibTable:
    """Speed table of the ref-003 RC car: PWM counts -> forward speed, m/s (no reverse)."""
    p_lo = (SPEED_MIN_CM_S + 22.636) / 2.038
    p_hi = (SPEED_MAX_CM_S + 22.636) / 2.038
    return CalibTable(
        name="speed",
        unit="m_s",
        neutral_pwm=0.0,
        pos_pwm=(p_lo, p_hi),
        pos_value=(SPEED_MIN_CM_S / 100.0, SPEED_MAX_CM_S / 100.0),
        neg_pwm=(),
        neg_value=(),
        pwm_min=0.0,
        pwm_max=255.0,
        value_max=SPEED_MAX_CM_S / 100.0,
    )
