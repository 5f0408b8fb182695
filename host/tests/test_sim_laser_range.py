"""A laser with no range (max_range_m = 0, horizontal or tilted) is a scenario error naming its key and line."""

from __future__ import annotations

import pytest

from agnav_host.sim.scenario import ScenarioError, parse_scenario
from _scenario_text import scenario_text


@pytest.mark.parametrize("table, extra", [("laser", ""), ("tilted_laser", "[tilted_laser]\nmax_range_m = 0.0")])
def test_zero_laser_range_is_a_scenario_error(table: str, extra: str) -> None:
    txt = scenario_text(laser="max_range_m = 0.0" if table == "laser" else "", extra=extra)
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(txt, "<t>")
    assert ei.value.field == f"{table}.max_range_m"
    assert ei.value.line == [i for i, s in enumerate(txt.splitlines(), 1) if s.startswith("max_range_m")][0]
