"""Sensor models: 2-D lasers (horizontal and tilted), the sonar ring and wheel encoders.

All randomness comes from the ``rng`` argument, so a run is reproducible from its seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import numpy.typing as npt

from ..types import EncoderEdges, FloatArray, LaserScan, Pose2D, SonarFrame
from ._raycast import cast_rays, cast_rays_at
from .world import World

if TYPE_CHECKING:
    from ..perception import TiltedMount

__all__ = [
    "LaserSpec",
    "Laser2D",
    "TiltedLaser",
    "LASER_PRESETS",
    "laser_preset",
    "SonarSpec",
    "SonarRing",
    "EncoderSpec",
    "WheelEncoder",
    "SPEED_OF_SOUND_M_S",
]

SPEED_OF_SOUND_M_S = 343.0  # dry air at 20 degC


@dataclass(frozen=True)
class LaserSpec:
    """A planar scanning laser.

    ``n_beams = round(fov / resolution) + 1`` beams from ``-fov/2`` to ``+fov/2`` (0 = forward, CCW+).
    ``no_return`` is the value written for beams without a return (NaN, inf or 0, as drivers differ).
    """

    name: str
    fov_rad: float
    resolution_rad: float
    max_range_m: float
    rate_hz: float
    min_range_m: float = 0.05
    range_std_m: float = 0.01
    dropout_prob: float = 0.0
    mixed_pixel_prob: float = 0.3
    mixed_pixel_jump_m: float = 0.3  # range jump between neighbours that can produce a mixed pixel
    no_return: float = math.nan

    @property
    def n_beams(self) -> int:
        return int(round(self.fov_rad / self.resolution_rad)) + 1

    @property
    def angle_min_rad(self) -> float:
        return -0.5 * self.resolution_rad * (self.n_beams - 1)

    def __post_init__(self) -> None:
        if not 0 < self.fov_rad < 2 * math.pi:
            raise ValueError(f"{self.name}: fov_rad must be in (0, 2pi), got {self.fov_rad}")
        if not (self.resolution_rad > 0 and self.max_range_m > 0 and self.rate_hz > 0):
            raise ValueError(f"{self.name}: resolution, max range and rate must be > 0")
        if not (math.isnan(self.no_return) or self.no_return == 0 or math.isinf(self.no_return)):
            raise ValueError(f"{self.name}: no_return must be NaN, inf or 0")


_D = math.pi / 180.0
LASER_PRESETS: dict[str, LaserSpec] = {
    # SICK TiM561 (ref 001): 270 deg, 1/3 deg steps -> 811 beams, 10 m, 15 Hz
    "tim561": LaserSpec("tim561", 270 * _D, _D / 3.0, 10.0, 15.0, min_range_m=0.05, range_std_m=0.012),
    # SICK LMS200: 180 deg at 1 deg (181 beams); 8 m mode here (the scanner also offers 80 m), 75 Hz
    "lms200": LaserSpec("lms200", 180 * _D, 1.0 * _D, 8.0, 75.0, min_range_m=0.1, range_std_m=0.01),
    # SICK TiM310: 270 deg at 1 deg (271 beams), 4 m, 15 Hz
    "tim310": LaserSpec("tim310", 270 * _D, 1.0 * _D, 4.0, 15.0, min_range_m=0.05, range_std_m=0.02),
}


def laser_preset(name: str) -> LaserSpec:
    """Spec of a named laser (tim561, lms200, tim310); ValueError lists the names on a miss."""
    try:
        return LASER_PRESETS[name.lower()]
    except KeyError:
        raise ValueError(f"unknown laser {name!r}; known: {', '.join(sorted(LASER_PRESETS))}") from None


def _apply_noise(spec: LaserSpec, r: FloatArray, rng: np.random.Generator | None) -> FloatArray:
    """Range noise, mixed pixels at range jumps, dropouts, then no-return marking."""
    r = r.copy()
    finite = np.isfinite(r)
    if rng is not None:
        if spec.mixed_pixel_prob > 0 and len(r) > 1:
            # where neighbouring beams straddle an edge, one of the two may report a blend of both
            a, b = r[:-1], r[1:]
            both = np.isfinite(a) & np.isfinite(b)
            with np.errstate(invalid="ignore"):
                jump = np.abs(np.where(both, a - b, 0.0))
            edge = np.nonzero(both & (jump > spec.mixed_pixel_jump_m))[0]
            if len(edge):
                pick = edge[rng.random(len(edge)) < spec.mixed_pixel_prob]
                if len(pick):
                    which = pick + (rng.random(len(pick)) < 0.5)
                    u = rng.random(len(pick))
                    r[which] = r[pick] + u * (r[pick + 1] - r[pick])
        if spec.range_std_m > 0:
            r[finite] += rng.normal(0.0, spec.range_std_m, int(finite.sum()))
        if spec.dropout_prob > 0:
            r[rng.random(len(r)) < spec.dropout_prob] = np.inf
    bad = ~np.isfinite(r) | (r < spec.min_range_m) | (r > spec.max_range_m)
    r[bad] = spec.no_return
    return r


@dataclass
class Laser2D:
    """A horizontal 2-D laser mounted at ``mount`` (pose in the robot frame)."""

    spec: LaserSpec
    mount: Pose2D = field(default_factory=Pose2D)

    def sensor_pose(self, robot_pose: Pose2D) -> Pose2D:
        return robot_pose.compose(self.mount)

    def exact_ranges(self, world: World, robot_pose: Pose2D, t_s: float = 0.0) -> FloatArray:
        """Noise-free ranges (n_beams,), m, inf for no hit."""
        sp = self.sensor_pose(robot_pose)
        s = self.spec
        return world.raycast(sp.x_m, sp.y_m, sp.yaw_rad, s.angle_min_rad, s.resolution_rad, s.n_beams, s.max_range_m, t_s)

    def scan(self, world: World, robot_pose: Pose2D, t_s: float = 0.0, rng: np.random.Generator | None = None) -> LaserScan:
        """One scan with noise (when rng is given), no-return values and the sensor's world pose."""
        r = _apply_noise(self.spec, self.exact_ranges(world, robot_pose, t_s), rng)
        s = self.spec
        return LaserScan(s.angle_min_rad, s.resolution_rad, r, s.max_range_m, t_s, self.sensor_pose(robot_pose))


@dataclass
class TiltedLaser:
    """A 2-D laser pitched down by ``tilt_rad`` at ``height_m`` above the ground, seeing the terrain.

    Beam a (scan-plane angle) has direction ``(cos a cos tilt, sin a, -cos a sin tilt)`` in the robot
    frame. Each beam is marched in ``march_step_m`` steps up to ``march_max_m`` against
    ``World.ground_height_m``; the first crossing is refined linearly. Obstacles (segments, circles)
    are treated as taller than the beam. Ranges are slant ranges along the beam, m.
    """

    spec: LaserSpec
    height_m: float = 0.5
    tilt_rad: float = math.radians(20.0)
    mount: Pose2D = field(default_factory=Pose2D)
    march_step_m: float = 0.02
    march_max_m: float = 4.0

    def __post_init__(self) -> None:
        if not (self.height_m > 0 and 0 < self.tilt_rad < math.pi / 2):
            raise ValueError("TiltedLaser needs height_m > 0 and 0 < tilt_rad < 90 deg")

    def perception_mount(self) -> "TiltedMount":
        """This laser's pose as perception sees it (height, pitch down, pose on the robot)."""
        from ..perception import TiltedMount

        return TiltedMount(self.height_m, self.tilt_rad, self.mount)

    def exact_ranges(self, world: World, robot_pose: Pose2D, t_s: float = 0.0) -> FloatArray:
        s = self.spec
        sp = robot_pose.compose(self.mount)
        a = s.angle_min_rad + s.resolution_rad * np.arange(s.n_beams)
        hx = np.cos(a) * math.cos(self.tilt_rad)
        hy = np.sin(a)
        hlen = np.hypot(hx, hy)  # horizontal metres per metre of beam
        dz = -np.cos(a) * math.sin(self.tilt_rad)  # vertical metres per metre of beam
        # obstacles: cast along each beam's horizontal direction
        hang = np.arctan2(hy, hx)
        r_obs_h = cast_rays_at(sp.x_m, sp.y_m, sp.yaw_rad, hang, s.max_range_m, world.segments, world.circles_at(t_s))
        r_obs = r_obs_h / np.maximum(hlen, 1e-12)
        # ground: march every beam that points downwards
        rmax = min(s.max_range_m, self.march_max_m)
        steps = np.arange(self.march_step_m, rmax + 1e-9, self.march_step_m)
        c, si = math.cos(sp.yaw_rad), math.sin(sp.yaw_rad)
        wx = c * hx - si * hy
        wy = si * hx + c * hy
        pz = self.height_m + steps[None, :] * dz[:, None]
        # The terrain lies between z_lo and z_hi (the features' depths and heights added up), so a beam point
        # above z_hi is certainly above ground and one below z_lo certainly under it: the height map is only
        # looked up in between (plus one step either side, for the interpolation). Same ranges, far fewer
        # look-ups (a 0.12 m rut: about 20 of the 200 points of a beam).
        z_lo, z_hi = _terrain_bounds_m(world)
        look = (pz <= z_hi + self.march_step_m) & (pz >= z_lo - self.march_step_m)
        look[:, :-1] |= look[:, 1:]
        look[:, 1:] |= look[:, :-1]
        gap = np.where(pz > z_hi, 1.0, -1.0)  # > 0 above ground
        if look.any():
            ii, jj = np.nonzero(look)
            px = sp.x_m + steps[jj] * wx[ii]
            py = sp.y_m + steps[jj] * wy[ii]
            gap[ii, jj] = pz[ii, jj] - world.ground_height_m(px, py)
        below = gap <= 0.0
        any_hit = below.any(axis=1)
        k = np.argmax(below, axis=1)
        r_gnd = np.full(s.n_beams, np.inf)
        rows = np.nonzero(any_hit)[0]
        kk = k[rows]
        g1 = gap[rows, kk]
        g0 = np.where(kk > 0, gap[rows, np.maximum(kk - 1, 0)], self.height_m)
        r0 = np.where(kk > 0, steps[np.maximum(kk - 1, 0)], 0.0)
        frac = g0 / np.where(g0 - g1 > 0, g0 - g1, 1.0)
        r_gnd[rows] = r0 + frac * self.march_step_m
        r: FloatArray = np.minimum(r_obs, r_gnd)
        r[r > s.max_range_m] = np.inf
        return r

    def scan(self, world: World, robot_pose: Pose2D, t_s: float = 0.0, rng: np.random.Generator | None = None) -> LaserScan:
        r = _apply_noise(self.spec, self.exact_ranges(world, robot_pose, t_s), rng)
        s = self.spec
        return LaserScan(s.angle_min_rad, s.resolution_rad, r, s.max_range_m, t_s, robot_pose.compose(self.mount))

    def ground_points(self, scan: LaserScan) -> FloatArray:
        """Valid returns as 3-D points (k, 3) in the robot frame at ground-contact level (z = 0 on flat ground)."""
        m = scan.valid_mask()
        a = scan.angles_rad[m]
        r = scan.ranges_m[m]
        x = r * np.cos(a) * math.cos(self.tilt_rad)
        y = r * np.sin(a)
        z = self.height_m - r * np.cos(a) * math.sin(self.tilt_rad)
        return np.column_stack((x, y, z))


def _terrain_bounds_m(world: World) -> tuple[float, float]:
    """Lowest and highest ground the world's features can make (they add up), m."""
    lo = -sum(h.depth_m for h in world.holes) - sum(r.depth_m for r in world.ruts)
    lo -= sum(max(0.0, -st.height_m) for st in world.steps)
    hi = sum(max(0.0, st.height_m) for st in world.steps)
    return lo, hi


@dataclass(frozen=True)
class SonarSpec:
    """A ring of ultrasonic range finders (ref 002: 12 sensors, 30 deg apart; sensor 0 forward,
    indices counter-clockwise so 3 = left, 6 = back, 9 = right)."""

    count: int = 12
    spacing_rad: float = math.radians(30.0)
    mount_radius_m: float = 0.225
    cone_rad: float = math.radians(30.0)  # full beam width
    rays_per_cone: int = 7
    max_range_m: float = 4.0  # HC-SR04 class
    min_range_m: float = 0.02
    range_std_m: float = 0.01
    dropout_prob: float = 0.02
    crosstalk_prob: float = 0.3  # chance a fired neighbour's earlier echo is heard instead
    speed_of_sound_m_s: float = SPEED_OF_SOUND_M_S

    def __post_init__(self) -> None:
        if self.count < 1 or self.rays_per_cone < 1:
            raise ValueError("SonarSpec: count and rays_per_cone must be >= 1")
        if not (0 < self.cone_rad < math.pi and self.max_range_m > self.min_range_m >= 0):
            raise ValueError("SonarSpec: need 0 < cone < 180 deg and max_range > min_range >= 0")

    @property
    def bearings_rad(self) -> FloatArray:
        return self.spacing_rad * np.arange(self.count, dtype=np.float64)


@dataclass
class SonarRing:
    """Sonar ring model producing echo times (us) for the firmware path and ranges (m).

    A sensor's range is the nearest hit of ``rays_per_cone`` rays spread across its cone (the first
    wave-front to return, not the cone's middle). Fired neighbours cross-talk: with
    ``crosstalk_prob``, a sensor whose neighbour fired in the same slot hears that neighbour's echo if
    it arrives first.
    """

    spec: SonarSpec = field(default_factory=SonarSpec)

    def exact_ranges(self, world: World, pose: Pose2D, t_s: float = 0.0,
                     indices: Sequence[int] | npt.NDArray[np.integer[Any]] | None = None) -> FloatArray:
        """Noise-free ranges (k,) of the given sensors (all when None), m; inf when nothing in range."""
        s = self.spec
        idx = np.arange(s.count) if indices is None else np.asarray(indices, dtype=int)
        circles = world.circles_at(t_s)
        out = np.full(len(idx), np.inf)
        inc = s.cone_rad / (s.rays_per_cone - 1) if s.rays_per_cone > 1 else 0.0
        a_min = -0.5 * s.cone_rad if s.rays_per_cone > 1 else 0.0
        for j, i in enumerate(idx):
            b = pose.yaw_rad + s.bearings_rad[i]
            ox = pose.x_m + s.mount_radius_m * math.cos(b)
            oy = pose.y_m + s.mount_radius_m * math.sin(b)
            r = cast_rays(ox, oy, b, a_min, inc if inc > 0 else 1.0, s.rays_per_cone, s.max_range_m, world.segments, circles)
            out[j] = r.min()
        return out

    def echo_us(
        self,
        world: World,
        pose: Pose2D,
        fired_indices: list[int] | FloatArray,
        t_s: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> FloatArray:
        """Round-trip echo times (k,) in microseconds for the fired sensors, NaN for no echo."""
        # Scalar Python over the few fired sensors (a group is ~4): the same arithmetic and the
        # same draws from ``rng`` in the same order as the array form, at a fraction of the cost.
        s = self.spec
        if type(fired_indices) is list and all(type(i) is int for i in fired_indices):
            idx = fired_indices
        else:
            idx = [int(i) for i in np.asarray(fired_indices, dtype=int).ravel()]
        n = s.count
        for i in idx:
            if i < 0 or i >= n:
                raise ValueError(f"sonar index out of range 0..{n - 1}: {idx}")
        r = self.exact_ranges(world, pose, t_s, idx).tolist()
        inf = math.inf
        if rng is not None and s.range_std_m > 0:
            fin = [j for j, v in enumerate(r) if math.isfinite(v)]
            for j, e in zip(fin, rng.normal(0.0, s.range_std_m, len(fin)).tolist()):
                r[j] += e
        lo, hi = s.min_range_m, s.max_range_m
        r = [inf if (v < lo or v > hi) else v for v in r]
        if rng is not None and s.dropout_prob > 0:
            p = s.dropout_prob
            r = [inf if u < p else v for v, u in zip(r, rng.random(len(r)).tolist())]
        c = s.speed_of_sound_m_s
        us = [2.0 * v / c * 1e6 for v in r]
        if rng is not None and s.crosstalk_prob > 0 and len(idx) > 1:
            pos = {i: j for j, i in enumerate(idx)}
            base = list(us)
            for j, i in enumerate(idx):
                for nb in ((i + 1) % n, (i - 1) % n):
                    k = pos.get(nb)
                    if k is not None and base[k] < us[j] and rng.random() < s.crosstalk_prob:
                        us[j] = base[k]
        return np.array([v if -inf < v < inf else math.nan for v in us])

    def measure(
        self, world: World, pose: Pose2D, fired_indices: list[int] | FloatArray, t_s: float = 0.0, rng: np.random.Generator | None = None
    ) -> SonarFrame:
        """A full-ring frame: arrays of length ``count``, NaN for sensors not fired or without echo."""
        s = self.spec
        idx = np.asarray(fired_indices, dtype=int)
        us = np.full(s.count, np.nan)
        us[idx] = self.echo_us(world, pose, idx, t_s, rng)
        fired = np.zeros(s.count, dtype=bool)
        fired[idx] = True
        return SonarFrame(t_s, fired, us, us * 1e-6 * s.speed_of_sound_m_s / 2.0)


# Quadrature phases in Gray order, forward = A leads B: (A, B) = 00, 10, 11, 01
_QUAD_AB = np.array([0b00, 0b10, 0b11, 0b01], dtype=np.uint8)


@dataclass(frozen=True)
class EncoderSpec:
    """Wheel encoder. ``quadrature``: ``counts_per_rev`` lines, 4 edges per line on A/B.
    ``hall``: ``counts_per_rev`` magnets (16 on the ref-003 car: 13.55 mm of a 69 mm wheel per
    pulse), one pulse (rise + fall on A) per magnet, no direction information."""

    mode: str = "quadrature"
    counts_per_rev: int = 360

    def __post_init__(self) -> None:
        if self.mode not in ("quadrature", "hall"):
            raise ValueError(f"encoder mode must be 'quadrature' or 'hall', got {self.mode!r}")
        if self.counts_per_rev < 1:
            raise ValueError("counts_per_rev must be >= 1")

    @property
    def edges_per_rev(self) -> int:
        return self.counts_per_rev * (4 if self.mode == "quadrature" else 2)

    @staticmethod
    def hall16() -> "EncoderSpec":
        return EncoderSpec("hall", 16)


@dataclass
class WheelEncoder:
    """Turns wheel-angle motion into edge times (the stream the firmware ISR sees)."""

    spec: EncoderSpec = field(default_factory=EncoderSpec)

    def edges(self, angle0_rad: float, angle1_rad: float, t0_s: float, t1_s: float) -> EncoderEdges:
        """Edges crossed while the wheel turns linearly from angle0 to angle1 between t0 and t1.

        Edge k sits at wheel angle ``k * 2 pi / edges_per_rev``; ``ab`` is the level after each edge.
        """
        step = 2.0 * math.pi / self.spec.edges_per_rev
        k0 = math.floor(angle0_rad / step)
        k1 = math.floor(angle1_rad / step)
        if k1 > k0:  # forward: crossing boundary k enters phase k
            ks = np.arange(k0 + 1, k1 + 1)
            phase = ks
        elif k1 < k0:  # backward: crossing boundary k enters phase k - 1
            ks = np.arange(k0, k1, -1)
            phase = ks - 1
        else:
            return EncoderEdges(np.zeros(0), np.zeros(0, dtype=np.uint8))
        da = angle1_rad - angle0_rad
        times = t0_s + (ks * step - angle0_rad) / da * (t1_s - t0_s)
        if self.spec.mode == "quadrature":
            ab = _QUAD_AB[np.mod(phase, 4)]
        else:
            ab = (np.mod(phase, 2).astype(np.uint8) << 1).astype(np.uint8)
        return EncoderEdges(times.astype(float), ab.astype(np.uint8))

    @staticmethod
    def decode_quadrature(ab: np.ndarray, start_ab: int = 0) -> tuple[int, int]:
        """Reference decoder: (net count, illegal transitions) for a level sequence (tests, SIL checks)."""
        order = {0b00: 0, 0b10: 1, 0b11: 2, 0b01: 3}
        count = errors = 0
        prev = order[start_ab]
        for v in ab.tolist():
            cur = order[int(v)]
            d = (cur - prev) % 4
            if d == 1:
                count += 1
            elif d == 3:
                count -= 1
            elif d == 2:
                errors += 1
            prev = cur
        return count, errors
