"""Geometric path through boundary states, built from the ref-003 polynomials.

AgNav separates *where* (this module) from *when* (:mod:`._profile`). Each leg between two states is
the ref-003 pair x(u) cubic / y(u) quintic over a normalised parameter u in [0, 1], written in the
frame of the leg's chord, with the tangent length ``lam`` playing the role of the speed in 003's
boundary conditions. The geometry of a polynomial trajectory depends only on these tangent lengths,
so AgNav tries a few and keeps the one with the smallest peak curvature (the smallest steering
angle). The time law that the car can really drive (speed 0 or in the calibrated band, acceleration
limited) is then laid along the arc length. That is the "or better" over driving the polynomials in
time directly: 003's x(t), y(t) start and stop at rest, so their speed passes through the dead band
the RC car cannot drive (below 43.5 cm/s) at both ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ...types import FloatArray, norm_angle_rad
from ._poly import BoundaryState

__all__ = ["GeoPath", "build_path", "LAMBDA_SCALES"]


_interp_real: Any = None
try:  # np.interp's compiled core (numpy >= 2): np.interp only checks for complex values around it (these are real)
    from numpy._core.multiarray import interp as _interp_real
except ImportError:  # pragma: no cover - numpy 1.x: np.interp itself
    pass


def _interp(x: npt.NDArray[Any], xp: FloatArray, fp: FloatArray) -> FloatArray:
    """np.interp(x, xp, fp) for real ``fp`` (the same function, without its Python-level checks)."""
    if _interp_real is None:  # pragma: no cover
        return np.asarray(np.interp(x, xp, fp))
    out: FloatArray = _interp_real(x, xp, fp, None, None)
    return out


def _clip(x: npt.NDArray[Any], lo: float, hi: float) -> npt.NDArray[Any]:
    """np.clip(x, lo, hi) (the same values: the maximum taken with ``lo`` first, as np.clip does for -0.0)
    without np.clip's Python-level dispatch (several times its two ufunc calls on short arrays)."""
    out: npt.NDArray[Any] = np.minimum(np.maximum(lo, x), hi)
    return out

#: tangent lengths tried per leg, as multiples of the chord length
LAMBDA_SCALES = (1.0, 0.75, 1.35, 1.8)
_MAX_REL_003_RAD = math.radians(60.0)  # chord-frame end headings beyond this use the quintic pair


@dataclass(frozen=True)
class GeoPath:
    """A sampled planar path. ``xy`` (n, 2) m, ``yaw`` (n,) rad (unwrapped, so interpolation is
    safe), ``kappa`` (n,) 1/m (+ = left), ``s`` (n,) arc length from the start, m. ``forms`` names the
    polynomial form used on each leg ("003" or "hermite5"); ``knots_s`` the arc length of each
    boundary state."""

    xy: FloatArray
    yaw: FloatArray
    kappa: FloatArray
    s: FloatArray
    forms: tuple[str, ...]
    knots_s: tuple[float, ...]
    #: the path family ("polynomial", "clothoid", "dubins", "reeds-shepp", or "a + b" over legs) and word
    kind: str = "polynomial"
    #: (n,) +1 where the car drives forward, -1 where it reverses (None: forward everywhere)
    direction: FloatArray | None = None
    #: (arc length m, wheel-turning time at rest s) where the car must stop: cusps and curvature jumps
    stops: tuple[tuple[float, float], ...] = ()
    #: top speed at which the servo's steering rate follows the path's curvature changes, m/s
    speed_cap_m_s: float = math.inf

    @property
    def reverse_m(self) -> float:
        """Length driven in reverse, m."""
        if self.direction is None or len(self.s) < 2:
            return 0.0
        return float(np.sum(np.diff(self.s)[self.direction[1:] < 0]))

    @property
    def length_m(self) -> float:
        return float(self.s[-1])

    @property
    def max_abs_kappa(self) -> float:
        return float(np.max(np.abs(self.kappa))) if len(self.kappa) else 0.0

    def sample(self, s_m: FloatArray | float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(x, y, yaw, kappa) at arc lengths ``s_m``. Beyond the end the path continues straight
        along the final heading (the tracker looks ahead past the goal)."""
        sc, x, y, yaw = self._sample(np.asarray(s_m, dtype=float))
        return x, y, yaw, _interp(sc, self.s, self.kappa)

    def sample_xy_yaw(self, s_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(x, y, yaw) of :meth:`sample` (the same values), without the curvature: the collision checks'."""
        _, x, y, yaw = self._sample(np.asarray(s_m, dtype=float))
        return x, y, yaw

    def _sample(self, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(s clipped to the path, x, y, yaw) at arc lengths ``s``, straight on beyond the end."""
        sc = _clip(s, 0.0, self.s[-1])
        x = _interp(sc, self.s, self.xy[:, 0])
        y = _interp(sc, self.s, self.xy[:, 1])
        yaw = _interp(sc, self.s, self.yaw)
        extra = s - sc
        if (extra != 0.0).any():
            x = x + extra * np.cos(yaw)
            y = y + extra * np.sin(yaw)
        return sc, x, y, yaw

    def project(self, x_m: float, y_m: float, hint_s_m: float = 0.0, window_m: float = 2.0) -> tuple[float, float]:
        """(arc length, signed lateral offset + = left) of the nearest path point to (x, y), searched
        within ``window_m`` around ``hint_s_m`` (keeps a loop-free answer on self-approaching paths)."""
        i0 = int(np.searchsorted(self.s, hint_s_m - window_m))
        i1 = int(np.searchsorted(self.s, hint_s_m + window_m)) + 1
        i0, i1 = max(0, i0 - 1), min(len(self.s), i1 + 1)
        p = self.xy[i0:i1]
        if len(p) < 2:
            p = self.xy
            i0 = 0
        a, b = p[:-1], p[1:]
        ab = b - a
        L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
        q = np.array([x_m, y_m])
        u = _clip(np.einsum("ij,ij->i", q - a, ab) / L2, 0.0, 1.0)
        proj = a + u[:, None] * ab
        d2 = np.einsum("ij,ij->i", q - proj, q - proj)
        k = int(np.argmin(d2))
        s0 = float(self.s[i0 + k] + u[k] * (self.s[i0 + k + 1] - self.s[i0 + k]))
        # past the end: measure along the final heading
        if k == len(ab) - 1 and u[k] >= 1.0 and i0 + k + 1 == len(self.s) - 1:
            yaw = float(self.yaw[-1])
            dx, dy = x_m - self.xy[-1, 0], y_m - self.xy[-1, 1]
            along = dx * math.cos(yaw) + dy * math.sin(yaw)
            lat = -dx * math.sin(yaw) + dy * math.cos(yaw)
            return s0 + max(along, 0.0), lat
        yaw = float(np.interp(s0, self.s, self.yaw))
        dx, dy = x_m - proj[k, 0], y_m - proj[k, 1]
        return s0, -dx * math.sin(yaw) + dy * math.cos(yaw)


def _leg_candidates(a: BoundaryState, b: BoundaryState, lam: tuple[float, ...], wheelbase_m: float, form: str) -> tuple[FloatArray, FloatArray]:
    """Coefficients (6, m) of x(u), y(u) for every tangent length in ``lam`` (m values) at once: the same
    equations as :func:`~._poly.poly003_coeffs` / :func:`~._poly.hermite5_coeffs` with T = 1. Scalar
    arithmetic per candidate: for four candidates it is several times faster than numpy on (4,) arrays."""
    if form != "003":
        return _hermite5_candidates(a, b, lam, wheelbase_m)
    ca, cb = math.cos(a.yaw_rad), math.cos(b.yaw_rad)
    ta, tb = math.tan(a.yaw_rad), math.tan(b.yaw_rad)
    ka, kb = math.tan(a.steer_rad) / wheelbase_m, math.tan(b.steer_rad) / wheelbase_m
    ca3, cb3 = ca**3, cb**3
    d = b.x_m - a.x_m
    cols = []
    for L in lam:
        vx0, vxT = L * ca, L * cb
        a2 = 3.0 * d - 2.0 * vx0 - vxT
        a3 = -2.0 * d + vx0 + vxT
        xdd0, xddT = 2.0 * a2, 2.0 * a2 + 6.0 * a3
        ay0 = ka * vx0 * vx0 / ca3 + ta * xdd0  # 003 chain rule (see _poly)
        ayT = kb * vxT * vxT / cb3 + tb * xddT
        cols.append((a.x_m, vx0, a2, a3, 0.0, 0.0) + _quintic_unit(a.y_m, vx0 * ta, ay0, b.y_m, vxT * tb, ayT))
    c = np.array(cols).T
    return c[:6], c[6:]


def _quintic_unit(p0: float, v0: float, a0: float, pT: float, vT: float, aT: float) -> tuple[float, ...]:
    """The six coefficients of :func:`~._poly.quintic_coeffs` with T = 1."""
    c1, c2 = v0, 0.5 * a0
    r0 = pT - (p0 + c1 + c2)
    r1 = vT - (c1 + 2.0 * c2)
    r2 = aT - 2.0 * c2
    return (p0, c1, c2, (20.0 * r0 - 8.0 * r1 + r2) / 2.0, (-30.0 * r0 + 14.0 * r1 - 2.0 * r2) / 2.0,
            (12.0 * r0 - 6.0 * r1 + r2) / 2.0)


def _hermite5_candidates(a: BoundaryState, b: BoundaryState, lam: tuple[float, ...], wheelbase_m: float) -> tuple[FloatArray, FloatArray]:
    """(6, m) x and y coefficients of :func:`~._poly.hermite5_coeffs` (T = 1, speed = tangent length) for
    every tangent length in ``lam``."""
    ca, sa = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    cb, sb = math.cos(b.yaw_rad), math.sin(b.yaw_rad)
    ka, kb = math.tan(a.steer_rad) / wheelbase_m, math.tan(b.steer_rad) / wheelbase_m
    cols = []
    for L in lam:
        l2 = L * L
        cols.append(_quintic_unit(a.x_m, L * ca, -l2 * ka * sa, b.x_m, L * cb, -l2 * kb * sb)
                    + _quintic_unit(a.y_m, L * sa, l2 * ka * ca, b.y_m, L * sb, l2 * kb * cb))
    c = np.array(cols).T
    return c[:6], c[6:]


_BASIS: dict[int, tuple[FloatArray, FloatArray, FloatArray]] = {}


def _basis(n: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Value, first and second derivative bases (n, 6) of degree-5 polynomials on linspace(0, 1, n)."""
    b = _BASIS.get(n)
    if b is None:
        u = np.linspace(0.0, 1.0, n)
        k = np.arange(6)
        up = u[:, None] ** np.maximum(k - 2, 0)[None, :]
        v0 = u[:, None] ** k[None, :]
        v1 = np.zeros((n, 6))
        v1[:, 1:] = k[1:] * (u[:, None] ** (k[1:] - 1))
        v2 = np.zeros((n, 6))
        v2[:, 2:] = (k[2:] * (k[2:] - 1)) * up[:, 2:]
        b = (v0, v1, v2)
        if len(_BASIS) > 256:
            _BASIS.clear()
        _BASIS[n] = b
    return b


def _eval_leg(cx: FloatArray, cy: FloatArray, n: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """(x, y, |P'|, kappa, heading) at n equally spaced parameters; cx, cy (6,) or (6, m) for m
    candidates at once (then every output is (n, m))."""
    v0, v1, v2 = _basis(n)
    x, y = v0 @ cx, v0 @ cy
    xd, yd = v1 @ cx, v1 @ cy
    xdd, ydd = v2 @ cx, v2 @ cy
    sp = np.hypot(xd, yd)
    kappa = (xd * ydd - yd * xdd) / np.maximum(sp, 1e-12) ** 3
    return x, y, sp, kappa, np.arctan2(yd, xd)


def build_path(states: list[BoundaryState], wheelbase_m: float, spacing_m: float = 0.05) -> GeoPath:
    """Path through ``states`` (>= 2; headings and steering angles are honoured at each, speeds are
    ignored). Each leg is solved in its chord frame with the tangent length from :data:`LAMBDA_SCALES`
    that gives the smallest peak curvature. Raises ValueError for coincident consecutive states."""
    if len(states) < 2:
        raise ValueError("a path needs at least two states")
    xs: list[FloatArray] = []
    ys: list[FloatArray] = []
    ks: list[FloatArray] = []
    hs: list[FloatArray] = []
    forms: list[str] = []
    legs = [_leg(a, b, wheelbase_m, spacing_m) for a, b in zip(states[:-1], states[1:])]
    if len(legs) == 1:
        return legs[0][5]  # built with the leg, the same arrays (never modified)
    for wx, wy, kap, hd, form, _ in legs:
        if xs:  # drop the duplicated joint
            wx, wy, kap, hd = wx[1:], wy[1:], kap[1:], hd[1:]
        xs.append(wx)
        ys.append(wy)
        ks.append(kap)
        hs.append(hd)
        forms.append(form)
    return _assemble(xs, ys, ks, hs, forms)


def _assemble(xs: list[FloatArray], ys: list[FloatArray], ks: list[FloatArray], hs: list[FloatArray],
              forms: list[str]) -> GeoPath:
    """The path of legs sampled in world coordinates (joints already dropped): unwrapped yaw, arc length, knots."""
    x, y, kappa = np.concatenate(xs), np.concatenate(ys), np.concatenate(ks)
    h = np.concatenate(hs)
    dh = np.diff(h)
    yaw = np.concatenate(([h[0]], h[0] + np.cumsum(norm_angle_rad(dh))))  # unwrapped
    seg = np.hypot(np.diff(x), np.diff(y))
    s = np.concatenate(([0.0], np.cumsum(seg)))
    ends = np.cumsum([len(h) for h in hs]) - 1
    knots = (0.0,) + tuple(float(s[i]) for i in ends)
    return GeoPath(np.column_stack((x, y)), yaw, kappa, s, tuple(forms), knots)


_Leg = tuple[FloatArray, FloatArray, FloatArray, FloatArray, str, GeoPath]


def _leg(a: BoundaryState, b: BoundaryState, wheelbase_m: float, spacing_m: float) -> _Leg:
    """One leg (x, y, kappa, heading, form, the leg alone as a path), from :data:`_LEGS` when built before."""
    key = (a.x_m, a.y_m, a.yaw_rad, a.steer_rad, b.x_m, b.y_m, b.yaw_rad, b.steer_rad, wheelbase_m, spacing_m)
    leg = _LEGS.get(key)
    if leg is None:
        wx, wy, kap, hd, form = _build_leg(a, b, wheelbase_m, spacing_m)
        leg = (wx, wy, kap, hd, form, _assemble([wx], [wy], [kap], [hd], [form]))
        if len(_LEGS) >= 64:
            _LEGS.clear()
        _LEGS[key] = leg
    return leg


#: legs already built (a search rebuilds the same legs behind its via point for every candidate and
#: every control step); keyed by the exact end states, cleared when full. Entries are never modified.
_LEGS: dict[tuple[float, ...], _Leg] = {}


def _build_leg(a: BoundaryState, b: BoundaryState, wheelbase_m: float,
               spacing_m: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, str]:
    """One leg in world coordinates: (x, y, kappa, heading, form); see :func:`build_path`."""
    chord, c_yaw, form, cx, cy, _ = _leg_shape(a, b, wheelbase_m)
    cc, sc = math.cos(c_yaw), math.sin(c_yaw)
    n = int(min(max(math.ceil(chord / spacing_m / 20.0) * 20, 40), 1500))  # quantised: reuses bases
    lx, ly, _, kap, hd = _eval_leg(cx, cy, n + 1)
    wx, wy = a.x_m + cc * lx - sc * ly, a.y_m + sc * lx + cc * ly
    hd = hd + c_yaw
    return wx, wy, kap, hd, form


def leg_kappa_floor(a: BoundaryState, b: BoundaryState, wheelbase_m: float) -> float:
    """A lower bound of the peak |curvature| of the polynomial leg ``a`` -> ``b`` that :func:`build_path`
    samples, 1/m, without sampling it: the peak over its shape's samples at u = 0, 1/20, ..., 1, which are
    among the path's samples (every path leg has a multiple of 20 intervals). ValueError as :func:`build_path`."""
    return _leg_shape(a, b, wheelbase_m)[5]


#: leg shapes already solved (:func:`_leg_shape`), keyed by the exact end states; cleared when full
_SHAPES: dict[tuple[float, ...], tuple[float, float, str, FloatArray, FloatArray, float]] = {}


def _leg_shape(a: BoundaryState, b: BoundaryState, wheelbase_m: float) -> tuple[float, float, str, FloatArray, FloatArray, float]:
    """(chord, chord direction, form, x and y coefficients (6,) in the chord frame, peak |kappa| at u = k/20) of
    the leg's polynomial: the tangent length of :data:`LAMBDA_SCALES` with the smallest peak curvature."""
    key = (a.x_m, a.y_m, a.yaw_rad, a.steer_rad, b.x_m, b.y_m, b.yaw_rad, b.steer_rad, wheelbase_m)
    shape = _SHAPES.get(key)
    if shape is not None:
        return shape
    dx, dy = b.x_m - a.x_m, b.y_m - a.y_m
    chord = math.hypot(dx, dy)
    if chord < 1e-6:
        raise ValueError(f"two consecutive path states coincide at ({a.x_m:.3f}, {a.y_m:.3f})")
    c_yaw = math.atan2(dy, dx)
    ra = BoundaryState(0.0, 0.0, norm_angle_rad(a.yaw_rad - c_yaw), a.steer_rad)
    rb = BoundaryState(chord, 0.0, norm_angle_rad(b.yaw_rad - c_yaw), b.steer_rad)
    form = "003" if max(abs(ra.yaw_rad), abs(rb.yaw_rad)) <= _MAX_REL_003_RAD else "hermite5"
    CX, CY = _leg_candidates(ra, rb, tuple(chord * k for k in LAMBDA_SCALES), wheelbase_m, form)
    _, v1, v2 = _basis(41)  # the derivatives only (the expressions of _eval_leg)
    xd, yd = v1 @ CX, v1 @ CY
    xdd, ydd = v2 @ CX, v2 @ CY
    sp = np.hypot(xd, yd)
    kap = (xd * ydd - yd * xdd) / np.maximum(sp, 1e-12) ** 3
    hd = np.arctan2(yd, xd)
    # no cusp: the tangent never (nearly) vanishes at a sample, and never turns by more than 90 deg
    # between two neighbouring samples. The second test catches a cusp that falls between samples on
    # a straight back-and-forth leg (goal behind the start, same heading): there the curvature is 0
    # everywhere and the heading flips by 180 deg in place, which no car can drive.
    ok = (sp.min(axis=0) >= 1e-3 * chord) & (np.cos(hd[1:] - hd[:-1]).min(axis=0) > 0.0)
    if not ok.any():
        raise ValueError("no cusp-free polynomial leg between the states")
    peak = np.where(ok, np.abs(kap).max(axis=0), np.inf)
    j = int(peak.argmin())
    shape = (chord, c_yaw, form, CX[:, j], CY[:, j], float(np.abs(kap[::2, j]).max()))
    if len(_SHAPES) >= 64:
        _SHAPES.clear()
    _SHAPES[key] = shape
    return shape
