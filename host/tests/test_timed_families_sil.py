"""A goal that needs a U-turn, driven by the timed planner through the firmware SIL (native firmware,
calibration dead band, radio link; the host on odometry and marker posts), past an unknown box and a
walker: the continuous-curvature plan meets the timed targets (5 cm, 2 deg, 0.2 s)."""

from __future__ import annotations

import ast
from pathlib import Path

from agnav_host.sil import run_sil_scenario
from agnav_host.sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[2]


def _uturn_toml() -> str:
    """The benchmark's U-turn scenario (``UTURN_TOML`` in bench/bench_timed.py), read without running the script."""
    tree = ast.parse((ROOT / "bench" / "bench_timed.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "UTURN_TOML" for t in node.targets):
            return str(ast.literal_eval(node.value))
    raise AssertionError("bench/bench_timed.py has no UTURN_TOML")


def test_a_u_turn_goal_in_the_sil_meets_the_timed_targets():
    sc = parse_scenario(_uturn_toml())
    out = run_sil_scenario(sc, "timed", seed=1)
    m = out.run.metrics
    assert out.run.end_reason == "arrived", out.run.end_reason
    assert m.arrival_time_error_s is not None and abs(m.arrival_time_error_s) <= 0.2, m.arrival_time_error_s
    assert m.final_heading_error_deg is not None and m.final_heading_error_deg <= 2.0, m.final_heading_error_deg
    assert m.final_position_error_m <= 0.05, m.final_position_error_m
    assert m.min_clearance_m is None or m.min_clearance_m > 0.0
