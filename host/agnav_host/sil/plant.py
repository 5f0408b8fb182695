"""The world side of the SIL: robot model, world and sensors wired to the firmware's pins.

* Outputs -> robot. Ackermann: steering servo pulse -> command byte
  (``byte = (us - 1000) * 255 / 1000``) -> the robot's *true* steering table; ESC pulse ->
  byte (``|us - 1500| * 255 / 500``, sign = direction) -> true speed table (the ESC is taken as
  symmetric: reverse mirrors the forward side). Differential: H-bridge duty + direction line per
  side -> the robot's true H-bridge table (:func:`hbridge_table`) -> wheel speed.
* Wheel rotation -> encoder edges. The wheels' angles before and after each world step go through
  :class:`~agnav_host.sim.sensors.WheelEncoder`; the edges are queued in the firmware at their
  exact microsecond. Ackermann: one Hall sensor (16 magnets) on the rear axle (its mean angle, the
  point the firmware's odometry tracks). Differential: a quadrature encoder per wheel.
* Sonar triggers -> echoes. For the sensors fired together the world's
  :class:`~agnav_host.sim.sensors.SonarRing` gives the round-trip time (noise, drop-outs and
  neighbour cross-talk included) at the pose of the trigger instant; the echo line rises
  ``echo_rise_us`` after the trigger and falls ``round-trip`` later. No echo: the line stays high
  ``no_echo_us`` (HC-SR04: ~38 ms), which the firmware classifies as NO_ECHO (free space).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..calib import CalibTable, default_speed_table, default_steering_table
from ..sim.robots import Ackermann, DiffDrive
from ..sim.scenario import Scenario
from ..sim.sensors import EncoderSpec, SonarRing, WheelEncoder
from ..sim.world import World
from ..types import DriveCommand, Pose2D, norm_angle_rad
from .binding import Firmware, Outputs

__all__ = ["Plant", "PlantConfig", "hbridge_table", "FIRMWARE_SONAR_PRESETS", "FastSonarRing"]

FIRMWARE_SONAR_PRESETS = (12,)  # SonarSpec layouts that match a firmware ring preset (SONAR_RING_12_SDLG)
CALIB_SPEED_LEFT, CALIB_SPEED_RIGHT = 1, 2


def hbridge_table(max_wheel_speed_m_s: float, deadband_duty: int = 10, min_speed_m_s: float = 0.02) -> CalibTable:
    """True duty -> wheel speed map of a differential robot's H-bridge: dead band below
    ``deadband_duty``, then linear from ``min_speed_m_s`` to ``max_wheel_speed_m_s`` at duty 255."""
    return CalibTable(name="hbridge", unit="m_s", neutral_pwm=0.0, pos_pwm=(float(deadband_duty), 255.0),
                      pos_value=(min_speed_m_s, max_wheel_speed_m_s), neg_pwm=(), neg_value=(), pwm_min=0.0,
                      pwm_max=255.0, value_max=max_wheel_speed_m_s)


class FastSonarRing(SonarRing):
    """:class:`SonarRing` with :meth:`exact_ranges` done for all fired sensors in one brute-force
    numpy pass (rays x objects; a sonar group is only ~28 rays) instead of one ray cast per sensor.
    Same geometry, same results (checked against the parent in hil/tests/test_sil_api.py)."""

    def exact_ranges(self, world: World, pose: Pose2D, t_s: float = 0.0, indices: np.ndarray | None = None) -> np.ndarray:
        s = self.spec
        idx = np.arange(s.count) if indices is None else np.asarray(indices, dtype=int)
        k = s.rays_per_cone
        b = pose.yaw_rad + s.bearings_rad[idx]
        ox = pose.x_m + s.mount_radius_m * np.cos(b)
        oy = pose.y_m + s.mount_radius_m * np.sin(b)
        if k > 1:
            off = -0.5 * s.cone_rad + (s.cone_rad / (k - 1)) * np.arange(k)
        else:
            off = np.zeros(1)
        ang = (b[:, None] + off[None, :]).ravel()
        dx, dy = np.cos(ang), np.sin(ang)
        ox_r, oy_r = np.repeat(ox, k), np.repeat(oy, k)
        best = np.full(len(ang), np.inf)
        seg = world.segments
        if len(seg):
            px, py = seg[:, 0][None, :], seg[:, 1][None, :]
            ex, ey = (seg[:, 2] - seg[:, 0])[None, :], (seg[:, 3] - seg[:, 1])[None, :]
            qx, qy = px - ox_r[:, None], py - oy_r[:, None]
            den = dx[:, None] * ey - dy[:, None] * ex
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (qx * ey - qy * ex) / den
                u = (qx * dy[:, None] - qy * dx[:, None]) / den
            ok = (den != 0.0) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
            best = np.minimum(best, np.where(ok, t, np.inf).min(axis=1))
        circ = world.circles_at(t_s)
        if len(circ):
            cx, cy, r = circ[:, 0][None, :], circ[:, 1][None, :], circ[:, 2][None, :]
            wx, wy = ox_r[:, None] - cx, oy_r[:, None] - cy
            bb = dx[:, None] * wx + dy[:, None] * wy
            cc = wx * wx + wy * wy - r * r
            disc = bb * bb - cc
            sq = np.sqrt(np.maximum(disc, 0.0))
            t1, t2 = -bb - sq, -bb + sq
            t = np.where(t1 >= 0.0, t1, np.where(t2 >= 0.0, t2, np.inf))
            best = np.minimum(best, np.where(disc >= 0.0, t, np.inf).min(axis=1))
        best[best > s.max_range_m] = np.inf
        return best.reshape(len(idx), k).min(axis=1)


@dataclass(frozen=True)
class PlantConfig:
    echo_rise_us: int = 450  # trigger -> echo line high (burst + processing of an HC-SR04)
    no_echo_us: int = 38000  # echo line high without an echo (HC-SR04)
    quad_lines: int = 360  # differential robots: quadrature lines per wheel revolution


class Plant:
    """Robot + world + sensors of one scenario, connected to a :class:`Firmware`."""

    def __init__(self, sc: Scenario, rng_robot: np.random.Generator, rng_sonar: np.random.Generator,
                 config: PlantConfig | None = None) -> None:
        self.sc = sc
        self.cfg = config or PlantConfig()
        self.world = sc.world
        self.robot = sc.make_robot()
        self.rng_robot = rng_robot
        self.rng_sonar = rng_sonar
        self.sonar = (FastSonarRing(sc.sonar.spec) if sc.sonar is not None and sc.sonar.spec.count in FIRMWARE_SONAR_PRESETS
                      else None)
        self.diff = isinstance(self.robot, DiffDrive)
        if self.diff:
            p = self.robot.params
            self.encoders = [WheelEncoder(EncoderSpec("quadrature", self.cfg.quad_lines)) for _ in range(2)]
            self.true_left = self.true_right = hbridge_table(p.max_wheel_speed_m_s)
        else:
            assert isinstance(self.robot, Ackermann)
            p = self.robot.params
            self.encoders = [WheelEncoder(EncoderSpec.hall16())]
            self.true_steer = p.true_steer or default_steering_table()
            self.true_speed = p.true_speed or default_speed_table()
        self._angles = self._wheel_angles()
        self._pose0 = self._pose1 = self.robot.pose
        self._t0_us = self._t1_us = 0
        self._target = (0.0, 0.0)
        self._last_out: Outputs | None = None
        self.edges_queued = 0
        self.echoes = 0

    # ---- firmware profile ----------------------------------------------------------------------------
    def firmware_params(self) -> dict[str, int]:
        """Parameters to store in the firmware's EEPROM before boot so it matches this robot."""
        out: dict[str, int] = {"SONAR_COUNT": self.sonar.spec.count if self.sonar is not None else 0}
        if self.diff:
            p = self.robot.params
            nm = 2.0 * math.pi * p.wheel_radius_m / self.encoders[0].spec.edges_per_rev * 1e9
            # MAX_STEER_CDEG 4500: the tightest arc the steering interface allows a differential
            # robot (radius = track / tan 45 deg), as it cannot be asked to turn on the spot.
            out.update(DRIVE_KIND=1, ENC_COUNT=2, ENC_MODE=0, ENC_NM_PER_CNT=int(round(nm)),
                       TRACK_MM=int(round(p.track_m * 1000)), MAX_STEER_CDEG=4500)
        else:
            p = self.robot.params
            nm = 2.0 * math.pi * p.wheel_radius_m / self.encoders[0].spec.counts_per_rev * 1e9
            out.update(DRIVE_KIND=0, ENC_COUNT=1, ENC_MODE=1, ENC_NM_PER_CNT=int(round(nm)),
                       TRACK_MM=int(round(p.track_m * 1000)), WHEELBASE_MM=int(round(p.wheelbase_m * 1000)))
        return out

    def calibration_uploads(self) -> list[tuple[int, list[int], list[int], int]]:
        """AGNAV_CALIB_TABLE contents (table id, pwm, value, neutral) the host sends at start:
        a differential robot's measured H-bridge tables (the firmware defaults are the RC car's)."""
        if not self.diff:
            return []
        out = []
        for tid, t in ((CALIB_SPEED_LEFT, self.true_left), (CALIB_SPEED_RIGHT, self.true_right)):
            pwm = [int(round(x)) for x in t.pos_pwm]
            val = [int(round(v * 1000)) for v in t.pos_value]
            out.append((tid, pwm, val, int(t.neutral_pwm)))
        return out

    # ---- outputs -> robot -------------------------------------------------------------------------------
    def set_outputs(self, o: Outputs) -> None:
        if o == self._last_out:
            return
        self._last_out = o
        if self.diff:
            vl = self.true_left.value_from_pwm(o.duty_left) * (-1.0 if o.reverse_left else 1.0)
            vr = self.true_right.value_from_pwm(o.duty_right) * (-1.0 if o.reverse_right else 1.0)
            self._target = (vl, vr)
        else:
            steer_b = min(255.0, max(0.0, round((o.steer_us - 1000) * 255 / 1000)))
            d = o.throttle_us - 1500
            speed_b = min(255.0, round(abs(d) * 255 / 500))
            v = self.true_speed.value_from_pwm(speed_b) if d != 0 else 0.0
            self._target = (self.true_steer.value_from_pwm(steer_b), math.copysign(v, d) if v else 0.0)

    def _wheel_angles(self) -> list[float]:
        a = self.robot.wheel_angles_rad
        if self.diff:
            return [float(a[0]), float(a[1])]
        return [0.5 * float(a[0] + a[1])]

    # ---- time -----------------------------------------------------------------------------------------------
    def advance(self, fw: Firmware, t0_us: int, t1_us: int) -> None:
        """Move the robot from t0 to t1 under the current outputs and queue the encoder edges."""
        dt_s = (t1_us - t0_us) * 1e-6
        self._pose0 = self.robot.pose
        if self.diff:
            vl, vr = self._target
            self.robot.step(DriveCommand(0.5 * (vl + vr), (vr - vl) / self.robot.params.track_m), dt_s, self.rng_robot)
        else:
            self.robot._advance(self._target[0], self._target[1], dt_s, self.rng_robot)
        self._pose1 = self.robot.pose
        self._t0_us, self._t1_us = t0_us, t1_us
        a1 = self._wheel_angles()
        span = float(t1_us - t0_us)
        for i, (enc, a0, b1) in enumerate(zip(self.encoders, self._angles, a1)):
            e = enc.edges(a0, b1, 0.0, span)
            n = len(e.times_s)
            if n:
                t = t0_us + np.clip(np.ceil(e.times_s), 1.0, span).astype(np.uint64)
                fw.queue_encoder_edges(i, t, e.ab)
                self.edges_queued += n
        self._angles = a1

    def pose_at(self, t_us: int) -> Pose2D:
        if self._t1_us <= self._t0_us:
            return self._pose1
        f = min(1.0, max(0.0, (t_us - self._t0_us) / (self._t1_us - self._t0_us)))
        p0, p1 = self._pose0, self._pose1
        dyaw = norm_angle_rad(p1.yaw_rad - p0.yaw_rad)
        return Pose2D(p0.x_m + f * (p1.x_m - p0.x_m), p0.y_m + f * (p1.y_m - p0.y_m), p0.yaw_rad + f * dyaw)

    def on_triggers(self, fw: Firmware, triggers: list[tuple[int, int]]) -> None:
        """Queue the echo edges for sonar triggers [(idx, t_us)] (sensors fired together at once)."""
        if not triggers:
            return
        if self.sonar is None:
            return  # no ring in the world: the line never rises (the firmware reports FAULT)
        groups: dict[int, list[int]] = {}
        for idx, t in triggers:
            groups.setdefault(t, []).append(idx)
        for t, idxs in sorted(groups.items()):
            us = self.sonar.echo_us(self.world, self.pose_at(t), idxs, t * 1e-6, self.rng_sonar)
            for idx, w in zip(idxs, us):
                rise = t + self.cfg.echo_rise_us
                width = self.cfg.no_echo_us if not math.isfinite(w) else max(1, int(round(w)))
                fw.queue_echo(idx, rise, 1)
                fw.queue_echo(idx, rise + width, 0)
                self.echoes += 1

    # ---- truth ----------------------------------------------------------------------------------------------
    def clearance(self, t_s: float) -> float:
        cx, cy = self.robot.footprint_centre()
        return float(self.world.clearance_m(cx, cy, t_s)[0]) - self.robot.radius_m
