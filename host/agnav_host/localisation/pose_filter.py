"""Extended Kalman filter over the planar pose (x, y, yaw): odometry moves it, post sightings correct it.

Prediction. The firmware reports its odometry pose (in its own frame, which starts at the start
pose) about every 100 ms. The increment between two reports, expressed in the earlier report's
body frame, is applied to the estimate (the first report's increment is from the odometry origin, so
the estimate becomes the start pose composed with the reported pose) (odometry is good over short stretches and drifts over long
ones); its noise grows with the distance driven and the angle turned (``FilterParams``).

Latency. A report describes the robot at the firmware time it was stamped (``time_boot_ms``), up to
a report period plus the radio delay before the host uses it. The filter keeps the estimate at the
stamp of the last report and :func:`extrapolate` carries it to any later time with the reported
speed and yaw rate (a constant-twist arc); a laser sighting is compared with the pose extrapolated to
the scan's time. The firmware's clock is the host's (``time_boot_ms`` of the same boot); a real host
must synchronise the two first.

Correction. Each post sighting (range and bearing of the post's centre from the laser) is one EKF
update with a numerical Jacobian; a sighting whose innovation is beyond ``gate_sigma`` standard
deviations is rejected (wrong association, a person next to the post).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import FloatArray, Pose2D, norm_angle_rad
from .landmarks import LandmarkMap, PostSighting

__all__ = ["FilterParams", "PoseFilter", "compose", "relative", "extrapolate"]


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """a (+) b: ``b`` expressed in ``a``'s frame, brought to the world."""
    return a.compose(b)


def relative(a: Pose2D, b: Pose2D) -> Pose2D:
    """``b`` expressed in ``a``'s frame (the inverse of :func:`compose`: a (+) relative(a, b) = b)."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    dx, dy = b.x_m - a.x_m, b.y_m - a.y_m
    return Pose2D(c * dx + s * dy, -s * dx + c * dy, norm_angle_rad(b.yaw_rad - a.yaw_rad))


def extrapolate(p: Pose2D, speed_m_s: float, yaw_rate_rad_s: float, dt_s: float) -> Pose2D:
    """Pose after ``dt_s`` on a constant-twist arc (speed along the heading, constant yaw rate)."""
    if dt_s <= 0.0:
        return p
    d = speed_m_s * dt_s
    dth = yaw_rate_rad_s * dt_s
    if abs(dth) < 1e-9:
        step = Pose2D(d, 0.0, 0.0)
    else:
        rad = d / dth
        step = Pose2D(rad * math.sin(dth), rad * (1.0 - math.cos(dth)), dth)
    return p.compose(step)


@dataclass(frozen=True)
class FilterParams:
    """Noise model (1 sigma). Odometry: ``odo_along`` and ``odo_across`` per metre driven (slip, tick
    quantisation), ``odo_yaw_per_m`` rad per metre plus ``odo_yaw_per_rad`` of the angle turned
    (steering error). Sightings: ``range_sigma_m``, ``bearing_sigma_rad``. ``init_sigma_*``: how well
    the start pose is known. ``gate_sigma``: innovations beyond this many sigmas are rejected."""

    odo_along: float = 0.03
    odo_across: float = 0.03
    odo_yaw_per_m: float = math.radians(1.0)
    odo_yaw_per_rad: float = 0.05
    range_sigma_m: float = 0.03
    bearing_sigma_rad: float = math.radians(1.0)
    init_sigma_m: float = 0.02
    init_sigma_rad: float = math.radians(1.0)
    gate_sigma: float = 3.5

    def __post_init__(self) -> None:
        for k in ("range_sigma_m", "bearing_sigma_rad", "init_sigma_m", "init_sigma_rad", "gate_sigma"):
            if not getattr(self, k) > 0:
                raise ValueError(f"FilterParams.{k} must be > 0")


def odometry_step(yaw_rad: float, d: Pose2D, p: FilterParams) -> tuple[FloatArray, FloatArray, FloatArray]:
    """An odometry increment ``d`` (robot frame) from a pose of heading ``yaw_rad``: the Jacobians of pose (+) d
    with respect to the pose (F) and to d (G), and the increment's noise Q (:class:`FilterParams`)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    F = np.array([[1.0, 0.0, -s * d.x_m - c * d.y_m], [0.0, 1.0, c * d.x_m - s * d.y_m], [0.0, 0.0, 1.0]])
    G = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    dist = math.hypot(d.x_m, d.y_m)
    Q = np.diag([(p.odo_along * dist) ** 2 + 1e-8, (p.odo_across * dist) ** 2 + 1e-8,
                 (p.odo_yaw_per_m * dist + p.odo_yaw_per_rad * abs(d.yaw_rad)) ** 2 + 1e-10])
    return F, G, Q


def _range_bearing(pose: Pose2D, mount: Pose2D, lx: float, ly: float) -> tuple[float, float]:
    sen = pose.compose(mount)
    dx, dy = lx - sen.x_m, ly - sen.y_m
    return math.hypot(dx, dy), norm_angle_rad(math.atan2(dy, dx) - sen.yaw_rad)


class PoseFilter:
    """See the module docstring. ``posts``: the surveyed posts; ``mount``: laser pose on the robot."""

    def __init__(self, start: Pose2D, posts: LandmarkMap | None, mount: Pose2D = Pose2D(),
                 params: FilterParams | None = None) -> None:
        self.params = params or FilterParams()
        self.posts = posts
        self.mount = mount
        p = self.params
        self.pose = start  # estimate at the stamp of the last odometry report
        self.P = np.diag([p.init_sigma_m ** 2, p.init_sigma_m ** 2, p.init_sigma_rad ** 2])
        self.stamp_s: float | None = None
        self.speed_m_s = 0.0
        self.yaw_rate_rad_s = 0.0
        self._last_odo = Pose2D()  # the odometry frame's origin is the start pose
        self.updates = 0
        self.rejected = 0

    # ---- prediction ------------------------------------------------------------------------------
    def odometry(self, odo_pose: Pose2D, stamp_s: float, speed_m_s: float, yaw_rate_rad_s: float) -> None:
        """A new odometry report (pose in the odometry frame, which starts at ``start``; its stamp,
        speed, yaw rate). The first report moves the estimate from ``start`` by the whole reported pose
        (start (+) odo_pose), each later one by the increment since the previous report. Reports with a
        stamp not newer than the last one are ignored (a repeated or late frame)."""
        if self.stamp_s is not None and stamp_s <= self.stamp_s:
            return
        self._move(relative(self._last_odo, odo_pose))
        self._last_odo = odo_pose
        self.stamp_s = stamp_s
        self.speed_m_s = speed_m_s
        self.yaw_rate_rad_s = yaw_rate_rad_s

    def _move(self, d: Pose2D) -> None:
        F, G, Q = odometry_step(self.pose.yaw_rad, d, self.params)
        self.pose = self.pose.compose(d)
        self.P = F @ self.P @ F.T + G @ Q @ G.T

    def pose_at(self, t_s: float) -> Pose2D:
        """The estimate carried from the last report's stamp to ``t_s`` (see :func:`extrapolate`)."""
        if self.stamp_s is None:
            return self.pose
        return extrapolate(self.pose, self.speed_m_s, self.yaw_rate_rad_s, min(t_s - self.stamp_s, 0.5))

    # ---- correction ------------------------------------------------------------------------------
    def sightings(self, seen: list[PostSighting], t_s: float) -> int:
        """Correct with post sightings of a scan taken at ``t_s``; returns how many were used."""
        if self.posts is None or not seen:
            return 0
        p = self.params
        R = np.diag([p.range_sigma_m ** 2, p.bearing_sigma_rad ** 2])
        dt = 0.0 if self.stamp_s is None else min(max(t_s - self.stamp_s, 0.0), 0.5)
        used = 0
        for sg in seen:
            lx, ly = float(self.posts.xy[sg.index, 0]), float(self.posts.xy[sg.index, 1])
            base = self.pose

            def h(v: FloatArray, lx: float = lx, ly: float = ly) -> FloatArray:
                q = extrapolate(Pose2D(float(v[0]), float(v[1]), float(v[2])), self.speed_m_s, self.yaw_rate_rad_s, dt)
                return np.array(_range_bearing(q, self.mount, lx, ly))

            x0 = np.array([base.x_m, base.y_m, base.yaw_rad])
            z_hat = h(x0)
            H = np.zeros((2, 3))
            for k, eps in enumerate((1e-4, 1e-4, 1e-5)):
                dx = np.zeros(3)
                dx[k] = eps
                dz = h(x0 + dx) - z_hat
                dz[1] = norm_angle_rad(float(dz[1]))
                H[:, k] = dz / eps
            nu = np.array([sg.range_m - z_hat[0], norm_angle_rad(sg.bearing_rad - float(z_hat[1]))])
            S = H @ self.P @ H.T + R
            Si = np.linalg.inv(S)
            if float(nu @ Si @ nu) > p.gate_sigma ** 2:
                self.rejected += 1
                continue
            K = self.P @ H.T @ Si
            x = x0 + K @ nu
            self.pose = Pose2D(float(x[0]), float(x[1]), norm_angle_rad(float(x[2])))
            IKH = np.eye(3) - K @ H
            self.P = IKH @ self.P @ IKH.T + K @ R @ K.T  # Joseph form: stays symmetric and positive
            used += 1
        self.updates += used
        return used

    @property
    def sigma(self) -> tuple[float, float, float]:
        """1-sigma of x, y (m) and yaw (rad)."""
        d = np.sqrt(np.maximum(np.diag(self.P), 0.0))
        return float(d[0]), float(d[1]), float(d[2])
