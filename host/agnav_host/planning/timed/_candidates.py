"""Geometric candidates for a timed plan: the ref-003 polynomials where they fit, else the path families.

A candidate is a :class:`~._path.GeoPath` that carries what its timing needs: the top speed at which the
steering servo follows its curvature changes (``speed_cap_m_s``), the stops it needs (cusps, and the
curvature jumps of Dubins and Reeds-Shepp paths, with the time to turn the wheels at rest there) and
where it reverses. :mod:`._plan` times each and keeps the one that meets the arrival (or arrives first).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable

import numpy as np

from ...types import FloatArray, norm_angle_rad
from ._families import ALL_WORDS, CSC_WORDS, FamilyPath, Seg, cc_paths, dubins_paths, reeds_shepp_paths, sample_segments, seg_end, turning_rad, word_of
from ._path import GeoPath, build_path, leg_kappa_floor
from ._poly import BoundaryState

if TYPE_CHECKING:
    from ._plan import TimedLimits

__all__ = ["NO_LOOP_TURN_RAD", "poly_candidate", "cc_candidate", "dubins_candidate", "reeds_shepp_candidates", "via_candidate",
           "sharpness_for", "geo_from_family"]


#: a continuous-curvature leg through via points (a deviation) or of a replanning call turns at most this much
#: in all: a loop there would sweep ground the obstacle checks have not looked at
NO_LOOP_TURN_RAD = 1.5 * math.pi
#: sharper clothoids a via leg tries when the gentle ones do not fit (the top speeds they allow), m/s
VIA_LEG_CAPS_M_S = (1.0, 0.6)
#: continuous-curvature words tried: those whose Dubins path is within this of the shortest, m
PRUNE_M = 0.6


def _kmax(lim: "TimedLimits") -> float:
    """The plan's curvature limit, a hair inside it (atan(l * kmax) rounds back to the steering limit or below)."""
    return lim.plan_kappa_max * (1.0 - 1e-9)


def sharpness_for(lim: "TimedLimits", v_cap_m_s: float) -> float:
    """Clothoid sharpness (dk/ds, 1/m^2) the servo follows at up to ``v_cap_m_s``: dk/dt = sec^2(phi)
    phi_dot / l >= phi_dot / l, so sigma = steer_rate / (l v) never asks more than the rate."""
    return lim.steer_rate_rad_s / (lim.wheelbase_m * max(v_cap_m_s, 1e-3))


def geo_from_family(fp: FamilyPath, lim: "TimedLimits", speed_cap_m_s: float, spacing_m: float = 0.05,
                    stop_at_jumps: bool = False) -> GeoPath:
    """A sampled path of a family path; its stops are the cusps and (``stop_at_jumps``) every curvature jump,
    each with the time the servo needs to turn the wheels there at rest."""
    xy, yaw, kappa, s, direction = sample_segments(fp.start, fp.segs, spacing_m)
    stops: list[tuple[float, float]] = []
    acc = 0.0
    segs = [g for g in fp.segs if g.length_m > 1e-12]
    for a, b in zip(segs[:-1], segs[1:]):
        acc += a.length_m
        jump = abs(math.atan(lim.wheelbase_m * b.k0) - math.atan(lim.wheelbase_m * a.k1))
        if a.direction != b.direction or (stop_at_jumps and jump > 1e-9):
            stops.append((acc, jump / lim.steer_rate_rad_s))
    fwd = bool(np.all(direction > 0))
    return GeoPath(xy, yaw, kappa, s, (), (0.0, float(s[-1])), f"{fp.family} {fp.word}",
                   None if fwd else direction, tuple(stops), speed_cap_m_s)


def _poly_cap(path: GeoPath, lim: "TimedLimits") -> float:
    """Top speed at which the steering rate follows the polynomial's curvature changes, m/s (dphi/ds <=
    l dk/ds: the bound is conservative by cos^2 phi)."""
    if len(path.s) < 3:
        return math.inf
    ds = np.diff(path.s)
    dk = np.abs(np.diff(path.kappa))
    rate = float(np.max(dk / np.maximum(ds, 1e-9))) * lim.wheelbase_m  # rad/m
    return math.inf if rate < 1e-12 else lim.steer_rate_rad_s / rate


def poly_candidate(states: list[BoundaryState], lim: "TimedLimits", quick: bool = False) -> tuple[GeoPath | None, str]:
    """The ref-003 polynomial path through ``states`` when it fits the steering limit (None and why not).
    ``quick`` (one leg): a leg whose shape alone already needs more steering than the limit is refused before
    it is sampled (:func:`~._path.leg_kappa_floor`; the same verdict, a shorter reason)."""
    try:
        if quick and len(states) == 2:
            floor = leg_kappa_floor(states[0], states[1], lim.wheelbase_m) * (1.0 - 1e-9)
            if math.atan(lim.wheelbase_m * floor) > lim.plan_steer_rad + 1e-6:
                return None, (f"the polynomial needs more than {math.degrees(lim.plan_steer_rad):.1f} deg of steering")
        p = build_path(states, lim.wheelbase_m)
    except ValueError as e:
        return None, str(e)
    steer = math.atan(lim.wheelbase_m * p.max_abs_kappa)
    if steer > lim.plan_steer_rad + 1e-6:
        return None, (f"the polynomial needs {math.degrees(steer):.1f} deg of steering, the limit is "
                      f"{math.degrees(lim.plan_steer_rad):.1f} deg")
    cap = _poly_cap(p, lim)
    if cap < lim.v_min_m_s:
        return None, "the polynomial turns its steering faster than the servo can at the slowest speed"
    return GeoPath(p.xy, p.yaw, p.kappa, p.s, p.forms, p.knots_s, "polynomial " + "/".join(p.forms), None, (), cap), ""


#: end clothoids already integrated ((kind, x, y, th, k, sigma) -> result): the candidates of one replanning
#: call all start from the same state, at the same few sharpnesses; cleared when full
_END_CLOTHOIDS: dict[tuple[object, ...], tuple[Seg | None, tuple[float, float, float]]] = {}


def _unwind(x: float, y: float, th: float, k: float, sigma: float) -> tuple[Seg | None, tuple[float, float, float]]:
    """A clothoid from curvature k back to 0 (sharpness sigma) from (x, y, th), and the pose after it."""
    if abs(k) < 1e-9:
        return None, (x, y, th)
    key = ("out", x, y, th, k, sigma)
    hit = _END_CLOTHOIDS.get(key)
    if hit is None:
        seg = Seg(abs(k) / sigma, k, -math.copysign(sigma, k))
        hit = seg, seg_end(x, y, th, seg)
        _remember(key, hit)
    return hit


def _wind_in(x: float, y: float, th: float, k: float, sigma: float) -> tuple[Seg | None, tuple[float, float, float]]:
    """A clothoid from 0 up to curvature k that ends at (x, y, th), and the pose where it starts."""
    if abs(k) < 1e-9:
        return None, (x, y, th)
    key = ("in", x, y, th, k, sigma)
    hit = _END_CLOTHOIDS.get(key)
    if hit is None:
        seg = Seg(abs(k) / sigma, k, -math.copysign(sigma, k), -1)  # driven backwards from the end: k back to 0
        bx, by, bth = seg_end(x, y, th, seg)
        hit = Seg(abs(k) / sigma, 0.0, math.copysign(sigma, k)), (bx, by, bth)
        _remember(key, hit)
    return hit


def _remember(key: tuple[object, ...], value: tuple[Seg | None, tuple[float, float, float]]) -> None:
    if len(_END_CLOTHOIDS) >= 32:
        _END_CLOTHOIDS.clear()
    _END_CLOTHOIDS[key] = value


def cc_family(a: BoundaryState, b: BoundaryState, lim: "TimedLimits", v_cap_m_s: float, run_in: bool = True,
              max_turn_rad: float = math.inf) -> list[FamilyPath]:
    """Every continuous-curvature path from ``a`` to ``b`` for the sharpness of ``v_cap_m_s``, shortest
    first; a steering angle at either end is wound out (in) by a clothoid first (last). ``run_in``: end on
    a straight of ``lim.run_in_m`` (with no steering asked at the goal). ``max_turn_rad``: leave out paths
    that turn more in all (a loop)."""
    sigma = sharpness_for(lim, v_cap_m_s)
    kmax = _kmax(lim)
    ka = max(-kmax, min(kmax, math.tan(a.steer_rad) / lim.wheelbase_m))
    kb = max(-kmax, min(kmax, math.tan(b.steer_rad) / lim.wheelbase_m))
    head, p0 = _unwind(a.x_m, a.y_m, a.yaw_rad, ka, sigma)
    run = lim.run_in_m if run_in and abs(kb) < 1e-9 else 0.0
    bx, by = b.x_m - run * math.cos(b.yaw_rad), b.y_m - run * math.sin(b.yaw_rad)
    tail, p1 = _wind_in(bx, by, b.yaw_rad, kb, sigma)
    last: tuple[Seg, ...] = ((tail,) if tail else ()) + ((Seg(run, 0.0),) if run > 0 else ())
    out = []
    words = ALL_WORDS if math.isinf(max_turn_rad) else CSC_WORDS  # no loop: the three-turn words are left out
    # the clothoids winding the steering out and in turn k^2 / (2 sigma) each (as turning_rad counts them)
    extra = sum(abs(0.5 * (g.k0 + g.k1)) * g.length_m for g in (head, tail) if g is not None)
    for fp in cc_paths(p0, p1, kmax, sigma, prune_m=PRUNE_M, words=words, max_turn_rad=max_turn_rad, turn_extra_rad=extra):
        if turning_rad(fp) + extra > max_turn_rad + 1e-9:
            continue  # a loop for certain (the sum below only adds the same terms in another order)
        segs = ((head,) if head else ()) + fp.segs + last
        f = FamilyPath(fp.family, fp.word, segs, (a.x_m, a.y_m, a.yaw_rad))
        if turning_rad(f) <= max_turn_rad:
            out.append(f)
    out.sort(key=lambda f: f.length_m)
    return out


def cc_candidate(a: BoundaryState, b: BoundaryState, lim: "TimedLimits", v_cap_m_s: float,
                 spacing_m: float = 0.05, run_in: bool = True, max_turn_rad: float = math.inf) -> GeoPath | None:
    """The shortest continuous-curvature path from ``a`` to ``b`` the servo follows up to ``v_cap_m_s``
    (``max_turn_rad``: of those that turn at most that much in all)."""
    fams = cc_family(a, b, lim, v_cap_m_s, run_in, max_turn_rad)
    if not fams:
        return None
    return geo_from_family(fams[0], lim, v_cap_m_s, spacing_m)


def dubins_candidate(a: BoundaryState, b: BoundaryState, lim: "TimedLimits", min_piece_m: float) -> GeoPath | None:
    """The shortest Dubins path whose pieces between stops are all at least ``min_piece_m`` long (the car
    stops at every curvature jump to turn its wheels; a shorter piece is a move it cannot make)."""
    for fp in sorted(dubins_paths((a.x_m, a.y_m, a.yaw_rad), (b.x_m, b.y_m, b.yaw_rad), _kmax(lim)),
                     key=lambda f: f.length_m):
        if all(g.length_m >= min_piece_m for g in fp.segs if g.length_m > 1e-12):
            return geo_from_family(fp, lim, math.inf, stop_at_jumps=True)
    return None


def reeds_shepp_candidates(a: BoundaryState, b: BoundaryState, lim: "TimedLimits", min_piece_m: float,
                           n: int = 4) -> list[GeoPath]:
    """Up to ``n`` shortest Reeds-Shepp paths (forward and reverse; forward-only Dubins paths driven either
    way round too) whose pieces between stops are all at least ``min_piece_m`` long."""
    s0, g0 = (a.x_m, a.y_m, a.yaw_rad), (b.x_m, b.y_m, b.yaw_rad)
    kmax = _kmax(lim)
    fams = reeds_shepp_paths(s0, g0, kmax)
    for fp in dubins_paths(g0, s0, kmax):  # backwards from the goal, then driven in reverse from the start
        segs = tuple(Seg(g.length_m, g.k1, -g.sigma, -g.direction) for g in reversed(fp.segs))
        fams.append(FamilyPath("reeds-shepp", word_of(segs), segs, s0))
    out = []
    for fp in sorted(fams, key=lambda f: f.length_m):
        if all(g.length_m >= min_piece_m for g in fp.segs if g.length_m > 1e-12):
            out.append(geo_from_family(fp, lim, math.inf, stop_at_jumps=True))
            if len(out) >= n:
                break
    return out


def via_candidate(states: list[BoundaryState], lim: "TimedLimits", v_cap_m_s: float,
                  reject_prefix: Callable[[GeoPath], bool] | None = None) -> GeoPath | None:
    """A path through every state: the polynomial through all of them when it fits, else per leg the
    polynomial when it fits, else the shortest continuous-curvature leg; None when a leg has neither.

    The first leg's polynomial is built first (legs are cached, :func:`~._path.build_path`): when it does not
    fit, neither does the polynomial through all the states (its samples are among theirs), and the legs after
    it are built only when the first has a continuous-curvature path (a leg with neither ends the work).
    ``reject_prefix``: None is returned as soon as it says True of the first leg (a path that begins so is
    of no use to the caller: a deviation whose first leg runs into a static return)."""
    n_legs = len(states) - 1
    first, _ = poly_candidate(states[:2], lim, quick=True)
    if first is not None and reject_prefix is not None and reject_prefix(first):
        return None
    if first is not None:
        whole, _ = poly_candidate(states, lim) if n_legs > 1 else (first, "")
        if whole is not None:
            return whole
    xs: list[FloatArray] = []
    yaws: list[FloatArray] = []
    ks: list[FloatArray] = []
    ss: list[FloatArray] = []
    forms: list[str] = []
    knots, kinds = [0.0], []
    cap = math.inf
    s_off = 0.0
    for i, (a, b) in enumerate(zip(states[:-1], states[1:])):
        leg = first if i == 0 else poly_candidate([a, b], lim, quick=True)[0]
        # else continuous curvature, sharper (slower) clothoids where the gentle ones do not fit; the
        # straight run-in only into the goal
        for leg_cap in (v_cap_m_s,) + tuple(c for c in VIA_LEG_CAPS_M_S if lim.v_min_m_s < c < v_cap_m_s):
            if leg is not None:
                break
            leg = cc_candidate(a, b, lim, leg_cap, run_in=i == n_legs - 1, max_turn_rad=NO_LOOP_TURN_RAD)
        if leg is None:
            return None
        if i == 0 and first is None and reject_prefix is not None and reject_prefix(leg):
            return None
        kinds.append(leg.kind.split(" ")[0])
        cap = min(cap, leg.speed_cap_m_s)
        sl = slice(1, None) if xs else slice(None)
        xs.append(leg.xy[sl])
        yaws.append(leg.yaw[sl])
        ks.append(leg.kappa[sl])
        ss.append(leg.s[sl] + s_off)
        s_off += leg.length_m
        knots.append(s_off)
        forms.extend(leg.forms)  # the polynomial legs' forms
    h = np.concatenate(yaws)
    yaw = np.concatenate(([h[0]], h[0] + np.cumsum(norm_angle_rad(np.diff(h)))))
    kind = " + ".join(dict.fromkeys(kinds))
    return GeoPath(np.concatenate(xs), yaw, np.concatenate(ks), np.concatenate(ss), tuple(forms), tuple(knots), kind,
                   None, (), cap)
