import math

import numpy as np
import pytest

from agnav_host.sim.metrics import (
    SUMMARY_KEYS,
    RunMetrics,
    bending_energy,
    count_heading_oscillations,
    count_stops,
    path_length_m,
)


def test_straight_path_has_zero_bending_energy():
    xy = np.column_stack((np.linspace(0, 10, 37), np.linspace(0, 5, 37)))
    assert path_length_m(xy) == pytest.approx(math.hypot(10, 5))
    assert bending_energy(xy) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("radius, n", [(1.0, 500), (2.0, 2000), (5.0, 300)])
def test_circle_bending_energy_is_length_over_r_squared(radius, n):
    a = np.linspace(0, 1.5 * math.pi, n)
    xy = radius * np.column_stack((np.cos(a), np.sin(a)))
    length = 1.5 * math.pi * radius
    assert path_length_m(xy) == pytest.approx(length, rel=1e-3)
    assert bending_energy(xy) == pytest.approx(length / radius**2, rel=0.02)


def test_bending_energy_does_not_depend_on_sample_rate():
    a1 = np.linspace(0, math.pi, 100)
    a2 = np.linspace(0, math.pi, 3000)
    assert bending_energy(np.column_stack((np.cos(a1), np.sin(a1)))) == pytest.approx(
        bending_energy(np.column_stack((np.cos(a2), np.sin(a2)))), rel=0.02)


def test_stops_and_oscillations():
    v = np.array([0, 0.3, 0.3, 0.0, 0.0, 0.3, 0.0])
    assert count_stops(v) == 1  # the final stop is arrival, not a stop
    w = np.array([0.2, 0.3, -0.2, 0.05, -0.3, 0.4, 0.0])
    assert count_heading_oscillations(w) == 2


def test_summary_keys_and_nulls():
    t = np.linspace(0, 10, 11)
    xy = np.column_stack((t, np.zeros_like(t)))
    m = RunMetrics.compute(t, xy, np.zeros(11), np.ones(11), np.zeros(11), np.full(11, 0.5), (10.0, 0.0),
                           None, None, True, 10.0)
    d = m.to_dict()
    assert tuple(d) == SUMMARY_KEYS
    assert d["final_heading_error_deg"] is None and d["arrival_time_error_s"] is None
    m2 = RunMetrics.compute(t, xy, np.zeros(11), np.ones(11), np.zeros(11), np.full(11, 0.5), (10.0, 0.0),
                            math.pi / 2, 9.0, True, 10.0)
    assert m2.final_heading_error_deg == pytest.approx(90.0) and m2.arrival_time_error_s == pytest.approx(1.0)
