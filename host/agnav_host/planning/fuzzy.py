"""A small fuzzy engine for the FLB planner (ref 000): trapezoids, a 27-rule table, product
inference and centre-of-largest-area (CLA) defuzzification. Plain floats and one numpy array
per step; no generic fuzzy library.

Distances are clearances (range minus robot radius) divided by the robot radius ("normalised by
the robot size", ref 000). The heading output is a change of heading in rad, CCW positive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..types import FloatArray

__all__ = [
    "Dist",
    "Speed",
    "Turn",
    "RULES",
    "Rule",
    "trapezoid",
    "DistanceSets",
    "TurnSets",
    "infer",
    "cla_defuzzify",
    "Inference",
]


class Dist(IntEnum):
    CLOSE = 0
    MEDIUM = 1
    FAR = 2


class Speed(IntEnum):
    STOP = 0  # 0
    SLOW = 1  # 0.2 Vmax
    FAST = 2  # Vmax


SPEED_FRACTION = (0.0, 0.2, 1.0)


class Turn(IntEnum):
    NB = 0
    NS = 1
    ZR = 2
    PS = 3
    PB = 4
    GOAL = 5  # towards the goal: its side when the front is blocked, its bearing when it is open


@dataclass(frozen=True)
class Rule:
    left: Dist
    front: Dist
    right: Dist
    speed: Speed
    turn: Turn


_C, _M, _F = Dist.CLOSE, Dist.MEDIUM, Dist.FAR
_T = Turn
# Ref 000, table 3-I, in its order: IF (dL, dF, dR) THEN (v, dPhi). Rule 27 says ZR there, but the
# text says that with every sector far the robot drives to the goal at full speed, so it uses GOAL;
# likewise ZR with a Far front (rules 17, 26) is read as "no avoidance turn: keep seeking the goal"
# (a literal zero turn lets the robot run along a wall past the goal, never turning to it).
RULES: tuple[Rule, ...] = (
    Rule(_C, _C, _C, Speed.STOP, _T.PB), Rule(_C, _C, _M, Speed.STOP, _T.NS), Rule(_C, _C, _F, Speed.STOP, _T.NB),
    Rule(_C, _M, _C, Speed.STOP, _T.ZR), Rule(_C, _M, _M, Speed.STOP, _T.NS), Rule(_C, _M, _F, Speed.STOP, _T.NS),
    Rule(_C, _F, _C, Speed.STOP, _T.ZR), Rule(_C, _F, _M, Speed.STOP, _T.NS), Rule(_C, _F, _F, Speed.STOP, _T.NS),
    Rule(_M, _C, _C, Speed.SLOW, _T.PS), Rule(_M, _C, _M, Speed.SLOW, _T.GOAL), Rule(_M, _C, _F, Speed.SLOW, _T.NS),
    Rule(_M, _M, _C, Speed.SLOW, _T.PS), Rule(_M, _M, _M, Speed.SLOW, _T.ZR), Rule(_M, _M, _F, Speed.SLOW, _T.NS),
    Rule(_M, _F, _C, Speed.SLOW, _T.PS), Rule(_M, _F, _M, Speed.SLOW, _T.GOAL), Rule(_M, _F, _F, Speed.SLOW, _T.NS),
    Rule(_F, _C, _C, Speed.SLOW, _T.PB), Rule(_F, _C, _M, Speed.SLOW, _T.PS), Rule(_F, _C, _F, Speed.SLOW, _T.GOAL),
    Rule(_F, _M, _C, Speed.SLOW, _T.PS), Rule(_F, _M, _M, Speed.SLOW, _T.PS), Rule(_F, _M, _F, Speed.SLOW, _T.GOAL),
    Rule(_F, _F, _C, Speed.SLOW, _T.PS), Rule(_F, _F, _M, Speed.SLOW, _T.GOAL), Rule(_F, _F, _F, Speed.FAST, _T.GOAL),
)
assert len(RULES) == 27
_RULE_INDEX = {(r.left, r.front, r.right): r for r in RULES}


def trapezoid(x: float, a: float, b: float, c: float, d: float) -> float:
    """Trapezoid membership: 0 below a, rising to 1 at b, 1 up to c, falling to 0 at d.

    ``a == b`` (or ``c == d``) makes a vertical edge; use -inf / inf for shoulders."""
    if x < a or x > d:
        return 0.0
    if x < b:
        return (x - a) / (b - a)
    if x <= c:
        return 1.0
    return (d - x) / (d - c)


@dataclass(frozen=True)
class DistanceSets:
    """Close / Medium / Far over normalised clearance (clearance / robot radius).

    Close is 1 up to ``close_full`` and 0 from ``medium_full``; Medium rises over that span, stays 1
    to ``medium_end`` and falls to 0 at ``far_full``, where Far reaches 1. The defaults (0.5, 1.5,
    2.5, 3.5 radii) put a 0.45 m robot's Close band at 0.11-0.34 m and Far beyond 0.79 m."""

    close_full: float = 0.5
    medium_full: float = 1.5
    medium_end: float = 2.5
    far_full: float = 3.5

    def __post_init__(self) -> None:
        if not 0.0 <= self.close_full < self.medium_full <= self.medium_end < self.far_full:
            raise ValueError("DistanceSets: need 0 <= close_full < medium_full <= medium_end < far_full")

    def memberships(self, x: float) -> tuple[float, float, float]:
        """(Close, Medium, Far) degrees of a normalised clearance."""
        return (
            trapezoid(x, -math.inf, -math.inf, self.close_full, self.medium_full),
            trapezoid(x, self.close_full, self.medium_full, self.medium_end, self.far_full),
            trapezoid(x, self.medium_end, self.far_full, math.inf, math.inf),
        )


@dataclass(frozen=True)
class TurnSets:
    """Five triangular heading sets NB..PB centred every ``step_rad`` (30 deg), each ``step_rad``
    wide at half height, on a universe of ``n`` points across +-``span_rad`` (90 deg)."""

    step_rad: float = math.radians(30.0)
    span_rad: float = math.radians(90.0)
    n: int = 91

    @property
    def universe(self) -> FloatArray:
        return np.linspace(-self.span_rad, self.span_rad, self.n)

    def centre(self, t: Turn) -> float:
        return (int(t) - 2) * self.step_rad

    def triangle(self, centre_rad: float) -> FloatArray:
        return np.maximum(0.0, 1.0 - np.abs(self.universe - centre_rad) / self.step_rad)


@dataclass(frozen=True)
class Inference:
    """Result of one inference: fired rules (index, strength), the aggregated heading membership over
    the universe, the defuzzified heading change (rad) and speed fraction (0..1 of Vmax)."""

    fired: tuple[tuple[int, float], ...]
    universe: FloatArray
    aggregate: FloatArray
    turn_rad: float
    speed_fraction: float


_SET_CACHE: dict[TurnSets, FloatArray] = {}


def _fixed_sets(ts: TurnSets) -> FloatArray:
    m = _SET_CACHE.get(ts)
    if m is None:
        m = np.stack([ts.triangle(ts.centre(Turn(k))) for k in range(5)])
        _SET_CACHE[ts] = m
    return m


def infer(left: float, front: float, right: float, goal_bearing_rad: float, trsh: float,
          dsets: DistanceSets = DistanceSets(), tsets: TurnSets = TurnSets(),
          keep_rad: float | None = None, keep_bonus: float = 0.0, goal_side: float | None = None) -> Inference:
    """Run the 27 rules on normalised clearances (left, front, right).

    Firing strength is the product of the three memberships. Each fired rule's heading set is cut at
    its strength (min) and the cuts are aggregated by max; the heading change comes from
    :func:`cla_defuzzify` with threshold ``trsh`` (``keep_rad`` / ``keep_bonus``: its hysteresis);
    the speed is the strength-weighted mean of the rules' speed singletons (ref 000 eq. 3).

    A GOAL turn with the front not Far turns at least one step to the goal's side: the sign of
    ``goal_side`` when given (the caller holds the side while the goal is nearly dead ahead, where
    the sign of the bearing flips with every wobble of the heading), else of the bearing."""
    ml, mf, mr = dsets.memberships(left), dsets.memberships(front), dsets.memberships(right)
    fixed = _fixed_sets(tsets)
    agg = np.zeros(tsets.n)
    fired: list[tuple[int, float]] = []
    num = den = 0.0
    gb = max(-tsets.span_rad, min(tsets.span_rad, goal_bearing_rad))
    for i in range(3):
        if ml[i] == 0.0:
            continue
        for j in range(3):
            if mf[j] == 0.0:
                continue
            a_lf = ml[i] * mf[j]
            for k in range(3):
                if mr[k] == 0.0:
                    continue
                a = a_lf * mr[k]
                rule = _RULE_INDEX[(Dist(i), Dist(j), Dist(k))]
                fired.append((RULES.index(rule), a))
                if rule.turn == Turn.GOAL:
                    c = gb
                    if rule.front != Dist.FAR:  # obstacle ahead: turn at least "small" to the goal's side
                        side = goal_side if goal_side is not None else (c if c != 0.0 else 1.0)
                        c = math.copysign(max(abs(c), tsets.step_rad), side)
                    shape = tsets.triangle(c)
                else:
                    shape = fixed[int(rule.turn)]
                np.maximum(agg, np.minimum(shape, a), out=agg)
                num += a * SPEED_FRACTION[int(rule.speed)]
                den += a
    turn = cla_defuzzify(tsets.universe, agg, trsh, goal_bearing_rad, keep_rad, keep_bonus)
    return Inference(tuple(fired), tsets.universe, agg, turn, num / den if den > 0 else 0.0)


def cla_defuzzify(x: FloatArray, mu: FloatArray, trsh: float, prefer_rad: float = 0.0,
                  keep_rad: float | None = None, keep_bonus: float = 0.0) -> float:
    """Centre of the largest area (ref 000).

    Points whose membership is below ``trsh * max(mu)`` are dropped; the rest split into contiguous
    areas; the centroid of the largest area is returned. Areas within 5 % of the largest count as a
    tie, resolved towards ``prefer_rad`` (the goal side). ``trsh = 0`` is the plain centroid of the
    non-zero support; ``trsh = 1`` keeps only the maxima (mean of maximum). Returns 0 for an empty
    output.

    Hysteresis (not in ref 000; a controller running at 10-15 Hz needs it): the area that holds
    ``keep_rad`` (the previous output), or lies nearest to it, counts ``1 + keep_bonus`` times its
    area, so two areas of nearly equal size do not take turns from one step to the next."""
    if not 0.0 <= trsh <= 1.0:
        raise ValueError(f"trsh must be in [0, 1], got {trsh}")
    peak = float(mu.max()) if len(mu) else 0.0
    if peak <= 0.0:
        return 0.0
    keep = mu >= max(trsh * peak, 1e-12) - 1e-12
    # run boundaries of the kept mask
    k = keep.astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], k, [0]))))
    starts, ends = edges[0::2], edges[1::2]
    held = -1
    if keep_rad is not None and keep_bonus > 0.0 and len(starts) > 1:
        gap = [0.0 if x[s] <= keep_rad <= x[e - 1] else min(abs(x[s] - keep_rad), abs(x[e - 1] - keep_rad))
               for s, e in zip(starts, ends)]
        held = int(np.argmin(gap))
    best = None
    for i, (s, e) in enumerate(zip(starts, ends)):
        w = mu[s:e]
        raw = float(w.sum())
        cen = float((w * x[s:e]).sum() / raw) if raw > 0 else float(x[s:e].mean())
        area = raw * (1.0 + keep_bonus if i == held else 1.0)
        if best is None or area > best[0] * 1.05:
            best = (area, cen)
        elif area >= best[0] / 1.05 and abs(cen - prefer_rad) < abs(best[1] - prefer_rad):
            best = (max(area, best[0]), cen)
    assert best is not None
    return best[1]
