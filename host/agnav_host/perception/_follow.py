"""Row following controllers: centre line between two rows, proximity to one row, headland turns (the row
navigator that drives whole fields with them is planning.row_navigator).

Each controller has ``reset()`` and ``step(obs) -> DriveCommand`` (the simulator's ``Controller``
shape) and reads ``obs.scan``; the laser's pose on the robot is a parameter (``mount``).

Between scans the estimate (lateral error e, heading error psi) is carried forward with the robot's
own speed and yaw rate, ``de/dt = v sin(psi)`` and ``dpsi/dt = w - v kappa``, in a two-state Kalman
filter; each detection is a measurement whose noise grows as its confidence falls. The steering law
puts the lateral error on a second-order response with natural frequency ``omega_n`` and damping
``zeta``: ``w = v kappa - 2 zeta omega_n psi - (omega_n^2 / v) e`` (a differential drive takes ``w``
directly, an Ackermann robot the steering angle ``atan(L w / v)``).
"""

from __future__ import annotations

import math
from typing import Any, cast
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ..types import DriveCommand, FloatArray, Observation, Pose2D, norm_angle_rad
from ._rows import ROW_METHODS, RowEstimate, RowParams, detect_rows_points
from ._scan import ScanParams, ScanPoints, points_from_scan

__all__ = [
    "DriveLimits",
    "RowFollowerParams",
    "RowFollower",
    "SingleRowEstimate",
    "detect_single_row",
    "ProximityFollowerParams",
    "ProximityFollower",
    "headland_path",
    "HeadlandTurn",
]


@dataclass(frozen=True)
class DriveLimits:
    """The robot the controller drives (SI units)."""

    kinematics: str = "diff_drive"  # or "ackermann"
    max_yaw_rate_rad_s: float = 1.2
    wheelbase_m: float = 0.174
    max_steer_rad: float = math.radians(24.6)
    min_turn_radius_m: float = 0.3  # differential drive: the tightest headland arc it should drive

    def __post_init__(self) -> None:
        if self.kinematics not in ("diff_drive", "ackermann"):
            raise ValueError(f"kinematics must be 'diff_drive' or 'ackermann', got {self.kinematics!r}")

    @property
    def turn_radius_m(self) -> float:
        if self.kinematics == "ackermann":
            return self.wheelbase_m / math.tan(self.max_steer_rad)
        return self.min_turn_radius_m

    def command(self, v: float, w: float) -> DriveCommand:
        """A drive command for speed v (m/s) and yaw rate w (rad/s), within the limits."""
        if self.kinematics == "ackermann":
            steer = math.atan(self.wheelbase_m * w / v) if abs(v) > 1e-6 else 0.0
            return DriveCommand(v, 0.0, max(-self.max_steer_rad, min(self.max_steer_rad, steer)))
        return DriveCommand(v, max(-self.max_yaw_rate_rad_s, min(self.max_yaw_rate_rad_s, w)))


class _TrackFilter:
    """Kalman filter on (e, psi) of the module docstring."""

    def __init__(self, q_e: float, q_psi: float) -> None:
        self.q = np.diag([q_e**2, q_psi**2])
        self.x: FloatArray | None = None
        self.P = np.eye(2)
        self.t: float | None = None
        self.kappa = 0.0

    def predict(self, t: float, v: float, w: float) -> None:
        if self.x is None or self.t is None:
            self.t = t
            return
        dt = max(0.0, t - self.t)
        self.t = t
        e, psi = self.x
        self.x = np.array([e + v * math.sin(psi) * dt, norm_angle_rad(psi + (w - v * self.kappa) * dt)])
        F = np.array([[1.0, v * math.cos(psi) * dt], [0.0, 1.0]])
        self.P = F @ self.P @ F.T + self.q * max(dt, 1e-3)

    def update(self, e: float, psi: float | None, std_e: float, std_psi: float) -> None:
        if self.x is None:
            self.x = np.array([e, psi if psi is not None else 0.0])
            self.P = np.diag([std_e**2, std_psi**2 if psi is not None else 0.05])
            return
        if psi is None:
            H = np.array([[1.0, 0.0]])
            z = np.array([e])
            R = np.array([[std_e**2]])
        else:
            H = np.eye(2)
            z = np.array([e, psi])
            R = np.diag([std_e**2, std_psi**2])
        y = z - H @ self.x
        S = H @ self.P @ H.T + R
        K = self.P @ H.T @ np.linalg.inv(S)
        self.x = self.x + K @ y
        self.P = (np.eye(2) - K @ H) @ self.P


@dataclass(frozen=True)
class RowFollowerParams:
    """Centre-line row following (SI units). ``method`` names a detector of :data:`ROW_METHODS`."""

    method: str = "ransac"
    speed_m_s: float = 0.4
    omega_n_rad_s: float = 1.2
    zeta: float = 0.9
    limits: DriveLimits = field(default_factory=DriveLimits)
    mount: Pose2D = field(default_factory=Pose2D)
    rows: RowParams = field(default_factory=RowParams)
    meas_std_m: float = 0.02  # detection noise at confidence 1
    meas_std_rad: float = 0.03
    process_std_m: float = 0.01  # per sqrt(s)
    process_std_rad: float = 0.05
    min_confidence: float = 0.15
    # a soft gate: a detection's noise is multiplied by 1 + (de / gate_m)^2 + (dpsi / gate_rad)^2 + (ds / (gate_spacing
    # s))^2: de, dpsi its distance in lateral offset and heading from the median of the last ``gate_history``
    # detections (each carried to the robot's present pose by its odometry), ds from the expected row spacing s.
    # One far off (a weed line, a neighbouring row seen through a gap) hardly moves the filter; what the detections
    # agree on does, even where the filter is off. inf: no gate (each detection weighed by its confidence alone)
    gate_m: float = math.inf
    gate_rad: float = math.inf
    gate_spacing: float = math.inf
    gate_history: int = 7

    def __post_init__(self) -> None:
        if self.method not in ROW_METHODS:
            raise ValueError(f"unknown row method {self.method!r}; known: {', '.join(ROW_METHODS)}")
        if not (self.speed_m_s > 0 and self.omega_n_rad_s > 0 and self.zeta > 0):
            raise ValueError("RowFollowerParams: speed, omega_n and zeta must be > 0")


def _steer(limits: DriveLimits, v: float, e: float, psi: float, kappa: float, wn: float, zeta: float) -> DriveCommand:
    vv = max(abs(v), 0.1)
    w = v * kappa - 2.0 * zeta * wn * psi - (wn * wn / vv) * e
    return limits.command(v, w)


class RowFollower:
    """Drive the centre line between two rows with the named detector (see the module docstring).

    ``last`` holds the latest :class:`RowEstimate`; ``fill`` feeds an end-of-row detector.
    """

    def __init__(self, params: RowFollowerParams | None = None) -> None:
        self.params = params or RowFollowerParams()
        p = self.params
        self._kf = _TrackFilter(p.process_std_m, p.process_std_rad)
        self.last: RowEstimate | None = None
        self._seen: list[tuple[float, float, float]] = []  # the gate's history: (row yaw, centre x, centre y)

    def reset(self) -> None:
        p = self.params
        self._kf = _TrackFilter(p.process_std_m, p.process_std_rad)
        self.last = None
        self._seen = []

    @property
    def state(self) -> tuple[float, float] | None:
        """Filtered (lateral_offset_m, heading_rad), or None before the first detection."""
        x = self._kf.x
        return None if x is None else (float(x[0]), float(x[1]))

    def observe(self, obs: Observation) -> RowEstimate | None:
        """Predict to ``obs.t_s`` and fold in the scan's detection; returns the raw estimate."""
        p = self.params
        self._kf.predict(obs.t_s, obs.speed_m_s, obs.yaw_rate_rad_s)
        if obs.scan is None:
            return None
        pts = points_from_scan(obs.scan, p.mount, p.rows.scan)
        est = detect_rows_points(pts, p.method, p.rows)
        self.last = est
        if est.confidence >= p.min_confidence:
            k = self._gate(est, obs.pose) / max(est.confidence, 0.05)
            self._kf.update(est.lateral_offset_m, est.heading_rad if est.heading_observed else None,
                            p.meas_std_m * k, p.meas_std_rad * k)
        return est

    def _gate(self, est: RowEstimate, pose: Pose2D) -> float:
        """The soft gate's factor on the detection's noise (>= 1; see the parameters)."""
        p = self.params
        if not (math.isfinite(p.gate_m) or math.isfinite(p.gate_rad) or math.isfinite(p.gate_spacing)):
            return 1.0
        s0 = p.rows.expected_spacing_m
        k = 1.0 + ((est.row_spacing_m - s0) / (p.gate_spacing * s0)) ** 2
        # each earlier detection as a centre line in the odometry frame, seen from the present pose
        row_yaw = pose.yaw_rad - est.heading_rad
        cx = pose.x_m + math.sin(row_yaw) * est.lateral_offset_m
        cy = pose.y_m - math.cos(row_yaw) * est.lateral_offset_m
        if len(self._seen) >= 3:
            e_now, psi_now = [], []
            for yaw_i, cx_i, cy_i in self._seen:
                psi_now.append(norm_angle_rad(pose.yaw_rad - yaw_i))
                e_now.append(-math.sin(yaw_i) * (pose.x_m - cx_i) + math.cos(yaw_i) * (pose.y_m - cy_i))
            k += ((est.lateral_offset_m - float(np.median(e_now))) / p.gate_m) ** 2
            if est.heading_observed:
                k += (norm_angle_rad(est.heading_rad - float(np.median(psi_now))) / p.gate_rad) ** 2
        self._seen.append((row_yaw, cx, cy))
        del self._seen[:-p.gate_history]
        return k

    def step(self, obs: Observation) -> DriveCommand:
        p = self.params
        self.observe(obs)
        st = self.state
        if st is None:
            return p.limits.command(0.5 * p.speed_m_s, 0.0)
        return _steer(p.limits, p.speed_m_s, st[0], st[1], 0.0, p.omega_n_rad_s, p.zeta)


# ---- proximity following of one row --------------------------------------------------------------


@dataclass(frozen=True)
class SingleRowEstimate:
    """One row beside the robot: ``offset_m`` is the signed lateral position of the row's visible face
    at the robot (left positive), ``heading_rad`` the robot's heading relative to the row (CCW
    positive), ``curvature_1_m`` the row's curvature (left turn positive)."""

    offset_m: float
    heading_rad: float
    curvature_1_m: float
    confidence: float
    n_points: int


def detect_single_row(pts: ScanPoints, side: str, x_min_m: float = -1.0, x_max_m: float = 3.0,
                      max_lateral_m: float = 2.5, prior: SingleRowEstimate | None = None,
                      gate_m: float = 0.4, trim_m: float = 0.12) -> SingleRowEstimate | None:
    """Quadratic least-squares fit ``y = a + b x + c x^2`` to the row points on ``side`` ('left' or
    'right'), refitted twice without points more than ``trim_m`` from the curve. With a ``prior``,
    only points within ``gate_m`` of the prior's curve are used. A quadratic keeps the fit on a
    curved row (a straight line through a bend is off by about kappa x^2 / 2 at the robot)."""
    sgn = 1.0 if side == "left" else -1.0
    if side not in ("left", "right"):
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    xy = pts.xy
    x, y = xy[:, 0], xy[:, 1]
    sel = (x >= x_min_m) & (x <= x_max_m) & (sgn * y > 0.1) & (sgn * y < max_lateral_m)
    if prior is not None:
        b0 = -math.tan(prior.heading_rad)
        yp = prior.offset_m + b0 * x + 0.5 * prior.curvature_1_m * x * x
        sel &= np.abs(y - yp) < gate_m
    else:
        # nearest return per 0.25 m of x: the row's near face, not what lies beyond it
        pass
    x, y = x[sel], y[sel]
    if len(x) < 6:
        return None
    keep = np.ones(len(x), dtype=bool)
    coef: npt.NDArray[np.floating[Any]] = np.zeros(3)
    for _ in range(3):
        if keep.sum() < 6:
            return None
        A = np.column_stack((np.ones(int(keep.sum())), x[keep], x[keep] ** 2))
        coef, *_ = np.linalg.lstsq(A, y[keep], rcond=None)
        res = y - (coef[0] + coef[1] * x + coef[2] * x * x)
        keep = np.abs(res) < trim_m
    a, b, c = (float(v) for v in coef)
    n = int(keep.sum())
    span = float(np.ptp(x[keep])) if n else 0.0
    conf = min(1.0, n / 30.0) * min(1.0, span / 2.0)
    return SingleRowEstimate(a * math.cos(math.atan(b)), -math.atan(b), 2.0 * c / (1.0 + b * b) ** 1.5, conf, n)


@dataclass(frozen=True)
class ProximityFollowerParams:
    """Follow one row at ``distance_m`` from its centre line (ref 000 follows at 1 m).

    ``row_half_width_m`` is the distance from the row's centre line to the face the laser sees (half
    the canopy width, a field parameter); 0 follows the face itself. The row is estimated from a short
    map of its face: each scan's row points go, through the robot's odometry (speed and yaw rate), into
    a buffer that keeps the face seen over the last ``window_back_m`` of travel; a curve of degree
    ``fit_degree`` is fitted to it over ``[-window_back_m, window_ahead_m]`` around the robot (0.1 m bins,
    so every stretch of row counts the same however many beams hit it; bins more than ``trim_m`` off the
    curve are dropped). With ``smooth_cutoff_m`` > 0 (the default) the curve is not a polynomial but a
    third-difference smoother on a 0.2 m grid whose cut-off wavelength is ``smooth_cutoff_m``: bends of the
    row longer than that pass (a 24 m wave loses 0.14 %), while the bushes' own scatter, a metre or two long, is
    averaged out better than a cubic over the same window does. ``curvature_filter_m`` is the travel over which
    the curvature feed-forward is averaged. ``map_motion``: the map follows the robot through ``obs.pose`` (the
    default: on the robot the firmware's odometry pose, integrated from the encoders at 50 Hz; it must not jump,
    so not a pose corrected by landmarks) or by integrating ``obs.speed_m_s`` / ``obs.yaw_rate_rad_s`` at the
    scan rate ("velocity": for a pose source that jumps; in the SIL it spread the distance by 1-3 cm more,
    the firmware's velocities arriving late and coarse)."""

    side: str = "right"  # the row is on this side of the robot
    distance_m: float = 1.0
    row_half_width_m: float = 0.0
    speed_m_s: float = 0.5
    omega_n_rad_s: float = 1.0
    zeta: float = 0.9
    limits: DriveLimits = field(default_factory=DriveLimits)
    mount: Pose2D = field(default_factory=Pose2D)
    scan: ScanParams = field(default_factory=ScanParams)
    x_min_m: float = -1.0  # scan points used from this far behind the robot ...
    x_max_m: float = 5.5  # ... to this far ahead
    window_back_m: float = 6.0
    window_ahead_m: float = 5.0
    fit_degree: int = 3
    bin_m: float = 0.1
    trim_m: float = 0.1
    gate_m: float = 0.3
    curvature_filter_m: float = 1.0
    smooth_cutoff_m: float = 8.0  # > 0: the face is a smooth curve passing bends longer than this (0: the polynomial)
    meas_std_m: float = 0.02
    meas_std_rad: float = 0.03
    process_std_m: float = 0.01
    process_std_rad: float = 0.05
    map_motion: str = "pose"  # how the row map follows the robot: "pose" (obs.pose) or "velocity" (speed, yaw rate)

    def __post_init__(self) -> None:
        if self.side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {self.side!r}")
        if self.map_motion not in ("pose", "velocity"):
            raise ValueError(f"map_motion must be 'pose' or 'velocity', got {self.map_motion!r}")
        if not (self.distance_m > 0 and self.speed_m_s > 0):
            raise ValueError("ProximityFollowerParams: distance_m and speed_m_s must be > 0")
        if not (self.window_back_m >= 0 and self.window_ahead_m > 0 and self.bin_m > 0 and 1 <= self.fit_degree <= 3
                and self.smooth_cutoff_m >= 0):
            raise ValueError("ProximityFollowerParams: windows and bin_m must be > 0, fit_degree 1-3, smooth_cutoff_m >= 0")


class _RowFaceMap:
    """The row's face over the last metres of travel, in an odometry frame (the robot's pose, or dead
    reckoning from its speed and yaw rate), and the curve fitted to it around the robot."""

    def __init__(self, p: ProximityFollowerParams) -> None:
        self.p = p
        self.sgn = 1.0 if p.side == "left" else -1.0
        self.pose = np.zeros(3)  # odometry x, y, yaw
        self.s = 0.0  # travel, m
        self._t: float | None = None
        self._vw = (0.0, 0.0)
        # the map: face points in the odometry frame, how many returns each averages, the travel when seen
        self._xy = np.zeros((0, 2))
        self._wt = np.zeros(0)
        self._seen_s = np.zeros(0)
        self.coef: npt.NDArray[np.floating[Any]] | None = None  # y = sum coef[i] x^i in the robot frame at fit_pose
        self.fit_pose = np.zeros(3)

    def moved_to(self, t: float, pose: Pose2D) -> None:
        """Follow the robot by its pose (an odometry pose that does not jump)."""
        p = np.array([pose.x_m, pose.y_m, pose.yaw_rad])
        if self._t is not None:
            self.s += math.hypot(p[0] - self.pose[0], p[1] - self.pose[1])
        self.pose = p
        self._t = t

    def odometry(self, t: float, v: float, w: float) -> None:
        if self._t is not None:
            dt = max(0.0, t - self._t)
            vm, wm = 0.5 * (self._vw[0] + v), 0.5 * (self._vw[1] + w)
            th = self.pose[2] + 0.5 * wm * dt
            self.pose = self.pose + np.array([vm * math.cos(th) * dt, vm * math.sin(th) * dt, wm * dt])
            self.s += abs(vm) * dt
        self._t = t
        self._vw = (v, w)

    def _to_frame(self, frame: FloatArray, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        c, s = math.cos(frame[2]), math.sin(frame[2])
        dx, dy = xy[:, 0] - frame[0], xy[:, 1] - frame[1]
        return c * dx + s * dy, -s * dx + c * dy

    def add_scan(self, pts: ScanPoints) -> None:
        p, sgn = self.p, self.sgn
        x, y = pts.xy[:, 0], pts.xy[:, 1]
        c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
        odo = np.column_stack((self.pose[0] + c * x - s * y, self.pose[1] + s * x + c * y))
        sel = (x >= p.x_min_m) & (x <= p.x_max_m) & (sgn * y > 0.05)
        if self.coef is not None:
            fx, fy = self._to_frame(self.fit_pose, odo)
            sel &= np.abs(fy - np.polynomial.polynomial.polyval(fx, self.coef)) < p.gate_m
        else:  # first scan: gate by a single-scan fit of the near face
            # look for the face out to a metre beyond where it should be (at least the 2.5 m default)
            est = detect_single_row(pts, p.side, max_lateral_m=max(2.5, p.distance_m - p.row_half_width_m + 1.0))
            if est is None:
                return
            b0 = -math.tan(est.heading_rad)
            a0 = est.offset_m / math.cos(math.atan(b0))
            sel &= np.abs(y - (a0 + b0 * x + 0.5 * est.curvature_1_m * x * x)) < p.gate_m
        # thinned on arrival: the scan's points averaged per half fit bin along its own x (a curved row turns
        # less than a degree over a bin), kept with their counts so that fit() weighs every return as before
        xs, pts_sel = x[sel], odo[sel]
        if len(xs):
            b = np.floor((xs - p.x_min_m) / p.bin_m).astype(int)
            n = np.bincount(b)
            ok = n > 0
            mean = np.column_stack((np.bincount(b, pts_sel[:, 0])[ok], np.bincount(b, pts_sel[:, 1])[ok])) / n[ok, None]
            self._xy = np.concatenate((self._xy, mean))
            self._wt = np.concatenate((self._wt, n[ok].astype(float)))
            self._seen_s = np.concatenate((self._seen_s, np.full(len(mean), self.s)))
        first = int(np.searchsorted(self._seen_s, self.s - p.window_back_m - max(0.0, p.x_max_m)))
        if first:
            self._xy, self._wt, self._seen_s = self._xy[first:], self._wt[first:], self._seen_s[first:]

    def fit(self) -> SingleRowEstimate | None:
        p = self.p
        if not len(self._wt):
            return None
        rx, ry = self._to_frame(self.pose, self._xy)
        wt = self._wt
        m = (rx >= -p.window_back_m) & (rx <= p.window_ahead_m)
        rx, ry, wt = rx[m], ry[m], wt[m]
        if wt.sum() < 10:
            return None
        b = np.floor((rx + p.window_back_m) / p.bin_m).astype(int)
        n = cast(FloatArray, np.bincount(b, wt))  # with weights: float sums, not the int counts its stubs say
        ok = n > 0
        bx = np.bincount(b, rx * wt)[ok] / n[ok]
        by = np.bincount(b, ry * wt)[ok] / n[ok]
        if p.smooth_cutoff_m > 0 and np.ptp(bx) > 2.0:
            return self._fit_smooth(bx, by, n[ok])
        deg = p.fit_degree if np.ptp(bx) > 2.0 else min(p.fit_degree, 1)
        keep = np.ones(len(bx), dtype=bool)
        coef = None
        for _ in range(3):
            if keep.sum() < deg + 4:
                return None
            coef = np.polynomial.polynomial.polyfit(bx[keep], by[keep], deg)
            keep = np.abs(by - np.polynomial.polynomial.polyval(bx, coef)) < p.trim_m
        assert coef is not None
        self.coef, self.fit_pose = coef, self.pose.copy()
        a0 = float(coef[0])
        b1 = float(coef[1]) if deg >= 1 else 0.0
        c2 = float(coef[2]) if deg >= 2 else 0.0
        nk = int(keep.sum())
        span = float(np.ptp(bx[keep])) if nk else 0.0
        conf = min(1.0, nk / 20.0) * min(1.0, span / 2.0)
        return SingleRowEstimate(a0 * math.cos(math.atan(b1)), -math.atan(b1), 2.0 * c2 / (1.0 + b1 * b1) ** 1.5, conf, nk)


    def _fit_smooth(self, bx: FloatArray, by: FloatArray, counts: FloatArray) -> SingleRowEstimate | None:
        """The face as a smooth curve on the bin grid (a third-difference Whittaker smoother: a row bends
        over many metres, its bushes stand out over one or two); offset, heading and curvature at x = 0."""
        p = self.p
        h = max(p.bin_m, 0.2)  # grid step: an 11 m window is 56 unknowns (dense solves past ~100 are slow)
        m = int(round((p.window_back_m + p.window_ahead_m) / h)) + 1
        grid = -p.window_back_m + h * np.arange(m)
        idx = np.clip(np.round((bx + p.window_back_m) / h).astype(int), 0, m - 1)
        lam = (p.smooth_cutoff_m / (2.0 * math.pi * h)) ** 6
        D = np.diff(np.eye(m), 3, axis=0)
        P = lam * (D.T @ D)
        keep = np.ones(len(bx), dtype=bool)
        f = None
        for _ in range(3):
            if keep.sum() < 10:
                return None
            w = np.zeros(m)
            z = np.zeros(m)
            np.add.at(w, idx[keep], 1.0)
            np.add.at(z, idx[keep], by[keep])
            f = np.linalg.solve(np.diag(w) + P, z)
            keep = np.abs(by - f[idx]) < p.trim_m
        assert f is not None
        i0 = int(round(p.window_back_m / h))
        r1 = int(round(1.0 / h))
        near = slice(max(0, i0 - r1), min(m, i0 + r1 + 1))  # a quadratic through the curve over +-1 m
        a0, b1, c2 = (float(v) for v in np.polynomial.polynomial.polyfit(grid[near], f[near], 2))
        # the fitted curve stands in for the polynomial when gating the next scan's points
        self.coef, self.fit_pose = np.polynomial.polynomial.polyfit(grid, f, 3), self.pose.copy()
        nk = int(keep.sum())
        span = float(np.ptp(bx[keep])) if nk else 0.0
        conf = min(1.0, nk / 20.0) * min(1.0, span / 2.0)
        return SingleRowEstimate(a0 * math.cos(math.atan(b1)), -math.atan(b1), 2.0 * c2 / (1.0 + b1 * b1) ** 1.5, conf, nk)


class ProximityFollower:
    """Keep ``distance_m`` from one row's centre line while driving along it (module docstring law,
    with the row's curvature, averaged over ``curvature_filter_m`` of travel and moved to the parallel
    path, as feed-forward). The row comes from :class:`_RowFaceMap` (see the parameters)."""

    def __init__(self, params: ProximityFollowerParams | None = None) -> None:
        self.params = params or ProximityFollowerParams()
        self.reset()

    def reset(self) -> None:
        p = self.params
        self._kf = _TrackFilter(p.process_std_m, p.process_std_rad)
        self._map = _RowFaceMap(p)
        self.last: SingleRowEstimate | None = None
        self._kappa = 0.0
        self._kr: float | None = None
        self._s_prev = 0.0

    def distance_estimate_m(self) -> float | None:
        """Filtered distance from the row's centre line, m."""
        x = self._kf.x
        if x is None:
            return None
        return self.params.distance_m + (1.0 if self.params.side == "right" else -1.0) * float(x[0])

    def observe(self, obs: Observation) -> SingleRowEstimate | None:
        """Odometry and filter to ``obs.t_s``, then fold in the scan's row estimate (returned); no steering."""
        p = self.params
        sgn = 1.0 if p.side == "left" else -1.0
        if p.map_motion == "pose":
            self._map.moved_to(obs.t_s, obs.pose)
        else:
            self._map.odometry(obs.t_s, obs.speed_m_s, obs.yaw_rate_rad_s)
        self._kf.kappa = self._kappa
        self._kf.predict(obs.t_s, obs.speed_m_s, obs.yaw_rate_rad_s)
        if obs.scan is None:
            return None
        self._map.add_scan(points_from_scan(obs.scan, p.mount, p.scan))
        est = self._map.fit()
        if est is None or est.confidence <= 0.1:
            return est
        self.last = est
        centre = est.offset_m + sgn * p.row_half_width_m
        e = -(centre - sgn * p.distance_m)  # robot left of the wanted path: positive
        k = 1.0 / max(est.confidence, 0.05)
        self._kf.update(e, est.heading_rad, p.meas_std_m * k, p.meas_std_rad * k)
        ds = self._map.s - self._s_prev
        self._s_prev = self._map.s
        kr = est.curvature_1_m
        if self._kr is None:
            self._kr = kr
        else:
            self._kr += min(1.0, ds / max(p.curvature_filter_m, 1e-6)) * (kr - self._kr)
        # the parallel path at distance d on the row's right (sgn = +1) or left: radius R + sgn d
        self._kappa = self._kr / max(0.2, 1.0 + sgn * self._kr * p.distance_m)
        return est

    def step(self, obs: Observation) -> DriveCommand:
        p = self.params
        self.observe(obs)
        x = self._kf.x
        if x is None:
            return p.limits.command(0.5 * p.speed_m_s, 0.0)
        return _steer(p.limits, p.speed_m_s, float(x[0]), float(x[1]), self._kappa, p.omega_n_rad_s, p.zeta)


# ---- headland turn -------------------------------------------------------------------------------


def _arc(x: float, y: float, yaw: float, radius: float, sweep: float, step: float) -> FloatArray:
    """Poses (k, 3) along an arc of ``radius`` turning by ``sweep`` (left positive), excluding the start."""
    n = max(1, int(math.ceil(abs(sweep) * radius / step)))
    s = np.arange(1, n + 1) * (sweep / n)
    sg = 1.0 if sweep > 0 else -1.0
    cx, cy = x - sg * radius * math.sin(yaw), y + sg * radius * math.cos(yaw)
    th = yaw + s
    return np.column_stack((cx + sg * radius * np.sin(th), cy - sg * radius * np.cos(th), th))


def headland_path(shift_m: float, radius_m: float, step_m: float = 0.02) -> FloatArray:
    """A turn into the next row, in the frame of the row end: start at the origin heading +x, end at
    (0, shift_m) heading -x (positive shift: the next row is to the left). Poses (k, 3): x_m, y_m, yaw_rad.

    ``|shift| >= 2R``: a "pi" turn (quarter arc, straight, quarter arc). Otherwise an omega turn of
    three arcs of radius R: away from the next row by beta, towards it by pi + 2 beta, away by beta,
    with ``cos(beta) = (|shift| / (2 R) + 1) / 2`` (the path is symmetric about y = shift / 2)."""
    if not (radius_m > 0 and abs(shift_m) > 1e-6):
        raise ValueError("headland_path needs radius_m > 0 and a non-zero shift")
    sg = 1.0 if shift_m > 0 else -1.0
    d = abs(shift_m)
    pts = [np.array([[0.0, 0.0, 0.0]])]
    x, y, yaw = 0.0, 0.0, 0.0
    if d >= 2.0 * radius_m:
        segs = [(radius_m, sg * math.pi / 2, 0.0), (0.0, 0.0, d - 2.0 * radius_m), (radius_m, sg * math.pi / 2, 0.0)]
    else:
        beta = math.acos((d / (2.0 * radius_m) + 1.0) / 2.0)
        segs = [(radius_m, -sg * beta, 0.0), (radius_m, sg * (math.pi + 2 * beta), 0.0), (radius_m, -sg * beta, 0.0)]
    for r, sweep, straight in segs:
        if straight > 0:
            n = max(1, int(math.ceil(straight / step_m)))
            s = np.arange(1, n + 1) * (straight / n)
            seg = np.column_stack((x + s * math.cos(yaw), y + s * math.sin(yaw), np.full(n, yaw)))
        else:
            seg = _arc(x, y, yaw, r, sweep, step_m)
        pts.append(seg)
        x, y, yaw = (float(v) for v in seg[-1])
    return np.vstack(pts)


class HeadlandTurn:
    """Pure-pursuit tracking of a :func:`headland_path` laid at the pose given to :meth:`start`.

    ``done`` becomes True within ``finish_tol_m`` of the path's end. Poses come from ``obs.pose``
    (odometry on the robot, the true pose in the simulator)."""

    def __init__(self, limits: DriveLimits | None = None, speed_m_s: float = 0.3, lookahead_m: float = 0.25,
                 finish_tol_m: float = 0.12) -> None:
        self.limits = limits or DriveLimits()
        self.speed_m_s, self.lookahead_m, self.finish_tol_m = speed_m_s, lookahead_m, finish_tol_m
        self.path: FloatArray = np.zeros((0, 3))
        self.done = False
        self._i = 0

    def reset(self) -> None:
        self.path = np.zeros((0, 3))
        self.done = False
        self._i = 0

    def start(self, origin: Pose2D, shift_m: float, radius_m: float | None = None) -> None:
        """Lay the turn at ``origin`` (world pose on the current row's centre line, facing along it)."""
        if radius_m is not None:
            r = radius_m
        elif self.limits.kinematics == "diff_drive":  # a plain pi turn whenever the rows allow it
            r = max(self.limits.min_turn_radius_m, abs(shift_m) / 2.0)
        else:  # 10 % margin on the tightest steering circle
            r = 1.1 * self.limits.turn_radius_m
        local = headland_path(shift_m, r)
        c, s = math.cos(origin.yaw_rad), math.sin(origin.yaw_rad)
        self.path = np.column_stack((origin.x_m + c * local[:, 0] - s * local[:, 1], origin.y_m + s * local[:, 0] + c * local[:, 1],
                                     origin.yaw_rad + local[:, 2]))
        self.done = False
        self._i = 0

    def step(self, obs: Observation) -> DriveCommand:
        if len(self.path) == 0 or self.done:
            return DriveCommand()
        pose = obs.pose
        px, py = self.path[:, 0], self.path[:, 1]
        # progress index: nearest point within a short window ahead of the last one
        hi = min(len(self.path), self._i + 40)
        d = np.hypot(px[self._i:hi] - pose.x_m, py[self._i:hi] - pose.y_m)
        self._i += int(np.argmin(d))
        if self._i >= len(self.path) - 3 or math.hypot(px[-1] - pose.x_m, py[-1] - pose.y_m) < self.finish_tol_m:
            self.done = True
            return DriveCommand()
        dist = np.hypot(px[self._i:] - pose.x_m, py[self._i:] - pose.y_m)
        ahead = np.nonzero(dist >= self.lookahead_m)[0]
        j = self._i + (int(ahead[0]) if len(ahead) else len(dist) - 1)
        dx, dy = px[j] - pose.x_m, py[j] - pose.y_m
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        ld2 = max(lx * lx + ly * ly, 1e-6)
        kappa = 2.0 * ly / ld2
        v = self.speed_m_s
        if self.limits.kinematics == "diff_drive" and lx < 0:  # target behind: turn towards it on the spot
            return self.limits.command(0.0, math.copysign(self.limits.max_yaw_rate_rad_s, ly))
        return self.limits.command(v, v * kappa)
