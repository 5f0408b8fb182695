"""Robot motion models: differential drive and Ackermann (car-like), with actuator effects.

Both models keep a pose at their reference point (centre of the drive axle for a differential drive,
centre of the rear axle for Ackermann) and integrate constant-curvature arcs exactly over each step.
Actuator effects, in the order they are applied to each step's command:

1. calibration (Ackermann with tables): physical command -> PWM through the *controller's* tables,
   PWM -> physical through the robot's *true* tables (dead band and saturation included);
2. motor dead band (wheel speed commands below ``deadband_m_s`` give 0);
3. first-order lag ``dv/dt = (v_cmd - v) / tau``, integrated exactly over the step;
4. acceleration limit (and a steering-rate limit for the servo);
5. wheel slip: the ground speed is the wheel's rim speed times (1 + N(0, slip_std)).

Wheel angles integrate the rim speed (before slip), so encoders read what the wheels did, not what
the robot did, and odometry drifts under slip just as on a real robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..calib import CalibTable
from ..types import DriveCommand, Pose2D, PwmCommand, norm_angle_rad

__all__ = ["DiffDriveParams", "DiffDrive", "AckermannParams", "Ackermann", "integrate_arc", "Robot", "SlipNoise"]


class SlipNoise(Protocol):
    """The random source of the wheel slip: ``normal(0, slip_std, 2)`` gives two draws (a numpy Generator,
    or anything that serves the same normals)."""

    def normal(self, loc: float, scale: float, size: int) -> Any: ...


def integrate_arc(x: float, y: float, yaw: float, v: float, w: float, dt: float) -> tuple[float, float, float]:
    """Exact pose after moving at constant speed v (m/s) and yaw rate w (rad/s) for dt (s)."""
    dth = w * dt
    if abs(dth) < 1e-9:
        # second-order series of the arc for tiny turns
        c = math.cos(yaw + 0.5 * dth)
        s = math.sin(yaw + 0.5 * dth)
        return x + v * dt * c, y + v * dt * s, yaw + dth
    r = v / w
    return (
        x + r * (math.sin(yaw + dth) - math.sin(yaw)),
        y - r * (math.cos(yaw + dth) - math.cos(yaw)),
        yaw + dth,
    )


def _lag(current: float, target: float, dt: float, tau_s: float, accel_max: float) -> float:
    """First-order lag towards target, then a rate limit of accel_max per second."""
    nxt = target if tau_s <= 0.0 else target + (current - target) * math.exp(-dt / tau_s)
    dmax = accel_max * dt
    return current + max(-dmax, min(dmax, nxt - current))


@dataclass(frozen=True)
class DiffDriveParams:
    """Differential drive. Defaults: the 0.45 m diameter robots of refs 001/002."""

    radius_m: float = 0.225  # footprint circle, centred on the reference point
    track_m: float = 0.40  # wheel separation
    wheel_radius_m: float = 0.127  # 10-inch wheels (ref 001)
    max_wheel_speed_m_s: float = 1.0
    max_accel_m_s2: float = 1.5  # per wheel
    tau_s: float = 0.12  # motor first-order lag
    deadband_m_s: float = 0.02  # wheel speed commands below this give 0
    slip_std: float = 0.01  # relative wheel slip noise (1 sigma)

    def __post_init__(self) -> None:
        for k in ("radius_m", "track_m", "wheel_radius_m", "max_wheel_speed_m_s", "max_accel_m_s2"):
            if not getattr(self, k) > 0:
                raise ValueError(f"DiffDriveParams.{k} must be > 0, got {getattr(self, k)}")
        for k in ("tau_s", "deadband_m_s", "slip_std"):
            if getattr(self, k) < 0:
                raise ValueError(f"DiffDriveParams.{k} must be >= 0, got {getattr(self, k)}")

    @staticmethod
    def ideal(**kw: float) -> "DiffDriveParams":
        """No lag, no dead band, no slip, (practically) unlimited acceleration: pure kinematics."""
        base: dict[str, float] = dict(tau_s=0.0, deadband_m_s=0.0, slip_std=0.0, max_accel_m_s2=1e9, max_wheel_speed_m_s=1e9)
        base.update(kw)
        return DiffDriveParams(**base)


@dataclass
class DiffDrive:
    """Differential-drive robot state and step function."""

    params: DiffDriveParams = field(default_factory=DiffDriveParams)
    pose: Pose2D = field(default_factory=Pose2D)
    v_left_m_s: float = 0.0  # wheel rim speeds after lag (what the motors do)
    v_right_m_s: float = 0.0
    wheel_angles_rad: np.ndarray = field(default_factory=lambda: np.zeros(2))  # left, right
    speed_m_s: float = 0.0  # body speed over ground, last step
    yaw_rate_rad_s: float = 0.0
    kind: str = "diff_drive"

    @property
    def radius_m(self) -> float:
        return self.params.radius_m

    def footprint_centre(self) -> tuple[float, float]:
        return self.pose.x_m, self.pose.y_m

    def wheel_targets(self, cmd: DriveCommand) -> tuple[float, float]:
        """Wheel rim speed targets (left, right) in m/s for a command, after saturation and dead band."""
        p = self.params
        half = 0.5 * p.track_m * cmd.yaw_rate_rad_s
        vl, vr = cmd.speed_m_s - half, cmd.speed_m_s + half
        m = max(abs(vl), abs(vr))
        if m > p.max_wheel_speed_m_s:  # scale both, keeping the curvature
            vl, vr = vl * p.max_wheel_speed_m_s / m, vr * p.max_wheel_speed_m_s / m
        vl = 0.0 if abs(vl) < p.deadband_m_s else vl
        vr = 0.0 if abs(vr) < p.deadband_m_s else vr
        return vl, vr

    def step(self, cmd: DriveCommand, dt_s: float, rng: SlipNoise | None = None) -> None:
        """Advance dt_s seconds under a physical command (speed + yaw rate; steer_rad is ignored)."""
        p = self.params
        tl, tr = self.wheel_targets(cmd)
        self.v_left_m_s = _lag(self.v_left_m_s, tl, dt_s, p.tau_s, p.max_accel_m_s2)
        self.v_right_m_s = _lag(self.v_right_m_s, tr, dt_s, p.tau_s, p.max_accel_m_s2)
        self.wheel_angles_rad = self.wheel_angles_rad + np.array([self.v_left_m_s, self.v_right_m_s]) * dt_s / p.wheel_radius_m
        gl, gr = self.v_left_m_s, self.v_right_m_s
        if rng is not None and p.slip_std > 0:
            n = rng.normal(0.0, p.slip_std, 2)
            gl, gr = gl * (1.0 + n[0]), gr * (1.0 + n[1])
        v = 0.5 * (gl + gr)
        w = (gr - gl) / p.track_m
        x, y, yaw = integrate_arc(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, v, w, dt_s)
        self.pose = Pose2D(x, y, norm_angle_rad(yaw))
        self.speed_m_s, self.yaw_rate_rad_s = v, w

    def reset(self, pose: Pose2D) -> None:
        self.pose = pose
        self.v_left_m_s = self.v_right_m_s = self.speed_m_s = self.yaw_rate_rad_s = 0.0
        self.wheel_angles_rad = np.zeros(2)


@dataclass(frozen=True)
class AckermannParams:
    """Car-like robot. Defaults: the ref-003 RC car (wheelbase 174 mm, track 191 mm, wheels 69 mm,
    steering to 24.6 deg, speed 43.5-200 cm/s through the PWM tables)."""

    wheelbase_m: float = 0.174
    track_m: float = 0.191
    wheel_radius_m: float = 0.0345
    radius_m: float = 0.16  # footprint circle, centred half a wheelbase ahead of the rear axle
    max_steer_rad: float = math.radians(24.6)
    max_speed_m_s: float = 2.0
    max_accel_m_s2: float = 2.0
    speed_tau_s: float = 0.25
    steer_tau_s: float = 0.05
    max_steer_rate_rad_s: float = math.radians(300.0)  # hobby servo, ~0.2 s per 60 deg
    deadband_m_s: float = 0.0  # used only without tables; the speed table has its own dead band
    slip_std: float = 0.01
    # tables: (true = what the hardware does, ctrl = what the controller believes); None = ideal
    true_steer: CalibTable | None = None
    true_speed: CalibTable | None = None
    ctrl_steer: CalibTable | None = None
    ctrl_speed: CalibTable | None = None

    def __post_init__(self) -> None:
        for k in ("wheelbase_m", "track_m", "wheel_radius_m", "radius_m", "max_steer_rad", "max_speed_m_s", "max_accel_m_s2"):
            if not getattr(self, k) > 0:
                raise ValueError(f"AckermannParams.{k} must be > 0, got {getattr(self, k)}")
        if self.max_steer_rad >= math.pi / 2:
            raise ValueError("AckermannParams.max_steer_rad must be below 90 deg")
        if (self.true_steer is None) != (self.ctrl_steer is None) or (self.true_speed is None) != (self.ctrl_speed is None):
            raise ValueError("AckermannParams: give both the true and the controller table, or neither")

    @staticmethod
    def ideal(**kw: object) -> "AckermannParams":
        """No tables, lag, slip or acceleration limit: pure bicycle kinematics."""
        base: dict[str, object] = dict(speed_tau_s=0.0, steer_tau_s=0.0, slip_std=0.0, max_accel_m_s2=1e9, max_steer_rate_rad_s=1e9)
        base.update(kw)
        return AckermannParams(**base)  # type: ignore[arg-type]


@dataclass
class Ackermann:
    """Ackermann robot (bicycle model about the rear-axle centre)."""

    params: AckermannParams = field(default_factory=AckermannParams)
    pose: Pose2D = field(default_factory=Pose2D)
    steer_rad: float = 0.0  # actual virtual front-wheel angle
    rim_speed_m_s: float = 0.0  # driven (rear) wheel rim speed after lag
    wheel_angles_rad: np.ndarray = field(default_factory=lambda: np.zeros(2))  # rear left, rear right
    speed_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    last_pwm: PwmCommand | None = None
    kind: str = "ackermann"

    @property
    def radius_m(self) -> float:
        return self.params.radius_m

    def footprint_centre(self) -> tuple[float, float]:
        h = 0.5 * self.params.wheelbase_m
        return self.pose.x_m + h * math.cos(self.pose.yaw_rad), self.pose.y_m + h * math.sin(self.pose.yaw_rad)

    def physical_targets(self, cmd: DriveCommand) -> tuple[float, float]:
        """(steer_rad, speed_m_s) the hardware aims for under a physical command."""
        p = self.params
        steer = cmd.steer_rad
        if steer is None:
            steer = math.atan(p.wheelbase_m * cmd.yaw_rate_rad_s / cmd.speed_m_s) if abs(cmd.speed_m_s) > 1e-6 else 0.0
        if p.ctrl_steer is not None and p.true_steer is not None and p.ctrl_speed is not None and p.true_speed is not None:
            pwm = PwmCommand(p.ctrl_steer.pwm_from_value(steer), p.ctrl_speed.pwm_from_value(cmd.speed_m_s))
            return self.pwm_targets(pwm)
        if p.true_steer is None:
            steer = max(-p.max_steer_rad, min(p.max_steer_rad, steer))
        speed = max(-p.max_speed_m_s, min(p.max_speed_m_s, cmd.speed_m_s))
        if abs(speed) < p.deadband_m_s:
            speed = 0.0
        return steer, speed

    def pwm_targets(self, pwm: PwmCommand) -> tuple[float, float]:
        """(steer_rad, speed_m_s) the hardware produces for raw PWM, through the true tables."""
        p = self.params
        if p.true_steer is None or p.true_speed is None:
            raise ValueError("raw PWM needs true calibration tables (AckermannParams.true_steer/true_speed)")
        self.last_pwm = pwm
        steer = float(p.true_steer.value_from_pwm(pwm.steer_pwm))
        speed = float(p.true_speed.value_from_pwm(pwm.speed_pwm))
        return steer, speed

    def step(self, cmd: DriveCommand | PwmCommand, dt_s: float, rng: SlipNoise | None = None) -> None:
        """Advance dt_s under a physical command or raw PWM."""
        target = self.pwm_targets(cmd) if isinstance(cmd, PwmCommand) else self.physical_targets(cmd)
        self._advance(target[0], target[1], dt_s, rng)

    def _advance(self, steer_t: float, speed_t: float, dt_s: float, rng: SlipNoise | None) -> None:
        p = self.params
        self.steer_rad = _lag(self.steer_rad, steer_t, dt_s, p.steer_tau_s, p.max_steer_rate_rad_s)
        self.rim_speed_m_s = _lag(self.rim_speed_m_s, speed_t, dt_s, p.speed_tau_s, p.max_accel_m_s2)
        v_rim = self.rim_speed_m_s
        # rear wheels on an arc: inner and outer rim speeds differ by the track (open differential)
        w_nom = v_rim * math.tan(self.steer_rad) / p.wheelbase_m
        self.wheel_angles_rad = self.wheel_angles_rad + np.array(
            [v_rim - 0.5 * p.track_m * w_nom, v_rim + 0.5 * p.track_m * w_nom]
        ) * dt_s / p.wheel_radius_m
        v = v_rim
        w = w_nom
        if rng is not None and p.slip_std > 0:
            n = rng.normal(0.0, p.slip_std, 2)
            v *= 1.0 + n[0]
            w *= 1.0 + n[1]
        x, y, yaw = integrate_arc(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, v, w, dt_s)
        self.pose = Pose2D(x, y, norm_angle_rad(yaw))
        self.speed_m_s, self.yaw_rate_rad_s = v, w

    def reset(self, pose: Pose2D) -> None:
        self.pose = pose
        self.steer_rad = self.rim_speed_m_s = self.speed_m_s = self.yaw_rate_rad_s = 0.0
        self.wheel_angles_rad = np.zeros(2)
        self.last_pwm = None


Robot = DiffDrive | Ackermann
