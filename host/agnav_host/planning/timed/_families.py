"""Path families that reach every pose a car-like robot can reach within its steering limit.

* **Dubins** (forward only): two arcs of the minimum radius joined by a straight (CSC) or a third arc
  (CCC), six words, closed form. The curvature jumps at every joint, so a car follows one exactly only
  by stopping there and turning its wheels at rest.
* **Continuous curvature** (forward only): the same words with every arc replaced by a *CC turn*: a
  clothoid from straight to the curvature limit (sharpness sigma), the arc, and the mirror clothoid back
  (Fraichard and Scheuer's CC-Dubins). A turn too small for the two clothoids at full curvature is two
  clothoids meeting at a lower peak. sigma follows from the steering rate the servo may use at the
  plan's top speed, so the servo follows the path at speed.
* **Reeds-Shepp** (forward and reverse, when the robot has a reverse side): the CSC and CCC words with
  any direction per segment and the C|C|C and CC|C / C|CC cusp words, each with the stops at its cusps.

Every path here is a list of :class:`Seg` (length, curvature at its start, sharpness, direction) from a
start pose. Curvatures are steering curvatures, tan(phi) / wheelbase, + = left; reversing along a
segment of curvature k turns the heading by -k per metre travelled. All angles in rad, lengths in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np
from scipy.special import fresnel

from ...types import FloatArray

__all__ = ["Seg", "FamilyPath", "dubins_paths", "cc_paths", "reeds_shepp_paths", "sample_segments", "seg_end",
           "shortest_dubins_m", "turning_rad", "word_of"]

TWO_PI = 2.0 * math.pi
_GL = ((0.5 - 0.5 * math.sqrt(0.6), 5.0 / 18.0), (0.5, 8.0 / 18.0), (0.5 + 0.5 * math.sqrt(0.6), 5.0 / 18.0))


@dataclass(frozen=True)
class Seg:
    """A piece of path: ``length_m`` travelled, steering curvature ``k0`` at its start (1/m), sharpness
    ``sigma`` (dk/ds, 1/m^2, 0 on lines and arcs) and ``direction`` (+1 forward, -1 reverse)."""

    length_m: float
    k0: float
    sigma: float = 0.0
    direction: int = 1

    @property
    def k1(self) -> float:
        return self.k0 + self.sigma * self.length_m


@dataclass(frozen=True)
class FamilyPath:
    """One path of a family: ``family`` ("dubins", "clothoid", "reeds-shepp"), its ``word`` (e.g. "LSR",
    "L+R-L+"), the segments from ``start`` (x, y, yaw)."""

    family: str
    word: str
    segs: tuple[Seg, ...]
    start: tuple[float, float, float]

    @property
    def length_m(self) -> float:
        return sum(s.length_m for s in self.segs)

    @property
    def reverse_m(self) -> float:
        return sum(s.length_m for s in self.segs if s.direction < 0)


def _mod2pi(a: float) -> float:
    r = math.fmod(a, TWO_PI)
    return r + TWO_PI if r < 0.0 else r


def seg_end(x: float, y: float, th: float, seg: Seg, n: int = 8) -> tuple[float, float, float]:
    """Pose after ``seg`` from (x, y, th): exact for lines and arcs, Gauss-Legendre (n x 3 nodes) on a clothoid."""
    d, L, k0, sg = seg.direction, seg.length_m, seg.k0, seg.sigma
    if L <= 0.0:
        return x, y, th
    if sg == 0.0:
        if abs(k0) < 1e-12:
            return x + d * L * math.cos(th), y + d * L * math.sin(th), th
        th1 = th + d * k0 * L
        return x + (math.sin(th1) - math.sin(th)) / k0, y - (math.cos(th1) - math.cos(th)) / k0, th1
    h = L / n
    sx = sy = 0.0
    for i in range(n):
        for a, w in _GL:
            u = (i + a) * h
            t = th + d * (k0 * u + 0.5 * sg * u * u)
            sx += w * math.cos(t)
            sy += w * math.sin(t)
    return x + d * h * sx, y + d * h * sy, th + d * (k0 * L + 0.5 * sg * L * L)


def sample_segments(start: tuple[float, float, float], segs: tuple[Seg, ...] | list[Seg],
                    spacing_m: float = 0.05) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """(xy (n, 2), yaw (n,), kappa (n,), s (n,) travelled, direction (n,)) along ``segs`` from ``start``;
    every segment end is a sample. Lines and arcs are exact; on clothoids the positions come from 3-point
    Gauss-Legendre over each interval (to ~1e-12 m at 5 cm spacing)."""
    x0, y0, th0 = start
    segs = [s for s in segs if s.length_m > 1e-12]
    if not segs:
        return np.array([[x0, y0]]), np.array([th0]), np.zeros(1), np.zeros(1), np.ones(1)
    m = len(segs)
    par = np.empty((m, 5))  # length, k0, sigma, direction, heading at the start
    t = th0
    for i, g in enumerate(segs):
        par[i] = (g.length_m, g.k0, g.sigma, g.direction, t)
        t += g.direction * (g.k0 * g.length_m + 0.5 * g.sigma * g.length_m ** 2)
    n = np.maximum(np.ceil(par[:, 0] / spacing_m), 1).astype(np.intp)
    idx = np.repeat(np.arange(m), n)  # segment of each interval
    first = np.cumsum(n) - n
    j = np.arange(len(idx)) - first[idx]
    L, k0, sg, d, th_s = (par[idx, c] for c in range(5))
    h = L / n[idx]
    ua = j * h
    ub = ua + h
    th_a = th_s + d * (k0 * ua + 0.5 * sg * ua * ua)
    th_b = th_s + d * (k0 * ub + 0.5 * sg * ub * ub)
    # exact chords where the curvature is constant, Gauss-Legendre on clothoids
    dx = np.empty(len(idx))
    dy = np.empty(len(idx))
    line = (sg == 0.0) & (np.abs(k0) < 1e-12)
    arc = (sg == 0.0) & ~line
    clo = sg != 0.0
    dx[line] = d[line] * h[line] * np.cos(th_a[line])
    dy[line] = d[line] * h[line] * np.sin(th_a[line])
    ka = k0[arc]
    dx[arc] = (np.sin(th_b[arc]) - np.sin(th_a[arc])) / ka
    dy[arc] = -(np.cos(th_b[arc]) - np.cos(th_a[arc])) / ka
    if clo.any():
        hc, uc, k0c, sgc, dc, tsc = h[clo], ua[clo], k0[clo], sg[clo], d[clo], th_s[clo]
        ax = np.zeros(len(hc))
        ay = np.zeros(len(hc))
        for a, w in _GL:
            u = uc + a * hc
            th = tsc + dc * (k0c * u + 0.5 * sgc * u * u)
            ax += w * np.cos(th)
            ay += w * np.sin(th)
        dx[clo] = dc * hc * ax
        dy[clo] = dc * hc * ay
    xs = np.empty(len(idx) + 1)
    ys = np.empty(len(idx) + 1)
    xs[0], ys[0] = x0, y0
    np.cumsum(dx, out=xs[1:])
    np.cumsum(dy, out=ys[1:])
    xs[1:] += x0
    ys[1:] += y0
    yaw = np.concatenate(([th0], th_b))
    kappa = np.concatenate(([segs[0].k0], k0 + sg * ub))
    s = np.concatenate(([0.0], np.cumsum(h)))
    direction = np.concatenate(([d[0]], d))
    return np.column_stack((xs, ys)), yaw, kappa, s, direction


# ---- CC turns --------------------------------------------------------------------------------------------


@lru_cache(maxsize=64)
def _turn_consts(kmax: float, sigma: float) -> tuple[float, float, float, float, float, float]:
    """(x_i, y_i, theta_i) of the clothoid from 0 to kmax, the outer-circle centre (x_O, y_O) of a left
    CC turn in its start frame, and delta_min (the smallest deflection at full curvature)."""
    if math.isinf(sigma):
        return 0.0, 0.0, 0.0, 0.0, 1.0 / kmax, 0.0
    lc = kmax / sigma
    a = math.sqrt(math.pi / sigma)
    S, C = fresnel(lc / a)
    xi, yi, thi = a * float(C), a * float(S), 0.5 * kmax * lc
    return xi, yi, thi, xi - math.sin(thi) / kmax, yi + math.cos(thi) / kmax, 2.0 * thi


def _turn_end(delta: float, kmax: float, sigma: float) -> tuple[float, float]:
    """End point of a left CC turn of deflection ``delta`` (>= 0) in its start frame (a right turn: (x, -y))."""
    if delta <= 0.0:
        return 0.0, 0.0
    xi, yi, _, xo, yo, dmin = _turn_consts(kmax, sigma)
    h = 0.5 * delta
    if delta >= dmin:
        mx, my = xo + math.sin(h) / kmax, yo - math.cos(h) / kmax
    else:  # two clothoids meeting at sqrt(sigma * delta)
        a = math.sqrt(math.pi / sigma)
        S, C = fresnel(math.sqrt(delta / math.pi))
        mx, my = a * float(C), a * float(S)
    c, s = math.cos(h), math.sin(h)
    m = 2.0 * (mx * c + my * s)
    return m * c, m * s


def _turn_segs(delta: float, side: int, kmax: float, sigma: float, direction: int = 1) -> list[Seg]:
    """Segments of a CC turn (``side`` +1 left, -1 right); an arc when sigma is inf."""
    if delta <= 1e-12:
        return []
    k = side * kmax
    if math.isinf(sigma):
        return [Seg(delta / kmax, k, 0.0, direction)]
    dmin = kmax * kmax / sigma
    if delta >= dmin:
        lc = kmax / sigma
        out = [Seg(lc, 0.0, side * sigma, direction)]
        if delta - dmin > 1e-12:
            out.append(Seg((delta - dmin) / kmax, k, 0.0, direction))
        out.append(Seg(lc, k, -side * sigma, direction))
        return out
    kp = math.sqrt(sigma * delta)
    lc = kp / sigma
    return [Seg(lc, 0.0, side * sigma, direction), Seg(lc, side * kp, -side * sigma, direction)]


def _rot(x: float, y: float, a: float) -> tuple[float, float]:
    c, s = math.cos(a), math.sin(a)
    return c * x - s * y, s * x + c * y


# ---- CSC and CCC words ------------------------------------------------------------------------------------


@lru_cache(maxsize=64)
def _csc_consts(kmax: float, sigma: float) -> tuple[float, float, float, float, float]:
    """(x_O, y_O, 2 R sin mu, 4 R^2 cos^2 mu, 2 R cos mu) of the outer circles (radius R, angle mu) for
    :func:`_csc_closed`, computed as it would."""
    _, _, _, xo, yo, _ = _turn_consts(kmax, sigma)
    R = math.hypot(xo, yo)
    mu = math.atan2(xo, yo)
    return xo, yo, 2.0 * R * math.sin(mu), 4.0 * R * R * math.cos(mu) ** 2, 2.0 * R * math.cos(mu)


def _csc_closed(word: str, gx: float, gy: float, gth: float, kmax: float, sigma: float) -> tuple[float, float, float] | None:
    """(delta1, straight, delta2) of a CSC word from the outer circles (exact when both turns reach full
    curvature, and for Dubins); start at the origin heading 0."""
    xo, yo, r_sin2, r2_cos4, r_cos2 = _csc_consts(kmax, sigma)
    a, b = (1 if word[0] == "L" else -1), (1 if word[2] == "L" else -1)
    osx, osy = xo, a * yo
    ogx, ogy = _rot(-xo, b * yo, gth)
    ogx += gx
    ogy += gy
    dx, dy = ogx - osx, ogy - osy
    D = math.hypot(dx, dy)
    thc = math.atan2(dy, dx)
    if a == b:
        ell = D - r_sin2
        th = thc
    else:
        q = D * D - r2_cos4
        if q < 0.0:
            return None
        ell = math.sqrt(q) - r_sin2
        th = thc + a * math.atan2(r_cos2, ell + r_sin2)
    if ell < -1e-9:
        return None
    return _mod2pi(a * th), max(ell, 0.0), _mod2pi(b * (gth - th))


def _csc_residual(d1: float, a: int, b: int, gx: float, gy: float, gth: float, kmax: float, sigma: float) -> tuple[float, float, float]:
    """(cross, straight, delta2) for a CSC word with first deflection d1 (the root of cross is the path)."""
    return _csc_residual_fn(a, b, gx, gy, gth, kmax, sigma)(d1)


def _csc_residual_fn(a: int, b: int, gx: float, gy: float, gth: float, kmax: float,
                     sigma: float) -> Callable[[float], tuple[float, float, float]]:
    """:func:`_csc_residual` as a function of d1 alone, with the turn constants looked up once and
    :func:`_turn_end` and :func:`_rot` written out (the same arithmetic: a Newton solve calls it dozens of times)."""
    _, _, _, xo, yo, dmin = _turn_consts(kmax, sigma)
    fa = math.sqrt(math.pi / sigma) if not math.isinf(sigma) else 0.0
    sin, cos, sqrt, fmod, pi = math.sin, math.cos, math.sqrt, math.fmod, math.pi

    def turn_end(delta: float) -> tuple[float, float]:
        if delta <= 0.0:
            return 0.0, 0.0
        h = 0.5 * delta
        if delta >= dmin:
            mx, my = xo + sin(h) / kmax, yo - cos(h) / kmax
        else:  # two clothoids meeting at sqrt(sigma * delta)
            S, C = fresnel(sqrt(delta / pi))
            mx, my = fa * float(C), fa * float(S)
        c, s = cos(h), sin(h)
        m = 2.0 * (mx * c + my * s)
        return m * c, m * s

    def resid(d1: float) -> tuple[float, float, float]:
        h1 = a * d1
        ex, ey = turn_end(d1)
        r = fmod(b * (gth - h1), TWO_PI)
        d2 = r + TWO_PI if r < 0.0 else r
        fx, fy = turn_end(d2)
        fy = b * fy
        c, s = cos(h1), sin(h1)
        fx, fy = c * fx - s * fy, s * fx + c * fy
        rx, ry = gx - ex - fx, gy - a * ey - fy
        return c * ry - s * rx, c * rx + s * ry, d2

    return resid


#: Newton steps in a row that do not halve the residual before a guess is given up (:func:`_csc_numeric`)
NEWTON_STALL_STEPS = 2


def _csc_numeric(word: str, gx: float, gy: float, gth: float, kmax: float, sigma: float,
                 guesses: tuple[float, ...]) -> tuple[float, float, float] | None:
    """Newton on the first deflection of a CSC word from each guess in turn (16 steps at most, each at most
    0.5 rad, d1 kept in [0, 2 pi)); the first root with a straight of length >= 0, else None.

    A guess is given up early when its steps stop converging: a step that leaves d1 where it is (held at a
    bound; it would repeat itself to the end), or :data:`NEWTON_STALL_STEPS` steps in a row that do not halve
    the residual (Newton bouncing round a minimum of |cross| above 0, where the word has no root: the
    roots it finds it reaches halving the residual at every step, measured on the benchmark's solves)."""
    a, b = (1 if word[0] == "L" else -1), (1 if word[2] == "L" else -1)
    resid = _csc_residual_fn(a, b, gx, gy, gth, kmax, sigma)
    eps = 1e-7
    top = TWO_PI - 1e-9
    for g in guesses:
        d1 = min(max(g, 0.0), top)
        at_d1 = None  # the residual at the current d1 when known
        best = math.inf
        stall = 0
        for _ in range(16):
            res = resid(d1)
            at_d1 = res
            f = res[0]
            if abs(f) < 1e-10:
                break
            if abs(f) < 0.5 * best:
                best, stall = abs(f), 0
            else:
                stall += 1
                if stall >= NEWTON_STALL_STEPS:
                    break
            f2 = resid(d1 + eps)[0]
            df = (f2 - f) / eps
            if df == 0.0 or not math.isfinite(df):
                break
            step = max(-0.5, min(0.5, f / df))
            nd = min(max(d1 - step, 0.0), top)
            if nd == d1:
                break
            d1 = nd
            at_d1 = None
        f, ell, d2 = resid(d1) if at_d1 is None else at_d1
        if abs(f) < 1e-8 and ell >= -1e-9:
            return d1, max(ell, 0.0), d2
    return None


def _ccc_dubins(word: str, gx: float, gy: float, gth: float, R: float) -> list[tuple[float, float, float]]:
    """(delta1, delta2, delta3) of the Dubins CCC word (LRL or RLR) of radius R; start at the origin, heading 0."""
    a = 1 if word[0] == "L" else -1
    osx, osy = 0.0, a * R
    ogx, ogy = gx - a * R * math.sin(gth), gy + a * R * math.cos(gth)
    dx, dy = ogx - osx, ogy - osy
    D = math.hypot(dx, dy)
    if D > 4.0 * R or D < 1e-12:
        return []
    thc = math.atan2(dy, dx)
    out = []
    al_s = -a * 0.5 * math.pi  # start point's angle on its circle
    al_g = gth - a * 0.5 * math.pi
    for sgn in (1.0, -1.0):
        phi = thc + sgn * math.acos(D / (4.0 * R))
        mx, my = osx + 2.0 * R * math.cos(phi), osy + 2.0 * R * math.sin(phi)
        b1 = phi
        b2 = math.atan2(ogy - my, ogx - mx)
        d1 = _mod2pi(a * (b1 - al_s))
        d2 = _mod2pi(-a * (b2 - (b1 + math.pi)))
        d3 = _mod2pi(a * (al_g - (b2 + math.pi)))
        out.append((d1, d2, d3))
    return out


def _ccc_pos(d1: float, d2: float, a: int, gth: float, kmax: float, sigma: float) -> tuple[float, float, float]:
    e1x, e1y = _turn_end(d1, kmax, sigma)
    e2x, e2y = _turn_end(d2, kmax, sigma)
    h1 = a * d1
    d3 = _mod2pi(a * (gth - h1 + a * d2))
    e3x, e3y = _turn_end(d3, kmax, sigma)
    px, py = e1x, a * e1y
    qx, qy = _rot(e2x, -a * e2y, h1)
    rx, ry = _rot(e3x, a * e3y, h1 - a * d2)
    return px + qx + rx, py + qy + ry, d3


def _ccc_cc(word: str, gx: float, gy: float, gth: float, kmax: float, sigma: float) -> list[tuple[float, float, float]]:
    """CC version of a CCC word by Newton from the Dubins solution on the outer circles."""
    _, _, _, xo, yo, _ = _turn_consts(kmax, sigma)
    a = 1 if word[0] == "L" else -1
    out = []
    for g in _ccc_dubins(word, gx, gy, gth, math.hypot(xo, yo)):
        d1, d2 = g[0], g[1]
        ok = False
        for _ in range(20):
            px, py, d3 = _ccc_pos(d1, d2, a, gth, kmax, sigma)
            rx, ry = gx - px, gy - py
            if rx * rx + ry * ry < 1e-20:
                ok = True
                break
            eps = 1e-7
            p1x, p1y, _ = _ccc_pos(d1 + eps, d2, a, gth, kmax, sigma)
            p2x, p2y, _ = _ccc_pos(d1, d2 + eps, a, gth, kmax, sigma)
            j11, j21 = (p1x - px) / eps, (p1y - py) / eps
            j12, j22 = (p2x - px) / eps, (p2y - py) / eps
            det = j11 * j22 - j12 * j21
            if abs(det) < 1e-12:
                break
            s1 = (j22 * rx - j12 * ry) / det
            s2 = (-j21 * rx + j11 * ry) / det
            m = max(abs(s1), abs(s2))
            if m > 0.5:
                s1, s2 = s1 * 0.5 / m, s2 * 0.5 / m
            d1 = min(max(d1 + s1, 0.0), TWO_PI)
            d2 = min(max(d2 + s2, 0.0), TWO_PI)
        if ok:
            out.append((d1, d2, d3))
    return out


def _to_frame(start: tuple[float, float, float], goal: tuple[float, float, float]) -> tuple[float, float, float]:
    dx, dy = goal[0] - start[0], goal[1] - start[1]
    c, s = math.cos(start[2]), math.sin(start[2])
    return c * dx + s * dy, -s * dx + c * dy, goal[2] - start[2]


def _words(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float, sigma: float,
           family: str, words: tuple[str, ...] = ("LSL", "RSR", "LSR", "RSL", "LRL", "RLR")) -> list[FamilyPath]:
    """The paths of ``words`` (Dubins when sigma is inf, else continuous curvature)."""
    gx, gy, gth = _to_frame(start, goal)
    out: list[FamilyPath] = []
    cc = not math.isinf(sigma)
    dmin = _turn_consts(kmax, sigma)[5]
    for w in ("LSL", "RSR", "LSR", "RSL"):
        if w not in words:
            continue
        sol = _csc_closed(w, gx, gy, gth, kmax, sigma)
        if cc and (sol is None or min(sol[0], sol[2]) < dmin - 1e-12):
            guesses = (sol[0],) if sol is not None else ()
            sol = _csc_numeric(w, gx, gy, gth, kmax, sigma, guesses + (1e-3, math.pi))
        if sol is None:
            continue
        d1, ell, d2 = sol
        a, b = (1 if w[0] == "L" else -1), (1 if w[2] == "L" else -1)
        segs = _turn_segs(d1, a, kmax, sigma) + ([Seg(ell, 0.0)] if ell > 1e-12 else []) + _turn_segs(d2, b, kmax, sigma)
        out.append(FamilyPath(family, w, tuple(segs), start))
    for w in ("LRL", "RLR"):
        if w not in words:
            continue
        a = 1 if w[0] == "L" else -1
        sols = _ccc_cc(w, gx, gy, gth, kmax, sigma) if cc else _ccc_dubins(w, gx, gy, gth, 1.0 / kmax)
        for d1, d2, d3 in sols:
            segs = _turn_segs(d1, a, kmax, sigma) + _turn_segs(d2, -a, kmax, sigma) + _turn_segs(d3, a, kmax, sigma)
            out.append(FamilyPath(family, w, tuple(segs), start))
    return out


def dubins_paths(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float) -> list[FamilyPath]:
    """Every Dubins path (CSC and CCC words) from ``start`` to ``goal`` (x, y, yaw) at curvature <= kmax."""
    return _words(start, goal, kmax, math.inf, "dubins")


def shortest_dubins_m(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float) -> float:
    """Length of the shortest forward path at curvature <= kmax: no car-like path is shorter."""
    return min(p.length_m for p in dubins_paths(start, goal, kmax))


ALL_WORDS = ("LSL", "RSR", "LSR", "RSL", "LRL", "RLR")
CSC_WORDS = ALL_WORDS[:4]


def cc_paths(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float, sigma: float,
             prune_m: float | None = None, words: tuple[str, ...] = ALL_WORDS, max_turn_rad: float = math.inf,
             turn_extra_rad: float = 0.0) -> list[FamilyPath]:
    """Every continuous-curvature path (CC turns of sharpness ``sigma``, curvature <= kmax, straight at both
    ends) of the CSC and CCC words from ``start`` to ``goal``. ``prune_m``: only the words whose Dubins
    path is within that of the shortest (a CC path runs a little outside its Dubins path, so the shortest
    CC path is one of them); all ``words`` when none of those has a CC path.

    ``max_turn_rad``: the caller keeps only paths that turn at most this much in all, ``turn_extra_rad`` of it
    being turned before and after these paths (the clothoids that wind a steering angle out and in). An LSL
    path turns mod2pi(goal heading - start heading) or 2 pi more, an RSR path mod2pi(start - goal) or more,
    so where that alone is too much the word is not solved for a path, only (when that decides whether
    the other words are tried) for whether it has one: the answer is the same, the work is not."""
    loops = _looping_words(goal[2] - start[2], words, max_turn_rad - turn_extra_rad)
    if prune_m is not None:
        dub = _dubins_lengths(start, goal, kmax, words)
        if dub:
            best = min(length for _, length in dub)
            keep = tuple(dict.fromkeys(w for w, length in dub if length <= best + prune_m))
            out = _words(start, goal, kmax, sigma, "clothoid", tuple(w for w in keep if w not in loops))
            if out or any(_csc_exists(w, start, goal, kmax, sigma) for w in keep if w in loops):
                return out
    return _words(start, goal, kmax, sigma, "clothoid", tuple(w for w in words if w not in loops))


def _looping_words(gth: float, words: tuple[str, ...], max_turn_rad: float) -> tuple[str, ...]:
    """The LSL / RSR among ``words`` whose every path turns more than ``max_turn_rad`` (heading change ``gth``):
    the two turns of LSL add up to mod2pi(gth) or that plus 2 pi, those of RSR to mod2pi(-gth) or more."""
    if math.isinf(max_turn_rad):
        return ()
    out = []
    if "LSL" in words and _mod2pi(gth) > max_turn_rad + 1e-9:
        out.append("LSL")
    if "RSR" in words and _mod2pi(-gth) > max_turn_rad + 1e-9:
        out.append("RSR")
    return tuple(out)


def _csc_exists(word: str, start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float,
                sigma: float) -> bool:
    """Whether :func:`_words` finds a path of the CSC ``word`` (the same closed form, then the same Newton)."""
    gx, gy, gth = _to_frame(start, goal)
    sol = _csc_closed(word, gx, gy, gth, kmax, sigma)
    if not math.isinf(sigma) and (sol is None or min(sol[0], sol[2]) < _turn_consts(kmax, sigma)[5] - 1e-12):
        guesses = (sol[0],) if sol is not None else ()
        sol = _csc_numeric(word, gx, gy, gth, kmax, sigma, guesses + (1e-3, math.pi))
    return sol is not None


def _dubins_lengths(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float,
                    words: tuple[str, ...]) -> list[tuple[str, float]]:
    """(word, length) of every Dubins path of ``words``, in the order of :func:`dubins_paths`, with the
    lengths summed as :attr:`FamilyPath.length_m` sums its segments, without building them."""
    gx, gy, gth = _to_frame(start, goal)
    out: list[tuple[str, float]] = []
    for w in ("LSL", "RSR", "LSR", "RSL"):
        if w not in words:
            continue
        sol = _csc_closed(w, gx, gy, gth, kmax, math.inf)
        if sol is None:
            continue
        d1, ell, d2 = sol
        out.append((w, sum([L for L in (d1 / kmax if d1 > 1e-12 else None, ell if ell > 1e-12 else None,
                                        d2 / kmax if d2 > 1e-12 else None) if L is not None])))
    for w in ("LRL", "RLR"):
        if w not in words:
            continue
        for ds in _ccc_dubins(w, gx, gy, gth, 1.0 / kmax):
            out.append((w, sum([d / kmax for d in ds if d > 1e-12])))
    return out


def turning_rad(fp: FamilyPath) -> float:
    """Total absolute heading change along a path, rad (a full loop adds 2 pi)."""
    return sum(abs(0.5 * (g.k0 + g.k1)) * g.length_m if g.sigma == 0.0 or g.k0 * g.k1 >= 0.0
               else (g.k0 * g.k0 + g.k1 * g.k1) / (2.0 * abs(g.sigma)) for g in fp.segs)


# ---- Reeds-Shepp --------------------------------------------------------------------------------------------


def _rs_words(x: float, y: float, phi: float, R: float) -> list[tuple[str, tuple[float, ...]]]:
    """Reeds-Shepp words in the unit-radius frame (x, y scaled by 1 / R), as (letters, signed lengths in
    radians or unit lengths); the CSC, CCC (C|C|C, C|CC, CC|C) families with their time-flip and reflection."""
    out: list[tuple[str, tuple[float, ...]]] = []

    def polar(a: float, b: float) -> tuple[float, float]:
        return math.hypot(a, b), math.atan2(b, a)

    def wrap(a: float) -> float:
        return (a + math.pi) % TWO_PI - math.pi

    def lsl(x: float, y: float, p: float) -> tuple[float, ...] | None:
        u, t = polar(x - math.sin(p), y - 1.0 + math.cos(p))
        v = wrap(p - t)
        return (t, u, v) if t >= -1e-9 and v >= -1e-9 else None

    def lsr(x: float, y: float, p: float) -> tuple[float, ...] | None:
        u1, t1 = polar(x + math.sin(p), y - 1.0 - math.cos(p))
        if u1 * u1 < 4.0:
            return None
        u = math.sqrt(u1 * u1 - 4.0)
        th = math.atan2(2.0, u)
        t = wrap(t1 + th)
        v = wrap(t - p)
        return (t, u, v) if t >= -1e-9 and v >= -1e-9 else None

    def lrl(x: float, y: float, p: float) -> tuple[float, ...] | None:  # L+ R- L (C|C|C and C|CC)
        u1, t1 = polar(x - math.sin(p), y - 1.0 + math.cos(p))
        if u1 > 4.0:
            return None
        u = -2.0 * math.asin(0.25 * u1)
        t = wrap(t1 + 0.5 * u + math.pi)
        v = wrap(p - t + u)
        return (t, u, v) if t >= -1e-9 and u <= 1e-9 else None

    def lrl_back(x: float, y: float, p: float) -> tuple[float, ...] | None:  # the same driven backwards: CC|C
        xb, yb = x * math.cos(p) + y * math.sin(p), x * math.sin(p) - y * math.cos(p)
        r = lrl(xb, yb, p)
        return None if r is None else (r[2], r[1], r[0])

    bases = (("LSL", lsl, "LSL"), ("LSR", lsr, "LSR"), ("LRL", lrl, "LRL"), ("LRLb", lrl_back, "LRL"))
    for _, fn, letters in bases:
        for flip, refl in ((False, False), (True, False), (False, True), (True, True)):
            xx, yy, pp = (-x if flip else x), (-y if refl else y), phi
            if flip != refl:
                pp = -phi
            r = fn(xx, yy, pp)
            if r is None:
                continue
            vals = tuple(-v if flip else v for v in r)
            lets = letters if not refl else letters.translate(str.maketrans("LR", "RL"))
            out.append((lets, vals))
    return out


def word_of(segs: tuple[Seg, ...] | list[Seg]) -> str:
    """Reeds-Shepp style name of arcs and lines: L, R, S with + forward, - reverse (clothoids are not named)."""
    return "".join(f"{'S' if g.k0 == 0 else ('L' if g.k0 > 0 else 'R')}{'+' if g.direction > 0 else '-'}"
                   for g in segs if g.sigma == 0.0 and g.length_m > 1e-12)


def reeds_shepp_paths(start: tuple[float, float, float], goal: tuple[float, float, float], kmax: float) -> list[FamilyPath]:
    """Reeds-Shepp paths (forward and reverse, arcs of curvature kmax and straights) from ``start`` to
    ``goal``: the CSC and CCC words with every direction pattern; each is checked by integrating it."""
    R = 1.0 / kmax
    gx, gy, gth = _to_frame(start, goal)
    out: list[FamilyPath] = []
    for letters, vals in _rs_words(gx / R, gy / R, gth, R):
        segs = []
        for ch, v in zip(letters, vals):
            if abs(v) < 1e-10:
                continue
            d = 1 if v > 0 else -1
            if ch == "S":
                segs.append(Seg(abs(v) * R, 0.0, 0.0, d))
            else:
                segs.append(Seg(abs(v) * R, kmax if ch == "L" else -kmax, 0.0, d))
        x, y, th = 0.0, 0.0, 0.0
        for s in segs:
            x, y, th = seg_end(x, y, th, s)
        if math.hypot(x - gx, y - gy) > 1e-6 or abs((th - gth + math.pi) % TWO_PI - math.pi) > 1e-6:
            continue  # a formula branch that does not close (kept out rather than trusted)
        out.append(FamilyPath("reeds-shepp", word_of(segs), tuple(segs), start))
    return out
