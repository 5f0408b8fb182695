"""One angle wrap, to [-pi, pi), for a number and for every element of an array (the planners, the simulator's
ray caster, the fake robot and the SIL all use it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.types import norm_angle_rad


def test_a_number_wraps_to_minus_pi_up_to_pi():
    assert norm_angle_rad(math.pi) == -math.pi and norm_angle_rad(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert norm_angle_rad(-0.25) == -0.25 and isinstance(norm_angle_rad(0.5), float)


def test_an_array_wraps_element_wise():
    a = np.array([-3 * math.pi, -math.pi, 0.0, 7.0])
    out = norm_angle_rad(a)
    assert isinstance(out, np.ndarray) and np.allclose(out, [-math.pi, -math.pi, 0.0, 7.0 - 2 * math.pi])
