"""Reversals in a driven path: counted apart in the run metrics and summary.json, and left out of the bending
energy, which stays continuous."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agnav_host.sim.metrics import SUMMARY_KEYS, RunMetrics, bending_energy
from agnav_host.sim.runner import run_scenario, write_outputs
from agnav_host.sim.scenario import parse_scenario
from _scenario_text import scenario_text


def _back_off(tilt_deg: float, back_m: float = 0.5) -> np.ndarray:
    fwd = np.column_stack((np.linspace(0.0, 1.0, 101), np.zeros(101)))
    a = math.radians(180.0 - tilt_deg)
    s = np.linspace(0.0, back_m, 51)[1:]
    return np.vstack((fwd, np.column_stack((1.0 + s * math.cos(a), s * math.sin(a)))))


@pytest.mark.parametrize("tilt_deg", [0.0, 0.2, 5.0, 25.0])
def test_bending_energy_skips_a_reversal(tilt_deg: float) -> None:
    assert bending_energy(_back_off(tilt_deg)) == pytest.approx(0.0, abs=1e-9)


def test_reversals_are_counted_in_the_run_metrics() -> None:
    for tilt, want in ((0.0, 1), (0.2, 1), (60.0, 0)):
        xy = _back_off(tilt)
        t = np.arange(len(xy)) * 0.1
        m = RunMetrics.compute(t, xy, np.zeros(len(t)), np.ones(len(t)), np.zeros(len(t)), np.full(len(t), 1.0),
                               (0.5, 0.0), None, None, True, float(t[-1]))
        assert m.reversals == want
        assert m.to_dict()["reversals"] == want
    assert "reversals" in SUMMARY_KEYS
    # a path without reversals keeps its bending energy (circle of radius 2: length / R^2)
    a = np.linspace(0.0, 1.5 * math.pi, 2000)
    assert bending_energy(2.0 * np.column_stack((np.cos(a), np.sin(a)))) == pytest.approx(1.5 * math.pi / 2.0, rel=0.02)


def test_summary_json_has_reversals(tmp_path) -> None:
    r = run_scenario(parse_scenario(scenario_text(dur=2.0)), "goal_seek", 0)
    write_outputs(r, tmp_path, plot=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(summary) == SUMMARY_KEYS and summary["reversals"] == 0
