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
