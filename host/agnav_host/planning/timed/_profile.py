"""Speed along the path: piecewise constant-acceleration profiles the RC car can drive.

The car's speed command is 0 or inside the calibrated band [v_min, v_max] (ref 003 table 6.2: 43.5 to
200 cm/s; nothing moves below). A *leg* covers a distance d in a set time tau from speed v_s to v_e:
ramp at +-a to a cruise speed v_c, cruise, ramp to v_e. Its time for a cruise speed v is

    t(v) = |v - v_s| / a + |v - v_e| / a + (d - |v^2 - v_s^2| / 2a - |v^2 - v_e^2| / 2a) / v

which falls as v rises, so the cruise speed for a wanted tau is found by bisection. The fastest leg
cruises at min(v_max, the peak the ramps allow); the slowest *moving* leg cruises at v_min. A longer
tau than that needs a stop: the leg dwells at rest first (at the start when already at rest, else
right after braking), which is how a 0.2 m/s average (ref 003's 400 cm in 20 s) is driven by a car
whose slowest speed is 0.435 m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ...types import FloatArray

__all__ = ["SpeedLimits", "SpeedProfile", "LegInfeasible", "leg_time_s", "leg_min_time_s", "solve_leg", "concat_profiles"]


def _clip(x: npt.NDArray[Any], lo: float, hi: float) -> npt.NDArray[Any]:
    """np.clip(x, lo, hi) (the same values: the maximum taken with ``lo`` first, as np.clip does for -0.0)
    without np.clip's Python-level dispatch (several times its two ufunc calls on short arrays)."""
    out: npt.NDArray[Any] = np.minimum(np.maximum(lo, x), hi)
    return out


@dataclass(frozen=True)
class SpeedLimits:
    """Speed band (m/s) and the acceleration the plan may use (m/s^2)."""

    v_min_m_s: float = 0.435
    v_max_m_s: float = 2.0
    accel_m_s2: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.v_min_m_s < self.v_max_m_s:
            raise ValueError(f"need 0 <= v_min < v_max, got {self.v_min_m_s}, {self.v_max_m_s}")
        if not self.accel_m_s2 > 0:
            raise ValueError(f"accel_m_s2 must be > 0, got {self.accel_m_s2}")


class LegInfeasible(ValueError):
    """A leg cannot be driven in the asked time; ``min_time_s`` is the fastest possible (or inf)."""

    def __init__(self, reason: str, min_time_s: float) -> None:
        super().__init__(reason)
        self.reason = reason
        self.min_time_s = min_time_s


@dataclass(frozen=True)
class SpeedProfile:
    """Phases k = 0..n-1 start at ``t_s[k]`` (relative to the profile start) with arc length ``s_m[k]``,
    speed ``v_m_s[k]`` and constant acceleration ``a_m_s2[k]``; ``t_s[n]`` is the end time. ``kind``
    names each phase ("ramp", "cruise", "dwell")."""

    t_s: FloatArray
    s_m: FloatArray
    v_m_s: FloatArray
    a_m_s2: FloatArray
    kind: tuple[str, ...]

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])

    @property
    def length_m(self) -> float:
        if len(self.a_m_s2) == 0:
            return 0.0
        dt = self.t_s[-1] - self.t_s[-2]
        return float(self.s_m[-1] + self.v_m_s[-1] * dt + 0.5 * self.a_m_s2[-1] * dt * dt)

    @property
    def max_speed_m_s(self) -> float:
        if len(self.v_m_s) == 0:
            return 0.0
        dt = np.diff(self.t_s)
        return float(max(np.max(self.v_m_s), np.max(self.v_m_s + self.a_m_s2 * dt)))

    @property
    def cruise_speed_m_s(self) -> float:
        c = [float(v) for v, k in zip(self.v_m_s, self.kind) if k == "cruise"]
        return max(c) if c else self.max_speed_m_s

    @property
    def dwell_s(self) -> float:
        return float(sum(self.t_s[k + 1] - self.t_s[k] for k in range(len(self.kind)) if self.kind[k] == "dwell"))

    def eval(self, t_rel: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """(arc length m, speed m/s) at times relative to the profile start; clamped at both ends."""
        t = _clip(np.asarray(t_rel, dtype=float), 0.0, self.t_s[-1])
        if len(self.a_m_s2) == 0:
            return np.zeros_like(t), np.zeros_like(t)
        k = _clip(np.searchsorted(self.t_s, t, "right") - 1, 0, len(self.a_m_s2) - 1)
        dt = t - self.t_s[k]
        return self.s_m[k] + self.v_m_s[k] * dt + 0.5 * self.a_m_s2[k] * dt * dt, self.v_m_s[k] + self.a_m_s2[k] * dt

    def s_at(self, t_rel: FloatArray) -> FloatArray:
        """The arc length of :meth:`eval` (the same values), without the speed."""
        t = _clip(np.asarray(t_rel, dtype=float), 0.0, self.t_s[-1])
        if len(self.a_m_s2) == 0:
            return np.zeros_like(t)
        k = _clip(np.searchsorted(self.t_s, t, "right") - 1, 0, len(self.a_m_s2) - 1)
        dt = t - self.t_s[k]
        out: FloatArray = self.s_m[k] + self.v_m_s[k] * dt + 0.5 * self.a_m_s2[k] * dt * dt
        return out

    def coming_to_rest(self, t_rel: float) -> bool:
        """True while the profile stands still in a dwell at ``t_rel`` (relative), or brakes straight into one."""
        n = len(self.kind)
        if n == 0 or not 0.0 <= t_rel < self.t_s[-1]:
            return False
        k = min(int(np.searchsorted(self.t_s, t_rel, "right")) - 1, n - 1)
        if self.kind[k] == "dwell":
            return True
        return bool(self.a_m_s2[k] < 0.0) and k + 1 < n and self.kind[k + 1] == "dwell"

def _ramp_d(v0: float, v1: float, a: float) -> float:
    return abs(v1 * v1 - v0 * v0) / (2.0 * a)


def leg_time_s(d: float, v_s: float, v_e: float, v: float, a: float) -> float:
    """Duration of a leg with cruise speed ``v`` (inf when the ramps do not fit in ``d``)."""
    cruise = d - _ramp_d(v_s, v, a) - _ramp_d(v, v_e, a)
    if cruise < -1e-9 or v <= 0:
        return math.inf
    return abs(v - v_s) / a + abs(v - v_e) / a + max(cruise, 0.0) / v


def _v_peak(d: float, v_s: float, v_e: float, lim: SpeedLimits) -> float:
    a = lim.accel_m_s2
    return min(lim.v_max_m_s, math.sqrt(a * d + 0.5 * (v_s * v_s + v_e * v_e)))


def leg_min_time_s(d: float, v_s: float, v_e: float, lim: SpeedLimits) -> float:
    """Fastest time for the leg (inf when it is too short to brake from v_s to v_e)."""
    if d <= 0:
        return 0.0 if abs(v_s - v_e) < 1e-9 else math.inf
    vp = _v_peak(d, v_s, v_e, lim)
    return leg_time_s(d, v_s, v_e, max(vp, 1e-6), lim.accel_m_s2)


def _phases_for(d: float, v_s: float, v_e: float, v: float, a: float) -> list[tuple[str, float, float, float]]:
    """[(kind, duration, start speed, accel)] of a leg with cruise speed v."""
    out = []
    t1 = abs(v - v_s) / a
    if t1 > 1e-9:
        out.append(("ramp", t1, v_s, math.copysign(a, v - v_s)))
    cruise = d - _ramp_d(v_s, v, a) - _ramp_d(v, v_e, a)
    if cruise > 1e-9:
        out.append(("cruise", cruise / v, v, 0.0))
    t3 = abs(v - v_e) / a
    if t3 > 1e-9:
        out.append(("ramp", t3, v, math.copysign(a, v_e - v)))
    return out


def _profile_from(phases: list[tuple[str, float, float, float]]) -> SpeedProfile:
    t = [0.0]
    s = []
    v = []
    acc = []
    kinds = []
    s_now = 0.0
    for kind, dur, v0, a in phases:
        s.append(s_now)
        v.append(v0)
        acc.append(a)
        kinds.append(kind)
        s_now += v0 * dur + 0.5 * a * dur * dur
        t.append(t[-1] + dur)
    return SpeedProfile(np.array(t), np.array(s), np.array(v), np.array(acc), tuple(kinds))


def solve_leg(d: float, tau: float, v_s: float, v_e: float, lim: SpeedLimits, allow_dwell: bool = True) -> SpeedProfile:
    """Profile covering ``d`` m in exactly ``tau`` s from speed v_s to v_e (v_e is 0 or in the band).

    Raises :class:`LegInfeasible` with the reason and the fastest time when tau is too short, or when
    tau is too long and dwelling is not allowed (or not possible: a leg that must end moving)."""
    a = lim.accel_m_s2
    v_s = max(0.0, v_s)
    if d <= 1e-6:
        if tau <= 1e-9:
            return _profile_from([])
        return _profile_from([("dwell", tau, 0.0, 0.0)])
    t_min = leg_min_time_s(d, v_s, v_e, lim)
    if not math.isfinite(t_min):
        raise LegInfeasible(f"cannot {'brake' if v_e < v_s else 'speed up'} from {v_s:.2f} to {v_e:.2f} m/s within {d:.2f} m",
                            math.inf)
    if tau < t_min - 1e-6:
        raise LegInfeasible(f"{d:.2f} m in {tau:.2f} s needs an average of {d / max(tau, 1e-9):.2f} m/s; with "
                            f"v_max {lim.v_max_m_s:.2f} m/s and {a:.2f} m/s^2 the fastest is {t_min:.2f} s", t_min)
    vp = _v_peak(d, v_s, v_e, lim)
    v_lo = min(lim.v_min_m_s, vp)
    t_slow = leg_time_s(d, v_s, v_e, v_lo, a)
    if tau <= t_slow + 1e-9:
        # closed form when the cruise is above both end speeds: a tau v = 2v^2 - (v_s + v_e) v + a d
        # - v^2 + (v_s^2 + v_e^2) / 2, i.e. v^2 - (v_s + v_e + a tau) v + a d + (v_s^2 + v_e^2) / 2 = 0
        bq = v_s + v_e + a * tau
        disc = bq * bq - 4.0 * (a * d + 0.5 * (v_s * v_s + v_e * v_e))
        if disc >= 0.0:
            v = 0.5 * (bq - math.sqrt(disc))
            if max(v_s, v_e) - 1e-9 <= v <= vp + 1e-9 and v >= v_lo - 1e-9 and abs(leg_time_s(d, v_s, v_e, v, a) - tau) < 1e-6:
                return _profile_from(_phases_for(d, v_s, v_e, v, a))
        lo, hi = v_lo, vp  # t(lo) >= tau >= t(hi)
        two_a = 2.0 * a
        vs2, ve2 = v_s * v_s, v_e * v_e
        for _ in range(50):  # to 1e-9 m/s: about 31 halvings of a 2 m/s bracket
            if hi - lo < 1e-9:
                break
            mid = 0.5 * (lo + hi)
            # leg_time_s(d, v_s, v_e, mid, a) written out (the same arithmetic)
            m2 = mid * mid
            cruise = d - abs(m2 - vs2) / two_a - abs(ve2 - m2) / two_a
            t_mid = math.inf if cruise < -1e-9 or mid <= 0 else \
                abs(mid - v_s) / a + abs(mid - v_e) / a + max(cruise, 0.0) / mid
            if t_mid > tau:
                lo = mid
            else:
                hi = mid
        return _profile_from(_phases_for(d, v_s, v_e, hi, a))
    if not allow_dwell:
        raise LegInfeasible(f"{d:.2f} m in {tau:.2f} s is slower than v_min {lim.v_min_m_s:.2f} m/s allows "
                            f"({t_slow:.2f} s) and dwelling is off", t_min)
    # dwell: brake to rest if moving, wait, then the slowest moving leg
    phases: list[tuple[str, float, float, float]] = []
    d_rest = d
    t_used = 0.0
    if v_s > 1e-6:
        d_brake = v_s * v_s / (2.0 * a)
        if d_brake >= d:
            raise LegInfeasible(f"cannot stop from {v_s:.2f} m/s within {d:.2f} m to wait", t_min)
        phases.append(("ramp", v_s / a, v_s, -a))
        d_rest -= d_brake
        t_used += v_s / a
    vp2 = _v_peak(d_rest, 0.0, v_e, lim)
    v_c = min(lim.v_min_m_s, vp2)
    t_leg = leg_time_s(d_rest, 0.0, v_e, v_c, a)
    wait = tau - t_used - t_leg
    if wait < 0:  # braking first made it slower than asked: cruise a little faster instead
        inner = solve_leg(d_rest, tau - t_used, 0.0, v_e, lim, allow_dwell=False)
        return concat_profiles([_profile_from(phases), inner])
    phases.append(("dwell", wait, 0.0, 0.0))
    phases.extend(_phases_for(d_rest, 0.0, v_e, v_c, a))
    return _profile_from(phases)


def concat_profiles(parts: list[SpeedProfile]) -> SpeedProfile:
    """Profiles one after the other (times and arc lengths offset)."""
    ts: list[FloatArray] = [np.zeros(1)]
    ss: list[FloatArray] = []
    vs: list[FloatArray] = []
    accs: list[FloatArray] = []
    kinds: list[str] = []
    t0 = s0 = 0.0
    for p in parts:
        n = len(p.a_m_s2)
        if n:
            ss.append(p.s_m[:n] + s0)
            vs.append(p.v_m_s[:n])
            accs.append(p.a_m_s2[:n])
            kinds.extend(p.kind[:n])
            ts.append(p.t_s[1:n + 1] + t0)
        t0 += p.duration_s
        s0 += p.length_m
    if not ss:
        return SpeedProfile(np.zeros(1), np.zeros(0), np.zeros(0), np.zeros(0), ())
    return SpeedProfile(np.concatenate(ts), np.concatenate(ss), np.concatenate(vs), np.concatenate(accs), tuple(kinds))
