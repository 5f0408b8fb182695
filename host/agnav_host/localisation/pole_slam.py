"""Localisation on poles learnt online (``--localise poles``): EKF-SLAM over the thin, isolated things a laser sees
in a yard or an orchard (marker poles, trunks, table legs), none of them surveyed, and over the straight walls
beside them.

The state is the robot's pose, the centre of every pole and the line of every wall learnt so far, with their
joint covariance. Wheel
odometry predicts the pose (the noise model of :class:`~.pose_filter.FilterParams`, the same latency
extrapolation as :class:`~.pose_filter.PoseFilter`). In each scan :func:`detect_poles` finds the poles: runs of
returns at most ``max_width_m`` wide that stand at least ``jump_m`` in front of both neighbouring beams. A
pole's radius in one scan is half the run's width plus one beam spacing at its range (the first and last returns
miss the silhouette by about a beam), and its centre is the circle of that radius fitted to the returns
(:func:`~.landmarks.fit_post_centre`): without the beam term the centre comes out about 18 mm nearer at 3-4 m
than at 1 m, and a robot that drives towards its poles then believes it has moved less than it has. A run whose
radius comes out above ``radius_m`` is no pole (a barrel or a bush seen edge-on: fitted with a clamped radius its
centre would stand in front of the real one and move as the robot passes). A learnt pole keeps the mean radius
of its sightings, and a sighting of fewer than ``radius_min_returns`` returns (a far pole, a thin one) is fitted
with that radius: a scan's radius over few returns is quantised by the beam spacing, their mean is not while the
pole spans two beams or more.

A sighting is matched to the learnt pole whose predicted centre is within ``gate_m`` and whose Mahalanobis
distance is below ``gate_chi2``; it then corrects the pose and every pole through their covariance. A
sighting far from every pole (beyond ``new_chi2``) becomes a candidate, which is learnt once it has been seen
``confirm_sightings`` times in a row within ``confirm_sd_m`` and has not crept more than
``confirm_drift_m`` (a walker moves on and is dropped); the new pole enters the state with its covariance
from the pose's and the sighting's.

Walls (:func:`detect_walls`): runs of returns without a jump, split where they bend, kept where a stretch is
at least ``wall_min_m`` long with ``wall_min_returns`` returns fitted within ``wall_rms_m``; a wall is the
infinite line (rho, alpha) in the world, matched and learnt like a pole. A wall holds the distance to it and,
with a pole or a second wall, the heading (the timed SIL figures with and without walls: BENCHMARKS.md).

State: ``ok``; ``slow`` after ``slow_after_m`` driven without a pole or wall matched, ``lost`` after ``lost_after_m``
(the host loop slows, then holds the robot). While lost no pole is learnt, so that a robot far off its estimate
does not map poles at the wrong place; the first matched sighting (the gate grows with the odometry's
covariance) ends it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, TypeVar

import numpy as np
import numpy.typing as npt

from ..types import FloatArray, Pose2D, norm_angle_rad
from .landmarks import fit_post_centre
from .pose_filter import FilterParams, extrapolate, odometry_step, relative

__all__ = ["PoleSlamParams", "PoleSighting", "WallSighting", "PoleSlam", "detect_poles", "detect_walls"]

OK, SLOW, LOST = "ok", "slow", "lost"
#: a match: (Mahalanobis distance, landmark index, innovation, H, S)
_Match = tuple[float, int, FloatArray, FloatArray, FloatArray]


@dataclass(frozen=True)
class PoleSlamParams:
    """Detection: ``max_width_m``, ``jump_m``, ``min_returns``, a pole's radius within ``radius_m`` (a run of a
    larger radius is no pole); a sighting of fewer than ``radius_min_returns`` returns is fitted with its pole's
    mean radius once ``radius_min_sightings`` have gone into that. Matching:
    ``gate_m`` and ``gate_chi2``; ``new_chi2`` above which a sighting is no known pole. Learning:
    ``confirm_sightings`` in a row within ``confirm_sd_m`` (sd of the positions), ``confirm_drift_m`` (first
    to last), a candidate forgotten after ``candidate_timeout_s`` unseen; at most ``max_landmarks`` poles and walls. A sighting's
    noise: ``range_sigma_m``, ``bearing_sigma_rad``. State:
    ``slow_after_m`` / ``lost_after_m`` driven without a matched pole."""

    max_width_m: float = 0.35
    jump_m: float = 0.25
    min_returns: int = 2
    radius_m: tuple[float, float] = (0.03, 0.15)
    max_range_m: float = 20.0
    gate_m: float = 0.4
    gate_chi2: float = 9.0
    new_chi2: float = 25.0
    confirm_sightings: int = 5
    confirm_sd_m: float = 0.03
    confirm_drift_m: float = 0.06
    candidate_radius_m: float = 0.15
    candidate_timeout_s: float = 1.0
    max_landmarks: int = 300
    # a scan's radius of a pole comes from the width of its silhouette, quantised by the beam spacing, and the
    # centre's range moves with it
    radius_min_returns: int = 4
    radius_min_sightings: int = 5
    range_sigma_m: float = 0.03  # a sighting's noise: the fitted centres of 16 cm poles scatter 11-24 mm in range
    bearing_sigma_rad: float = math.radians(0.5)  # and 0.2-0.4 deg in bearing beyond 1 m (TiM310, 1 deg beams)
    # walls: straight stretches at least wall_min_m long of wall_min_returns returns, fitted within wall_rms_m
    walls: bool = True
    wall_min_m: float = 0.6
    wall_min_returns: int = 10
    wall_rms_m: float = 0.02
    wall_sigma_m: float = 0.03
    wall_sigma_rad: float = math.radians(0.6)
    wall_gate_rad: float = math.radians(10.0)
    slow_after_m: float = 2.0
    lost_after_m: float = 5.0

    def __post_init__(self) -> None:
        for k in ("max_width_m", "jump_m", "max_range_m", "gate_m", "gate_chi2", "new_chi2", "confirm_sd_m",
                  "range_sigma_m", "bearing_sigma_rad",
                  "confirm_drift_m", "candidate_radius_m", "candidate_timeout_s", "slow_after_m", "lost_after_m"):
            if not getattr(self, k) > 0:
                raise ValueError(f"PoleSlamParams.{k} must be > 0")
        if self.min_returns < 2 or self.confirm_sightings < 2 or self.max_landmarks < 1:
            raise ValueError("PoleSlamParams: need min_returns >= 2, confirm_sightings >= 2, max_landmarks >= 1")
        if not 0 < self.radius_m[0] <= self.radius_m[1]:
            raise ValueError("PoleSlamParams.radius_m must be (min, max) with 0 < min <= max")
        if not self.slow_after_m <= self.lost_after_m:
            raise ValueError("PoleSlamParams: need slow_after_m <= lost_after_m")


@dataclass(frozen=True)
class PoleSighting:
    """A pole in a scan: its centre's range and bearing from the laser (m, rad), its radius (m) and the returns
    it was fitted to (laser frame, (n, 2) m)."""

    range_m: float
    bearing_rad: float
    radius_m: float
    returns_xy: FloatArray = field(default_factory=lambda: np.zeros((0, 2)), compare=False, repr=False)

    @property
    def returns(self) -> int:
        return len(self.returns_xy)

    def with_radius(self, radius_m: float) -> PoleSighting:
        """The same returns fitted with a circle of ``radius_m``."""
        if self.returns == 0:
            return self
        cx, cy = fit_post_centre(self.returns_xy[:, 0], self.returns_xy[:, 1], radius_m)
        return PoleSighting(math.hypot(cx, cy), math.atan2(cy, cx), radius_m, self.returns_xy)


def detect_poles(ranges_m: FloatArray, angles_rad: FloatArray, range_max_m: float = math.inf,
                 params: PoleSlamParams | None = None) -> list[PoleSighting]:
    """The poles of one scan (laser frame; NaN / out-of-range beams are no return): see the module docstring."""
    p = params or PoleSlamParams()
    r = np.asarray(ranges_m, dtype=float)
    a = np.asarray(angles_rad, dtype=float)
    ok = np.isfinite(r) & (r > 0.05) & (r < min(range_max_m, p.max_range_m))
    rr = np.where(ok, r, np.inf)
    n = len(rr)
    spacing = float(np.median(np.abs(np.diff(a)))) if n > 1 else 0.0
    out: list[PoleSighting] = []
    with np.errstate(invalid="ignore"):  # inf - inf between two beams without a return
        joined = np.abs(np.diff(rr)) < 0.1
    for i, j in _runs(ok, joined):
        run = slice(i, j + 1)
        near = float(rr[run].min())
        left = float(rr[i - 1]) if i > 0 else math.inf
        right = float(rr[j + 1]) if j + 1 < n else math.inf
        if j - i + 1 >= p.min_returns and left > near + p.jump_m and right > near + p.jump_m:
            xs, ys = rr[run] * np.cos(a[run]), rr[run] * np.sin(a[run])
            width = math.hypot(float(xs[-1] - xs[0]), float(ys[-1] - ys[0]))
            # a silhouette wider than the largest pole is no pole (a barrel, a bush seen edge-on): a centre fitted
            # with a clamped radius would stand in front of the real one and move as the robot passes
            rad = max(0.5 * (width + float(rr[run].mean()) * spacing), p.radius_m[0])
            if width <= p.max_width_m and rad <= p.radius_m[1]:
                cx, cy = fit_post_centre(xs, ys, rad)
                out.append(PoleSighting(math.hypot(cx, cy), math.atan2(cy, cx), rad, np.column_stack([xs, ys])))
    return out


def _runs(ok: npt.NDArray[np.bool_], joined: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The runs (first, last beam) of consecutive beams with a return (``ok``) where each beam is ``joined`` to
    the next (``joined[k]``: beams k and k + 1 belong together)."""
    out: list[tuple[int, int]] = []
    n = len(ok)
    i = 0
    while i < n:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and ok[j + 1] and joined[j]:
            j += 1
        out.append((i, j))
        i = j + 1
    return out


@dataclass(frozen=True)
class WallSighting:
    """A straight wall in a scan, as the line x cos(alpha) + y sin(alpha) = rho in the laser frame (rho >= 0 m,
    alpha the direction of the line's normal from the laser, rad), its length (m) and returns."""

    rho_m: float
    alpha_rad: float
    length_m: float
    returns: int


Sg = TypeVar("Sg", PoleSighting, WallSighting)


def _line_fit(xs: FloatArray, ys: FloatArray) -> tuple[float, float, float]:
    """Total least squares: (rho >= 0, alpha, rms m) of the line through the points."""
    mx, my = float(xs.mean()), float(ys.mean())
    dx, dy = xs - mx, ys - my
    cxx, cyy, cxy = float((dx * dx).mean()), float((dy * dy).mean()), float((dx * dy).mean())
    alpha = 0.5 * math.atan2(-2.0 * cxy, cyy - cxx)  # the normal: the direction of least spread
    rho = mx * math.cos(alpha) + my * math.sin(alpha)
    if rho < 0:
        rho, alpha = -rho, alpha + math.pi
    res = xs * math.cos(alpha) + ys * math.sin(alpha) - rho
    return rho, norm_angle_rad(alpha), float(np.sqrt(np.mean(res**2)))


def detect_walls(ranges_m: FloatArray, angles_rad: FloatArray, range_max_m: float = math.inf,
                 params: PoleSlamParams | None = None) -> list[WallSighting]:
    """The straight walls of one scan (laser frame): runs of returns without a jump, split where they bend
    (split-and-merge), kept when a stretch is long, has enough returns and fits a line closely."""
    p = params or PoleSlamParams()
    r = np.asarray(ranges_m, dtype=float)
    a = np.asarray(angles_rad, dtype=float)
    ok = np.isfinite(r) & (r > 0.05) & (r < min(range_max_m, p.max_range_m))
    xs_all, ys_all = np.where(ok, r, 0.0) * np.cos(a), np.where(ok, r, 0.0) * np.sin(a)
    out: list[WallSighting] = []

    def split(i: int, j: int) -> None:
        if j - i + 1 < p.wall_min_returns:
            return
        x0, y0, x1, y1 = xs_all[i], ys_all[i], xs_all[j], ys_all[j]
        length = math.hypot(x1 - x0, y1 - y0)
        if length < p.wall_min_m:
            return
        xs, ys = xs_all[i:j + 1], ys_all[i:j + 1]
        dev = np.abs((xs - x0) * (y1 - y0) - (ys - y0) * (x1 - x0)) / max(length, 1e-9)
        k = int(np.argmax(dev))
        if dev[k] > 3.0 * p.wall_rms_m and 0 < k < j - i:
            split(i, i + k)
            split(i + k, j)
            return
        rho, alpha, rms = _line_fit(xs, ys)
        if rms <= p.wall_rms_m:
            out.append(WallSighting(rho, alpha, length, j - i + 1))

    for i, j in _runs(ok, np.hypot(np.diff(xs_all), np.diff(ys_all)) < 0.1):
        split(i, j)
    return out


@dataclass
class _Candidate:
    xy: list[tuple[float, float]]
    last_t_s: float
    sighting: PoleSighting


@dataclass
class _WallCandidate:
    lines: list[FloatArray]
    last_t_s: float
    sighting: WallSighting


@dataclass
class PoleSlam:
    """See the module docstring. ``start``: the odometry frame's origin in the world; ``mount``: the laser on
    the robot."""

    start: Pose2D
    mount: Pose2D = Pose2D()
    params: PoleSlamParams = field(default_factory=PoleSlamParams)
    filter_params: FilterParams = field(default_factory=FilterParams)

    def __post_init__(self) -> None:
        self.X: FloatArray = np.array([self.start.x_m, self.start.y_m, self.start.yaw_rad])
        # the start pose is the origin of the map the poles are learnt in: known to the millimetre
        self.P: FloatArray = np.diag([1e-6, 1e-6, 1e-8])
        self.radii: list[float] = []  # per landmark: a pole's radius (0 for a wall)
        self._radius_sum: list[float] = []  # per landmark: the sum and count of the radii of its sightings
        self._radius_n: list[int] = []
        self.kinds: list[str] = []  # per landmark: "pole" (centre x, y) or "wall" (rho, alpha in the world)
        self._wall_cands: list[_WallCandidate] = []
        self.stamp_s: float | None = None
        self.speed_m_s = 0.0
        self.yaw_rate_rad_s = 0.0
        self._last_odo = Pose2D()
        self._cands: list[_Candidate] = []
        self.sighted = 0  # sightings that corrected the estimate
        self.state = OK
        self.reason = ""
        self.uncorrected_m = 0.0  # driven since the last matched pole, m

    # ---- the Localiser protocol ------------------------------------------------------------------
    def odometry(self, x_m: float, y_m: float, yaw_rad: float, stamp_s: float, speed_m_s: float,
                 yaw_rate_rad_s: float) -> None:
        """One odometry report (pose in the odometry frame; stamp; speed; yaw rate). Reports not newer than the
        last one are ignored."""
        if self.stamp_s is not None and stamp_s <= self.stamp_s:
            return
        odo = Pose2D(x_m, y_m, yaw_rad)
        d = relative(self._last_odo, odo)
        self._move(d)
        self.uncorrected_m += math.hypot(d.x_m, d.y_m)
        self._last_odo = odo
        self.stamp_s, self.speed_m_s, self.yaw_rate_rad_s = stamp_s, speed_m_s, yaw_rate_rad_s
        self._check_state()

    def pose_at(self, t_s: float) -> Pose2D:
        """The estimate carried from the last report's stamp to ``t_s``."""
        q = Pose2D(float(self.X[0]), float(self.X[1]), float(self.X[2]))
        return q if self.stamp_s is None else extrapolate(q, self.speed_m_s, self.yaw_rate_rad_s, self._dt(t_s))

    def scan(self, ranges_m: FloatArray, angles_rad: FloatArray, t_s: float, range_max_m: float = math.inf) -> int:
        """Correct with the poles and walls of one scan taken at ``t_s``; returns how many matched."""
        seen = detect_poles(ranges_m, angles_rad, range_max_m, self.params)
        dt = self._dt(t_s)
        R = np.diag([self.params.range_sigma_m ** 2, self.params.bearing_sigma_rad ** 2])
        taken: set[int] = set()
        matched: list[tuple[FloatArray, FloatArray, FloatArray]] = []  # (innovation, H, R) of each match
        unknown = self._match(seen, self._best_match, dt, R, taken, matched, self._add_radius)
        walls = detect_walls(ranges_m, angles_rad, range_max_m, self.params) if self.params.walls else []
        Rw = np.diag([self.params.wall_sigma_m ** 2, self.params.wall_sigma_rad ** 2])
        new_walls = self._match(walls, self._best_wall, dt, Rw, taken, matched)
        if matched:
            self._update(matched)
            self.sighted += len(matched)
            self.uncorrected_m = 0.0
            if self.state != OK:
                self.state, self.reason = OK, ""
        if self.state != LOST:  # a robot far off its estimate would learn poles at the wrong place
            self._learn(unknown, t_s, dt, R)
            self._learn_walls(new_walls, t_s, dt, Rw)
        return len(matched)

    def _match(self, sightings: list[Sg], best_of: Callable[[Sg, float, FloatArray, set[int]], _Match | None],
               dt: float, R: FloatArray, taken: set[int], matched: list[tuple[FloatArray, FloatArray, FloatArray]],
               on_match: Callable[[Sg, int], None] | None = None) -> list[Sg]:
        """Each sighting (covariance ``R``) to its best landmark (``best_of``): matched ones go into ``matched``
        (their landmark into ``taken``, and to ``on_match``); returns the sightings far from every landmark
        (candidates to learn)."""
        unknown: list[Sg] = []
        for sg in sightings:
            best = best_of(sg, dt, R, taken)
            if best is not None and best[0] < self.params.gate_chi2:
                _, k, nu, H, _ = best
                matched.append((nu, H, R))
                taken.add(k)
                if on_match is not None:
                    on_match(sg, k)
            elif best is None or best[0] > self.params.new_chi2:
                unknown.append(sg)
        return unknown

    def _update(self, matched: list[tuple[FloatArray, FloatArray, FloatArray]]) -> None:
        """One EKF update with every match of a scan (innovation, H, R each), gated on the state before it. One
        update of the stacked rows reads and writes the covariance once: a sighting at a time costs the whole
        covariance per sighting (a median of 32 ms a scan at 200-240 poles against 7 ms)."""
        H = np.vstack([m[1] for m in matched])
        nu = np.concatenate([m[0] for m in matched])
        R = np.zeros((len(nu), len(nu)))
        for i, m in enumerate(matched):
            R[2 * i: 2 * i + 2, 2 * i: 2 * i + 2] = m[2]
        cols = np.flatnonzero(np.any(H != 0.0, axis=0))
        Hc = H[:, cols]
        PHt = self.P[:, cols] @ Hc.T
        S = Hc @ PHt[cols, :] + R
        K = PHt @ np.linalg.inv(S)
        self.X = self.X + K @ nu
        self.X[2] = norm_angle_rad(float(self.X[2]))
        P = self.P - K @ PHt.T
        self.P = 0.5 * (P + P.T)

    # ---- state -----------------------------------------------------------------------------------
    def status(self) -> tuple[str, str]:
        """(state, reason): ``ok``, ``slow`` or ``lost``, and why when not ok."""
        return self.state, self.reason

    @property
    def sigma(self) -> tuple[float, float, float]:
        """1-sigma of x, y (m) and yaw (rad) of the pose."""
        d = np.sqrt(np.maximum(np.diag(self.P)[:3], 0.0))
        return float(d[0]), float(d[1]), float(d[2])

    @property
    def poles(self) -> FloatArray:
        """The learnt poles, (n, 3): centre x, y (m, world frame) and radius (m)."""
        idx = [k for k, kind in enumerate(self.kinds) if kind == "pole"]
        if not idx:
            return np.zeros((0, 3))
        xy = self.X[3:].reshape(-1, 2)[idx]
        return np.column_stack([xy, np.asarray(self.radii, dtype=float)[idx]])

    @property
    def walls(self) -> FloatArray:
        """The learnt walls, (n, 2): the line x cos(alpha) + y sin(alpha) = rho in the world (rho m, alpha rad)."""
        idx = [k for k, kind in enumerate(self.kinds) if kind == "wall"]
        return self.X[3:].reshape(-1, 2)[idx] if idx else np.zeros((0, 2))

    def _check_state(self) -> None:
        d = self.uncorrected_m
        why = f"{d:.1f} m driven without a pole or wall in sight"
        if d >= self.params.lost_after_m:
            self.state, self.reason = LOST, why
        elif d >= self.params.slow_after_m and self.state == OK:
            self.state, self.reason = SLOW, why

    # ---- the filter ------------------------------------------------------------------------------
    def _dt(self, t_s: float) -> float:
        return 0.0 if self.stamp_s is None else min(max(t_s - self.stamp_s, 0.0), 0.5)

    def _move(self, d: Pose2D) -> None:
        th = float(self.X[2])
        c, s = math.cos(th), math.sin(th)
        F, G, Q = odometry_step(th, d, self.filter_params)
        self.X[0] += c * d.x_m - s * d.y_m
        self.X[1] += s * d.x_m + c * d.y_m
        self.X[2] = norm_angle_rad(th + d.yaw_rad)
        P = self.P
        P[:3, :3] = F @ P[:3, :3] @ F.T + G @ Q @ G.T
        P[:3, 3:] = F @ P[:3, 3:]
        P[3:, :3] = P[:3, 3:].T

    def _sensor(self, pose: FloatArray, dt: float) -> Pose2D:
        q = extrapolate(Pose2D(float(pose[0]), float(pose[1]), float(pose[2])), self.speed_m_s, self.yaw_rate_rad_s, dt)
        return q.compose(self.mount)

    def _h(self, pose: FloatArray, lm: FloatArray, dt: float, kind: str = "pole") -> FloatArray:
        """What the laser sees of landmark ``lm`` from ``pose``: a pole's range and bearing, a wall's (rho, alpha)."""
        s = self._sensor(pose, dt)
        if kind == "wall":
            rho = float(lm[0]) - (s.x_m * math.cos(float(lm[1])) + s.y_m * math.sin(float(lm[1])))
            alpha = float(lm[1]) - s.yaw_rad
            if rho < 0:
                rho, alpha = -rho, alpha + math.pi
            return np.array([rho, norm_angle_rad(alpha)])
        dx, dy = float(lm[0]) - s.x_m, float(lm[1]) - s.y_m
        return np.array([math.hypot(dx, dy), norm_angle_rad(math.atan2(dy, dx) - s.yaw_rad)])

    def _jacobian(self, k: int, dt: float) -> FloatArray:
        H = np.zeros((2, len(self.X)))
        kind = self.kinds[k]
        pose, lm = self.X[:3].copy(), self.X[3 + 2 * k: 5 + 2 * k].copy()
        z0 = self._h(pose, lm, dt, kind)
        for i, eps in enumerate((1e-4, 1e-4, 1e-5)):
            d = np.zeros(3)
            d[i] = eps
            dz = self._h(pose + d, lm, dt, kind) - z0
            dz[1] = norm_angle_rad(float(dz[1]))
            H[:, i] = dz / eps
        for i, eps in enumerate((1e-4, 1e-5) if kind == "wall" else (1e-4, 1e-4)):
            e = np.zeros(2)
            e[i] = eps
            dz = self._h(pose, lm + e, dt, kind) - z0
            dz[1] = norm_angle_rad(float(dz[1]))
            H[:, 3 + 2 * k + i] = dz / eps
        return H

    def _best_wall(self, ws: WallSighting, dt: float, R: FloatArray, taken: set[int]) -> _Match | None:
        """The learnt wall nearest the sighting in Mahalanobis distance among those within 0.3 m and
        ``wall_gate_rad``."""
        best: _Match | None = None
        pose = self.X[:3]
        for k, kind in enumerate(self.kinds):
            if kind != "wall" or k in taken:
                continue
            zh = self._h(pose, self.X[3 + 2 * k: 5 + 2 * k], dt, "wall")
            nu = np.array([ws.rho_m - zh[0], norm_angle_rad(ws.alpha_rad - float(zh[1]))])
            if abs(nu[0]) > 0.3 or abs(nu[1]) > self.params.wall_gate_rad:
                continue
            best = self._better(best, k, nu, dt, R)
        return best

    def _best_match(self, sg: PoleSighting, dt: float, R: FloatArray, taken: set[int]) -> _Match | None:
        """The learnt pole nearest the sighting in Mahalanobis distance among those within ``gate_m`` (the
        sighting fitted as that pole would be seen, :meth:`_fitted`)."""
        best: _Match | None = None
        pose = self.X[:3]
        gate = self.params.gate_m
        if not self.kinds:
            return None
        # a screen over every landmark at once: only those near where the sighting puts the pole
        wx, wy = self._pole_in_world(pose, np.array([sg.range_m, sg.bearing_rad]), dt)
        lm = self.X[3:].reshape(-1, 2)
        near = np.flatnonzero((np.hypot(lm[:, 0] - wx, lm[:, 1] - wy) < 2.0 * gate)
                              & (np.asarray(self.kinds) == "pole"))
        for k in (int(i) for i in near):
            if k in taken:
                continue
            zh = self._h(pose, self.X[3 + 2 * k: 5 + 2 * k], dt)
            sk = self._fitted(sg, k)
            nu = np.array([sk.range_m - zh[0], norm_angle_rad(sk.bearing_rad - float(zh[1]))])
            if abs(nu[0]) > gate or abs(nu[1]) * sk.range_m > gate:
                continue
            best = self._better(best, k, nu, dt, R)
        return best

    def _add_radius(self, sg: PoleSighting, k: int) -> None:
        """A sighting matched to pole ``k``: its radius into the pole's mean, which is the pole's radius once
        ``radius_min_sightings`` have gone into it."""
        self._radius_sum[k] += sg.radius_m
        self._radius_n[k] += 1
        if self._radius_n[k] >= self.params.radius_min_sightings:
            self.radii[k] = self._radius_sum[k] / self._radius_n[k]

    def _fitted(self, sg: PoleSighting, k: int) -> PoleSighting:
        """Sighting ``sg`` as pole ``k`` would be seen: a sighting of few returns fitted with the pole's radius once
        that is learnt (``radius_min_returns``, ``radius_min_sightings``)."""
        p = self.params
        if sg.returns >= p.radius_min_returns or self._radius_n[k] < p.radius_min_sightings:
            return sg
        return sg.with_radius(self.radii[k])

    def _better(self, best: _Match | None, k: int, nu: FloatArray, dt: float, R: FloatArray) -> _Match:
        """``best`` or landmark ``k`` with innovation ``nu``, whichever is nearer in Mahalanobis distance."""
        H = self._jacobian(k, dt)
        S = self._innovation_cov(H, k, R)
        m = float(nu @ np.linalg.solve(S, nu))
        return (m, k, nu, H, S) if best is None or m < best[0] else best

    def _innovation_cov(self, H: FloatArray, k: int, R: FloatArray) -> FloatArray:
        """H P H^T + R from the pose's and landmark ``k``'s columns only (H is zero elsewhere)."""
        idx = np.array([0, 1, 2, 3 + 2 * k, 4 + 2 * k])
        Hs = H[:, idx]
        out: FloatArray = Hs @ self.P[np.ix_(idx, idx)] @ Hs.T + R
        return out

    # ---- learning poles --------------------------------------------------------------------------
    def _learn(self, unknown: list[PoleSighting], t_s: float, dt: float, R: FloatArray) -> None:
        p = self.params
        self._cands = [c for c in self._cands if t_s - c.last_t_s < p.candidate_timeout_s]
        for sg in unknown:
            wx, wy = (float(v) for v in self._pole_in_world(self.X[:3], np.array([sg.range_m, sg.bearing_rad]), dt))
            hit = None
            for c in self._cands:
                m = np.mean(np.asarray(c.xy), axis=0)
                if math.hypot(float(m[0]) - wx, float(m[1]) - wy) < p.candidate_radius_m:
                    hit = c
                    break
            if hit is None:
                self._cands.append(_Candidate([(wx, wy)], t_s, sg))
                continue
            hit.xy.append((wx, wy))
            hit.last_t_s, hit.sighting = t_s, sg
            xy = np.asarray(hit.xy)
            if len(xy) < p.confirm_sightings:
                continue
            if float(xy.std(axis=0).max()) < p.confirm_sd_m and math.hypot(*(xy[-1] - xy[0])) < p.confirm_drift_m:
                if len(self.kinds) < p.max_landmarks:
                    self._add_landmark(np.array([sg.range_m, sg.bearing_rad]), dt, R, "pole", sg.radius_m)
                self._cands.remove(hit)
            elif len(xy) > 2 * p.confirm_sightings + 2:  # it keeps moving: not a pole
                self._cands.remove(hit)

    def _pole_in_world(self, pose: FloatArray, z: FloatArray, dt: float) -> FloatArray:
        """Where a pole seen at range and bearing ``z`` from the laser stands, the robot at ``pose``."""
        s = self._sensor(pose, dt)
        return np.array([s.x_m + z[0] * math.cos(s.yaw_rad + z[1]), s.y_m + z[0] * math.sin(s.yaw_rad + z[1])])

    def _wall_in_world(self, pose: FloatArray, z: FloatArray, dt: float) -> FloatArray:
        """The world line of a wall seen as (rho, alpha) ``z`` from the laser, the robot at ``pose``."""
        s = self._sensor(pose, dt)
        alpha = float(z[1]) + s.yaw_rad
        rho = float(z[0]) + s.x_m * math.cos(alpha) + s.y_m * math.sin(alpha)
        if rho < 0:
            rho, alpha = -rho, alpha + math.pi
        return np.array([rho, norm_angle_rad(alpha)])

    def _learn_walls(self, unknown: list[WallSighting], t_s: float, dt: float, R: FloatArray) -> None:
        p = self.params
        self._wall_cands = [c for c in self._wall_cands if t_s - c.last_t_s < p.candidate_timeout_s]
        pose = self.X[:3]
        for ws in unknown:
            w = self._wall_in_world(pose, np.array([ws.rho_m, ws.alpha_rad]), dt)
            hit = None
            for c in self._wall_cands:
                m = c.lines[-1]
                if abs(m[0] - w[0]) < 0.1 and abs(norm_angle_rad(float(m[1] - w[1]))) < math.radians(3.0):
                    hit = c
                    break
            if hit is None:
                self._wall_cands.append(_WallCandidate([w], t_s, ws))
                continue
            hit.lines.append(w)
            hit.last_t_s, hit.sighting = t_s, ws
            if len(hit.lines) >= p.confirm_sightings:
                lines = np.asarray(hit.lines)
                da = np.array([norm_angle_rad(float(v - lines[0, 1])) for v in lines[:, 1]])
                if float(lines[:, 0].std()) < p.confirm_sd_m and float(da.std()) < math.radians(1.0):
                    if len(self.kinds) < p.max_landmarks:
                        self._add_landmark(np.array([ws.rho_m, ws.alpha_rad]), dt, R, "wall", 0.0)
                self._wall_cands.remove(hit)

    def _add_landmark(self, z: FloatArray, dt: float, R: FloatArray, kind: str, radius_m: float) -> None:
        """The landmark of sighting ``z`` into the state, its covariance from the pose's and the sighting's."""
        pose = self.X[:3].copy()

        def g(pose_: FloatArray, z_: FloatArray) -> FloatArray:
            return self._wall_in_world(pose_, z_, dt) if kind == "wall" else self._pole_in_world(pose_, z_, dt)

        l0 = g(pose, z)
        Gx = np.zeros((2, 3))
        Gz = np.zeros((2, 2))
        for i, eps in enumerate((1e-4, 1e-4, 1e-5)):
            d = np.zeros(3)
            d[i] = eps
            dl = g(pose + d, z) - l0
            dl[1] = norm_angle_rad(float(dl[1])) if kind == "wall" else dl[1]
            Gx[:, i] = dl / eps
        for i, eps in enumerate((1e-4, 1e-5)):
            e = np.zeros(2)
            e[i] = eps
            dl = g(pose, z + e) - l0
            dl[1] = norm_angle_rad(float(dl[1])) if kind == "wall" else dl[1]
            Gz[:, i] = dl / eps
        n = len(self.X)
        P = np.zeros((n + 2, n + 2))
        P[:n, :n] = self.P
        P[n:, :n] = Gx @ self.P[:3, :]
        P[:n, n:] = P[n:, :n].T
        P[n:, n:] = Gx @ self.P[:3, :3] @ Gx.T + Gz @ R @ Gz.T
        self.X = np.concatenate([self.X, l0])
        self.P = P
        self.radii.append(radius_m)
        self._radius_sum.append(0.0)
        self._radius_n.append(0)
        self.kinds.append(kind)
