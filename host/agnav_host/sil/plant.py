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

import ctypes as C
import math
from dataclasses import dataclass
from typing import Callable, Sequence, cast

import numpy as np

from ..calib import CalibTable, default_speed_table, default_steering_table
from ..sim.robots import Ackermann, DiffDrive
from ..sim.scenario import Scenario
from ..sim._raycast import RayBundle
from ..sim.sensors import EncoderSpec, SonarRing, WheelEncoder
from ..sim.world import World
from ..types import DriveCommand, FloatArray, Pose2D, norm_angle_rad
from ..units import si_to_milli
from ._kernels import kernels
from .binding import Firmware, Outputs

__all__ = ["Plant", "PlantConfig", "hbridge_table", "FIRMWARE_SONAR_PRESETS", "FastSonarRing"]

FIRMWARE_SONAR_PRESETS = (12,)  # SonarSpec layouts that match a firmware ring preset (SONAR_RING_12_SDLG)
CALIB_SPEED_LEFT, CALIB_SPEED_RIGHT = 1, 2
TRIGGER_GROUP_US = 500  # triggers closer than this to a group's first are one group (see Plant.on_triggers)
_EDGE_BATCH = 4096  # encoder edges per world step handled by the scalar path (more: the numpy path)
_QUAD_AB = (0b00, 0b10, 0b11, 0b01)  # quadrature levels per phase (as sim.sensors: A leads B forward)


class _PrefetchedNormals:
    """The robot model's random source: ``normal(loc, scale, n)`` served from standard normals drawn
    from the generator in blocks. A block draw yields exactly the values that many small draws
    would (the generator's normals are taken one after the other), so the robot moves bit for bit
    as with the generator itself, without a numpy call per world step. Only ``normal`` is offered:
    another kind of draw would need the generator's own position, so it fails loudly instead."""

    __slots__ = ("_rng", "_z", "_i")

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._z: list[float] = []
        self._i = 0

    def normal(self, loc: float = 0.0, scale: float = 1.0, size: int | None = None) -> list[float] | float:
        n = 1 if size is None else int(size)
        i = self._i
        if i + n > len(self._z):
            self._z = self._z[i:] + self._rng.standard_normal(max(4096, n)).tolist()
            i = 0
        self._i = i + n
        z = self._z
        if size is None:
            return loc + scale * z[i]
        if n == 2:  # the robot models' draw (slip of two wheels, or of speed and yaw rate)
            return [loc + scale * z[i], loc + scale * z[i + 1]]
        return [loc + scale * z[j] for j in range(i, i + n)]


def hbridge_table(max_wheel_speed_m_s: float, deadband_duty: int = 10, min_speed_m_s: float = 0.02) -> CalibTable:
    """True duty -> wheel speed map of a differential robot's H-bridge: dead band below
    ``deadband_duty``, then linear from ``min_speed_m_s`` to ``max_wheel_speed_m_s`` at duty 255."""
    return CalibTable(name="hbridge", unit="m_s", neutral_pwm=0.0, pos_pwm=(float(deadband_duty), 255.0),
                      pos_value=(min_speed_m_s, max_wheel_speed_m_s), neg_pwm=(), neg_value=(), pwm_min=0.0,
                      pwm_max=255.0, value_max=max_wheel_speed_m_s)


class FastSonarRing(SonarRing):
    """:class:`SonarRing` with :meth:`exact_ranges` done for all fired sensors in one brute-force
    pass (rays x objects; a sonar group is only ~28 rays) instead of one ray cast per sensor.
    Same geometry, same results (checked against the parent in hil/tests/test_sil_api.py).

    The ray directions come from numpy (into buffers allocated once); the (ray, object) pairs are
    done by the C kernel of world_kernels.c when it can be built, otherwise by
    :class:`~agnav_host.sim._raycast.RayBundle` (numpy; the two agree to the last bit)."""

    def __init__(self, *args: object, **kw: object) -> None:
        super().__init__(*args, **kw)  # type: ignore[arg-type]
        s = self.spec
        k = s.rays_per_cone
        self._off = (-0.5 * s.cone_rad + (s.cone_rad / (k - 1)) * np.arange(k)) if k > 1 else np.zeros(1)
        self._groups: dict[tuple[int, ...], np.ndarray] = {}
        self._bundle: RayBundle | None = None
        self._kern = kernels()
        n = s.count
        # ray angles (n*k) then sensor bearings (n), and their cosines and sines: one numpy call each
        self._ang, self._cs, self._sn = np.empty(n * k + n), np.empty(n * k + n), np.empty(n * k + n)
        self._out = np.empty(n)
        self._ptr = (self._cs.ctypes.data, self._sn.ctypes.data, self._out.ctypes.data)
        self._views: dict[int, tuple[np.ndarray, ...]] = {}
        self._world: tuple[object, object, np.ndarray, np.ndarray, int, int] | None = None

    def _bundle_for(self, world: World) -> RayBundle:
        b = self._bundle
        if b is None or b.segments is not world.segments or b.circles is not world.circles:
            b = self._bundle = RayBundle(world.segments, world.circles, self.spec.max_range_m,
                                         reach_m=self.spec.mount_radius_m)
        return b

    def _trig(self, pose: Pose2D, bear: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """cos and sin of a group's ray angles ``b + offsets`` (n*k) followed by those of the sensor
        bearings ``b = yaw + bearing`` (n), in the buffers (contiguous, as numpy computed them
        before: the same element-wise results)."""
        n = len(bear)
        v = self._views.get(n)
        if v is None:
            k = len(self._off)
            m = n * k + n
            v = self._views[n] = (self._ang[n * k:m], self._ang[n * k:m, None], self._ang[:n * k].reshape(n, k),
                                  self._ang[:m], self._cs[:m], self._sn[:m])
        b, bcol, ang, allang, cs, sn = v
        np.add(bear, pose.yaw_rad, out=b)
        np.add(bcol, self._off, out=ang)
        np.cos(allang, out=cs)
        np.sin(allang, out=sn)
        return cs, sn, n

    def exact_ranges(self, world: World, pose: Pose2D, t_s: float = 0.0,
                     indices: Sequence[int] | np.ndarray | None = None) -> FloatArray:
        s = self.spec
        if indices is None:
            key = tuple(range(s.count))
        elif type(indices) is list and all(type(i) is int for i in indices):
            key = tuple(indices)
        else:
            key = tuple(int(i) for i in np.asarray(indices, dtype=int).ravel())
        bear = self._groups.get(key)
        if bear is None:
            bear = self._groups[key] = s.bearings_rad[np.asarray(key, dtype=int)]
        cs, sn, n = self._trig(pose, bear)
        k = len(self._off)
        movers = (np.array([(*m.position(t_s), m.radius_m) for m in world.movers]) if world.movers else None)
        kern = self._kern
        if kern is None:
            R, nk = s.mount_radius_m, n * k
            ox, oy = pose.x_m + R * cs[nk:], pose.y_m + R * sn[nk:]
            nearest: FloatArray = self._bundle_for(world).cast(ox[:, None], oy[:, None], cs[:nk].reshape(n, k),
                                                               sn[:nk].reshape(n, k), movers,
                                                               centre=(pose.x_m, pose.y_m)).min(axis=1)
            return nearest
        w = self._world
        if w is None or w[0] is not world.segments or w[1] is not world.circles:
            seg = np.ascontiguousarray(world.segments, dtype=float).reshape(-1, 4)
            circ = np.ascontiguousarray(world.circles, dtype=float).reshape(-1, 3)
            w = self._world = (world.segments, world.circles, seg, circ, seg.ctypes.data, circ.ctypes.data)
        seg, circ, pseg, pcirc = w[2], w[3], w[4], w[5]
        if movers is not None:
            circ = np.ascontiguousarray(np.vstack((circ, movers)), dtype=float)
            pcirc = circ.ctypes.data
        pcs, psn, pout = self._ptr
        kern.agnav_sonar_cast(n, k, pose.x_m, pose.y_m, s.mount_radius_m, pcs, psn, len(seg), pseg, len(circ), pcirc,
                              s.max_range_m, pout)
        return self._out[:n].copy()


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
        if isinstance(self.robot, DiffDrive):
            self.encoders = [WheelEncoder(EncoderSpec("quadrature", self.cfg.quad_lines)) for _ in range(2)]
            self.true_left = self.true_right = hbridge_table(self.robot.params.max_wheel_speed_m_s)
        else:
            assert isinstance(self.robot, Ackermann)
            car = self.robot.params
            self.encoders = [WheelEncoder(EncoderSpec.hall16())]
            self.true_steer = car.true_steer or default_steering_table()
            self.true_speed = car.true_speed or default_speed_table()
        self._angles = self._wheel_angles()
        self._pose0 = self._pose1 = self.robot.pose
        self._t0_us = self._t1_us = 0
        self._target = (0.0, 0.0)
        self._last_out: Outputs | None = None
        self._last_drive: tuple[int, ...] | None = None
        self._robot_rng = _PrefetchedNormals(rng_robot)
        self._enc_step = [2.0 * math.pi / e.spec.edges_per_rev for e in self.encoders]  # as WheelEncoder.edges
        self._enc_quad = [e.spec.mode == "quadrature" for e in self.encoders]
        self._edge_t = (C.c_uint64 * _EDGE_BATCH)()
        self._edge_ab = (C.c_uint8 * _EDGE_BATCH)()
        self._capi_fw: object = None
        self._q_edges = self._q_echo = None
        self._k_edges: Callable[..., int] | None = None  # the C kernel's agnav_encoder_edges, when built
        self.edges_queued = 0
        self.echoes = 0

    # ---- firmware profile ----------------------------------------------------------------------------
    def firmware_params(self) -> dict[str, int]:
        """Parameters to store in the firmware's EEPROM before boot so it matches this robot."""
        out: dict[str, int] = {"SONAR_COUNT": self.sonar.spec.count if self.sonar is not None else 0}
        if isinstance(self.robot, DiffDrive):
            p = self.robot.params
            nm = 2.0 * math.pi * p.wheel_radius_m / self.encoders[0].spec.edges_per_rev * 1e9
            # MAX_STEER_CDEG 4500: the tightest arc the steering interface allows a differential
            # robot (radius = track / tan 45 deg), as it cannot be asked to turn on the spot.
            out.update(DRIVE_KIND=1, ENC_COUNT=2, ENC_MODE=0, ENC_NM_PER_CNT=int(round(nm)),
                       TRACK_MM=int(round(si_to_milli(p.track_m))), MAX_STEER_CDEG=4500)
        else:
            car = self.robot.params
            nm = 2.0 * math.pi * car.wheel_radius_m / self.encoders[0].spec.counts_per_rev * 1e9
            out.update(DRIVE_KIND=0, ENC_COUNT=1, ENC_MODE=1, ENC_NM_PER_CNT=int(round(nm)),
                       TRACK_MM=int(round(si_to_milli(car.track_m))),
                       WHEELBASE_MM=int(round(si_to_milli(car.wheelbase_m))))
        return out

    def calibration_uploads(self) -> list[tuple[int, list[int], list[int], int]]:
        """AGNAV_CALIB_TABLE contents (table id, pwm, value, neutral) the host sends at start:
        a differential robot's measured H-bridge tables (the firmware defaults are the RC car's)."""
        if not self.diff:
            return []
        out = []
        for tid, t in ((CALIB_SPEED_LEFT, self.true_left), (CALIB_SPEED_RIGHT, self.true_right)):
            pwm = [int(round(x)) for x in t.pos_pwm]
            val = [int(round(si_to_milli(v))) for v in t.pos_value]
            out.append((tid, pwm, val, int(t.neutral_pwm)))
        return out

    # ---- outputs -> robot -------------------------------------------------------------------------------
    def set_outputs(self, o: Outputs) -> None:
        # only the drive's own outputs matter (o also carries the watchdog count, new every step)
        drive = (o.duty_left, o.duty_right, o.reverse_left, o.reverse_right) if self.diff else (o.steer_us, o.throttle_us)
        self._last_out = o
        if drive == self._last_drive:
            return
        self._last_drive = drive
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
        robot = self.robot
        self._pose0 = robot.pose
        if self.diff:
            vl, vr = self._target
            diff = cast(DiffDrive, robot)
            diff.step(DriveCommand(0.5 * (vl + vr), (vr - vl) / diff.params.track_m), dt_s, self._robot_rng)
        else:
            cast(Ackermann, robot)._advance(self._target[0], self._target[1], dt_s, self._robot_rng)
        self._pose1 = robot.pose
        self._t0_us, self._t1_us = t0_us, t1_us
        a1 = self._wheel_angles()
        if fw is not self._capi_fw:
            self._bind(fw)
        if self._k_edges is not None:  # the C kernel computes and queues the edges of every wheel
            A0, A1 = self._k_a0, self._k_a1
            for i, (a0, b1) in enumerate(zip(self._angles, a1)):
                A0[i], A1[i] = a0, b1
            got = self._k_edges(self._q_ptr, len(a1), A0, A1, self._k_step, self._k_mode, t0_us, t1_us - t0_us,
                                self._edge_t, self._edge_ab, _EDGE_BATCH)
            if got == -1:
                raise RuntimeError("SIL event queue full (encoder edges)")
            if got >= 0:
                self.edges_queued += got
                self._angles = a1
                return
        q = self._q_edges
        span = float(t1_us - t0_us)
        ispan = t1_us - t0_us
        for i, (a0, b1) in enumerate(zip(self._angles, a1)):
            # WheelEncoder.edges + the microsecond rounding below, in scalar Python for the few
            # edges of one step: edge k at wheel angle k * step, time linear in the angle
            step = self._enc_step[i]
            k0, k1 = math.floor(a0 / step), math.floor(b1 / step)
            n = abs(k1 - k0)
            if n == 0:
                continue
            if q is None or n > _EDGE_BATCH:
                e = self.encoders[i].edges(a0, b1, 0.0, span)
                t = t0_us + np.clip(np.ceil(e.times_s), 1.0, span).astype(np.uint64)
                fw.queue_encoder_edges(i, t, e.ab)
                self.edges_queued += n
                continue
            ks, ph = (range(k0 + 1, k1 + 1), 0) if k1 > k0 else (range(k0, k1, -1), -1)
            da = b1 - a0
            T, AB = self._edge_t, self._edge_ab
            quad = self._enc_quad[i]
            for j, k in enumerate(ks):
                c = math.ceil(0.0 + (k * step - a0) / da * span)  # np.clip(np.ceil(times), 1, span)
                T[j] = t0_us + (1 if c < 1 else ispan if c > ispan else c)
                AB[j] = _QUAD_AB[(k + ph) % 4] if quad else ((k + ph) % 2) << 1
            got = q(i, T, AB, n)
            if got != n:
                raise RuntimeError(f"SIL event queue full: {got} of {n} encoder edges queued")
            self.edges_queued += n
        self._angles = a1

    def _bind(self, fw: Firmware) -> None:
        """The C API entry points behind ``fw`` (hil/sil/sil_api.h, the same for every backend)
        for the per-step calls, which are then made with ctypes arrays instead of numpy ones;
        a firmware object without them is driven through its methods."""
        lib = getattr(fw, "_lib", None)
        self._q_edges = getattr(lib, "sil_queue_encoder_edges", None)
        self._q_echo = getattr(lib, "sil_queue_echo", None)
        self._capi_fw = fw
        kern = kernels()
        self._k_edges = None
        if kern is not None and self._q_edges is not None:
            # the kernel calls the firmware's sil_queue_encoder_edges itself
            self._q_ptr = C.cast(self._q_edges, C.c_void_p).value
            nw = len(self.encoders)
            self._k_a0, self._k_a1 = (C.c_double * nw)(), (C.c_double * nw)()
            self._k_step = (C.c_double * nw)(*self._enc_step)
            self._k_mode = (C.c_int * nw)(*(0 if q else 1 for q in self._enc_quad))
            self._k_edges = kern.agnav_encoder_edges

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
        # A group: the sensors fired together. The native SIL logs them at one microsecond; the
        # AVR fires them one after the other (10 us pulse each), so triggers within
        # TRIGGER_GROUP_US of a group's first belong to it (the scheduler's sonar task runs every
        # 1 ms, so native groups are never merged). Each echo starts from its own trigger.
        groups: list[tuple[int, list[tuple[int, int]]]] = []
        for idx, t in sorted(triggers, key=lambda it: it[1]):
            if groups and t - groups[-1][0] < TRIGGER_GROUP_US:
                groups[-1][1].append((idx, t))
            else:
                groups.append((t, [(idx, t)]))
        if fw is not self._capi_fw:
            self._bind(fw)
        qe = self._q_echo
        rise_us, no_echo_us = self.cfg.echo_rise_us, self.cfg.no_echo_us
        for t, members in groups:
            idxs = [i for i, _ in members]
            us = self.sonar.echo_us(self.world, self.pose_at(t), idxs, t * 1e-6, self.rng_sonar)
            for (idx, t_i), w in zip(members, us.tolist()):
                rise = t_i + rise_us
                width = no_echo_us if not math.isfinite(w) else max(1, int(round(w)))
                if qe is None:
                    fw.queue_echo(idx, rise, 1)
                    fw.queue_echo(idx, rise + width, 0)
                elif not (qe(idx, rise, 1) and qe(idx, rise + width, 0)):
                    raise RuntimeError("SIL event queue full (echo)")
                self.echoes += 1

    # ---- truth ----------------------------------------------------------------------------------------------
    def clearance(self, t_s: float) -> float:
        cx, cy = self.robot.footprint_centre()
        return float(self.world.clearance_m(cx, cy, t_s)[0]) - self.robot.radius_m
