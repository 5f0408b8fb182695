"""The planners' control period is the period at which the simulator's runner calls them, and a control rate
above the physics rate is refused with its key and line."""

from __future__ import annotations

import numpy as np
import pytest

from agnav_host.sim.runner import robot_spec, run_scenario
from agnav_host.sim.scenario import ScenarioError, builtin_text, load_scenario, parse_scenario
from agnav_host.types import DriveCommand, Observation
from _scenario_text import scenario_text


class _Recorder:
    """A controller that stands still and records when it was called."""

    uses_sonar = False

    def __init__(self) -> None:
        self.t_s: list[float] = []

    def reset(self) -> None:
        self.t_s.clear()

    def step(self, obs: Observation) -> DriveCommand:
        self.t_s.append(obs.t_s)
        return DriveCommand(0.0, 0.0)


@pytest.mark.parametrize("name", ["corridor_obstacles", "flb_setup1"])
def test_robot_spec_control_dt_is_the_real_call_period(name: str) -> None:
    sc = load_scenario(name)
    rec = _Recorder()
    run_scenario(sc, "rec", 0, duration_s=3.0, controller=rec)
    period = float(np.diff(rec.t_s).mean())
    assert robot_spec(sc).control_dt_s == pytest.approx(period, abs=1e-12)


def test_control_hz_above_physics_rate_is_rejected_with_key_and_line() -> None:
    txt = builtin_text("corridor_obstacles").replace("control_hz = 15.0", "control_hz = 100.0")
    assert "control_hz = 100.0" in txt
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(txt, "<t>")
    line = next(i for i, s in enumerate(txt.splitlines(), 1) if s.startswith("control_hz"))
    assert ei.value.field == "scenario.control_hz" and ei.value.line == line
    sc = parse_scenario(scenario_text(hz=50.0))  # exactly one call per physics step is fine
    assert robot_spec(sc).control_dt_s == pytest.approx(0.02)
