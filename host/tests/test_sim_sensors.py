import math

import numpy as np
import pytest

from agnav_host.sim import World
from agnav_host.sim.sensors import EncoderSpec, SonarRing, SonarSpec, WheelEncoder
from agnav_host.types import Pose2D


def _wall_world():
    w = World()
    w.add_segments(np.array([[2.0, -5.0, 2.0, 5.0]]))
    return w


def test_sonar_echo_time_matches_range():
    ring = SonarRing(SonarSpec(dropout_prob=0.0, range_std_m=0.0, crosstalk_prob=0.0))
    us = ring.echo_us(_wall_world(), Pose2D(), [0, 6])
    expect_r = 2.0 - 0.225
    assert us[0] == pytest.approx(2 * expect_r / 343.0 * 1e6, rel=1e-9)
    assert math.isnan(us[1])  # back sensor: nothing within 4 m
    frame = ring.measure(_wall_world(), Pose2D(), [0], 0.0)
    assert frame.ranges_m[0] == pytest.approx(expect_r)
    assert frame.fired.sum() == 1 and math.isnan(frame.echo_us[3])


def test_sonar_cone_sees_off_axis_object_first():
    w = World()
    w.add_circles([[1.5, 0.3, 0.05]])  # 11 deg off sensor 0's axis, inside its 30 deg cone
    ring = SonarRing(SonarSpec(dropout_prob=0.0, range_std_m=0.0, crosstalk_prob=0.0, rays_per_cone=15))
    assert np.isfinite(ring.echo_us(w, Pose2D(), [0])[0])


def test_sonar_crosstalk_when_neighbours_fire_together():
    ring = SonarRing(SonarSpec(dropout_prob=0.0, range_std_m=0.0, crosstalk_prob=1.0))
    w = _wall_world()
    alone = ring.echo_us(w, Pose2D(), [1], 0.0, np.random.default_rng(0))[0]
    both = ring.echo_us(w, Pose2D(), [0, 1], 0.0, np.random.default_rng(0))
    assert both[1] < alone and both[1] == pytest.approx(both[0])
    with pytest.raises(ValueError):
        ring.echo_us(w, Pose2D(), [12])


def test_quadrature_edges_count_forward_and_back():
    enc = WheelEncoder(EncoderSpec("quadrature", 100))
    e = enc.edges(1e-3, 2 * math.pi + 1e-3, 0.0, 1.0)
    assert len(e.times_s) == 400 and np.all(np.diff(e.times_s) > 0)
    assert WheelEncoder.decode_quadrature(e.ab) == (400, 0)
    back = enc.edges(2 * math.pi + 1e-3, math.pi + 1e-3, 1.0, 2.0)
    assert WheelEncoder.decode_quadrature(back.ab, start_ab=int(e.ab[-1])) == (-200, 0)


def test_hall_mode_16_magnets_13_55_mm_per_pulse():
    enc = WheelEncoder(EncoderSpec.hall16())
    wheel_r = 0.0345
    dist = 1.0
    e = enc.edges(0.0, dist / wheel_r, 0.0, 1.0)
    rising = int(np.count_nonzero(e.ab == 0b10))
    assert rising == pytest.approx(dist / 0.01355, abs=1.5)


def _brute_force_tilted_ranges(tl, world, pose):
    """Every beam marched over its whole length against the height map (what TiltedLaser does, without
    skipping the points that are certainly above or below the ground)."""
    from agnav_host.sim._raycast import cast_rays_at

    s = tl.spec
    sp = pose.compose(tl.mount)
    a = s.angle_min_rad + s.resolution_rad * np.arange(s.n_beams)
    hx, hy = np.cos(a) * math.cos(tl.tilt_rad), np.sin(a)
    dz = -np.cos(a) * math.sin(tl.tilt_rad)
    r_obs = cast_rays_at(sp.x_m, sp.y_m, sp.yaw_rad, np.arctan2(hy, hx), s.max_range_m, world.segments,
                         world.circles_at(0.0)) / np.hypot(hx, hy)
    steps = np.arange(tl.march_step_m, min(s.max_range_m, tl.march_max_m) + 1e-9, tl.march_step_m)
    c, si = math.cos(sp.yaw_rad), math.sin(sp.yaw_rad)
    px = sp.x_m + steps[None, :] * (c * hx - si * hy)[:, None]
    py = sp.y_m + steps[None, :] * (si * hx + c * hy)[:, None]
    gap = tl.height_m + steps[None, :] * dz[:, None] - world.ground_height_m(px, py)
    r = np.full(s.n_beams, np.inf)
    for i in range(s.n_beams):
        k = np.flatnonzero(gap[i] <= 0.0)
        if len(k):
            k0 = k[0]
            g0, r0 = (gap[i, k0 - 1], steps[k0 - 1]) if k0 > 0 else (tl.height_m, 0.0)
            g1 = gap[i, k0]
            r[i] = r0 + (g0 / (g0 - g1) if g0 - g1 > 0 else 1.0) * tl.march_step_m
    r = np.minimum(r, r_obs)
    r[r > s.max_range_m] = np.inf
    return r


@pytest.mark.parametrize("name", ["hole_field", "ruts"])
def test_tilted_laser_skips_only_lookups_that_cannot_change_the_ranges(name):
    from agnav_host.sim.scenario import load_scenario

    sc = load_scenario(name)
    tl = sc.tilted_laser
    assert tl is not None
    rng = np.random.default_rng(3)
    for _ in range(8):
        pose = Pose2D(float(rng.uniform(0, 22)), float(rng.uniform(-3, 3)), float(rng.uniform(-math.pi, math.pi)))
        got = tl.exact_ranges(sc.world, pose)
        want = _brute_force_tilted_ranges(tl, sc.world, pose)
        assert np.array_equal(np.isfinite(got), np.isfinite(want))
        assert np.allclose(got[np.isfinite(got)], want[np.isfinite(want)], rtol=0, atol=1e-9)


def test_tilted_laser_beams_come_from_the_scenario():
    from agnav_host.sim.scenario import parse_scenario

    text = """[scenario]
name = "t"
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }
[tilted_laser]
model = "lms200"
height_m = 0.6
tilt_deg = 25.0
fov_deg = 60.0
resolution_deg = 0.5
[[goals]]
x_m = 1.0
y_m = 0.0
"""
    tl = parse_scenario(text, "<t>").tilted_laser
    assert tl is not None
    assert tl.spec.n_beams == 121 and tl.height_m == pytest.approx(0.6)
    assert tl.tilt_rad == pytest.approx(math.radians(25.0))
    assert tl.spec.angle_min_rad == pytest.approx(math.radians(-30.0))
