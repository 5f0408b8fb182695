"""Shared typed records for the host library and the simulator.

Every physical field carries its unit in its name (``_m``, ``_m_s``, ``_rad``, ``_rad_s``, ``_s``).
Frames follow REP-103: x forward, y left, z up; angles counter-clockwise positive, so a positive
steering angle or yaw rate turns the robot to the left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TypeAlias, overload

import numpy as np
import numpy.typing as npt

FloatArray: TypeAlias = npt.NDArray[np.float64]
#: n x 2 array of points in metres (x, y), world or sensor frame as documented by the producer.
ScanXY: TypeAlias = npt.NDArray[np.float64]
#: n x 4 array of segments in metres (x0, y0, x1, y1).
Segments: TypeAlias = npt.NDArray[np.float64]
#: n x 3 array of circles in metres (cx, cy, radius).
Circles: TypeAlias = npt.NDArray[np.float64]


@overload
def norm_angle_rad(a: float) -> float: ...
@overload
def norm_angle_rad(a: FloatArray) -> FloatArray: ...
def norm_angle_rad(a: float | FloatArray) -> float | FloatArray:
    """Wrap an angle, or every angle of an array, to [-pi, pi). Input and output in rad."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Pose2D:
    """Planar pose: position in m, heading in rad (0 = +x, CCW positive)."""

    x_m: float = 0.0
    y_m: float = 0.0
    yaw_rad: float = 0.0

    def distance_to(self, other: "Pose2D") -> float:
        """Euclidean distance between positions, m."""
        return math.hypot(other.x_m - self.x_m, other.y_m - self.y_m)

    def compose(self, other: "Pose2D") -> "Pose2D":
        """self (+) other: other is expressed in self's frame."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return Pose2D(
            self.x_m + c * other.x_m - s * other.y_m,
            self.y_m + s * other.x_m + c * other.y_m,
            norm_angle_rad(self.yaw_rad + other.yaw_rad),
        )


@dataclass(frozen=True)
class DriveCommand:
    """Physical drive setpoint, as the host sends it to the firmware.

    ``speed_m_s`` is the forward speed of the robot's reference point (axle centre for a differential
    drive, rear-axle centre for Ackermann). ``yaw_rate_rad_s`` is used by differential drives (and
    converted to a steering angle for Ackermann when ``steer_rad`` is None). ``steer_rad`` is the
    virtual middle front-wheel angle of an Ackermann robot, positive = left.
    """

    speed_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    steer_rad: float | None = None


@dataclass(frozen=True)
class PwmCommand:
    """Raw actuator command in calibration-table PWM units (see :mod:`agnav_host.calib`)."""

    steer_pwm: float
    speed_pwm: float


@dataclass(frozen=True)
class LaserScan:
    """One planar laser scan.

    Beam i points at ``angle_min_rad + i * angle_increment_rad`` in the sensor frame (0 = forward,
    CCW positive). ``ranges_m`` holds NaN, inf or 0 where there was no return.
    """

    angle_min_rad: float
    angle_increment_rad: float
    ranges_m: FloatArray
    range_max_m: float = math.inf
    stamp_s: float = 0.0
    pose: Pose2D | None = None  # sensor pose in the world frame when known

    @property
    def angles_rad(self) -> FloatArray:
        """Beam angles in the sensor frame, rad, shape (n,)."""
        return self.angle_min_rad + self.angle_increment_rad * np.arange(len(self.ranges_m), dtype=np.float64)

    @property
    def full_circle(self) -> bool:
        """True when the beams go all the way round (the last one beside the first: no edge of view)."""
        n, step = len(self.ranges_m), abs(self.angle_increment_rad)
        return n > 2 and step * n >= 2.0 * math.pi - 0.5 * step

    def from_first_beam_rad(self, angles_rad: FloatArray) -> FloatArray:
        """How far sensor-frame angles lie from the first beam in the laser's own sense of turn, in
        [0, 2 pi): whatever its start angle (-pi..pi or 0..2 pi) and whether it turns clockwise. Beam k is
        at ``k * abs(angle_increment_rad)``; beyond the last beam is outside the field of view."""
        sgn = 1.0 if self.angle_increment_rad >= 0 else -1.0
        return np.mod(sgn * (np.asarray(angles_rad, dtype=float) - self.angle_min_rad), 2.0 * math.pi)

    def valid_mask(self) -> npt.NDArray[np.bool_]:
        """True where the beam has a usable return (finite and > 0), shape (n,)."""
        r = self.ranges_m
        return np.isfinite(r) & (r > 0.0)

    def xy(self) -> ScanXY:
        """Valid returns as points in the sensor frame, m, shape (k, 2)."""
        m = self.valid_mask()
        a = self.angles_rad[m]
        r = self.ranges_m[m]
        return np.column_stack((r * np.cos(a), r * np.sin(a)))


@dataclass(frozen=True)
class SonarFrame:
    """One sonar-ring measurement cycle.

    Arrays have one entry per sensor. ``echo_us`` is the round-trip echo time in microseconds (NaN:
    no echo / not fired); ``ranges_m`` is the matching one-way range (NaN: no echo).
    """

    stamp_s: float
    fired: npt.NDArray[np.bool_]
    echo_us: FloatArray
    ranges_m: FloatArray


@dataclass(frozen=True)
class EncoderEdges:
    """Edge stream of one wheel encoder.

    ``times_s`` (n,) are edge times in s, ascending. ``ab`` (n,) is the level pair after each edge as
    ``(A << 1) | B`` (the byte ``sim_encoder_edge()`` takes); in Hall mode only A toggles (B = 0).
    """

    times_s: FloatArray
    ab: npt.NDArray[np.uint8]


@dataclass(frozen=True)
class Goal:
    """A navigation goal: position in m, optional heading (rad) and optional arrival time (s)."""

    x_m: float
    y_m: float
    yaw_rad: float | None = None
    arrival_s: float | None = None
    tolerance_m: float = 0.3


@dataclass
class Observation:
    """What a host planner / firmware stand-in sees at one control step."""

    t_s: float
    pose: Pose2D
    speed_m_s: float
    yaw_rate_rad_s: float
    goal: Goal
    scan: LaserScan | None = None
    sonar: SonarFrame | None = None
    extras: dict[str, object] = field(default_factory=dict)
