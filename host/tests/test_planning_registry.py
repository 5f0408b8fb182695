import json

import pytest

from agnav_host.cli import main
from agnav_host.planning import PlanningError, RobotSpec, UnknownPlanner, canonical_name, make_planner, planner_names
from agnav_host.planning.base import DeadlineMissed, NoPathFound
from agnav_host.planning._grid import OccupancyGrid
from agnav_host.sim import load_scenario, run_scenario

REFERENCE_PLANNERS = ["flb", "him", "vfh", "pbf", "apf", "subsumption", "follow-path"]


def test_registry_lists_the_reference_planners_first_and_builds_each():
    assert planner_names()[: len(REFERENCE_PLANNERS)] == REFERENCE_PLANNERS  # later planners (timed) come after
    for n in REFERENCE_PLANNERS:
        p = make_planner(n, RobotSpec())
        assert p.name == n
        p.reset()


def test_alias_and_unknown_name():
    assert canonical_name("follow_path") == "follow-path"
    with pytest.raises(UnknownPlanner, match=r"unknown planner 'astar'; known: flb, him, vfh"):
        make_planner("astar")
    assert issubclass(UnknownPlanner, ValueError) and issubclass(UnknownPlanner, PlanningError)


def test_params_are_validated():
    with pytest.raises(ValueError, match="trsh"):
        make_planner("flb", RobotSpec(), {"trsh": 1.5})
    with pytest.raises(ValueError, match="bad parameters"):
        make_planner("flb", RobotSpec(), {"no_such_field": 1})
    assert make_planner("flb", RobotSpec(), {"trsh": 0.3}).params.trsh == 0.3


def test_cli_sim_planner_choice_and_unknown(tmp_path, capsys):
    assert main(["sim", "--planner", "vfh", "--duration", "2", "--out", str(tmp_path / "a"), "--quiet", "--no-plot"]) == 0
    assert json.loads((tmp_path / "a" / "run_info.json").read_text())["planner"] == "vfh"
    assert main(["sim", "--planner", "nope", "--out", str(tmp_path / "b"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown planner 'nope'" in err and "follow-path" in err and "goal_seek" in err


def test_default_sim_run_succeeds_with_seed_0(tmp_path):
    """`make demo` runs `agnav sim --out DIR` (default scenario, seed 0)."""
    assert main(["sim", "--out", str(tmp_path), "--quiet", "--no-plot"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["success"] is True, s


def test_astar_is_bounded():
    g = OccupancyGrid((0.0, 0.0), 40.0, 0.1)
    with pytest.raises(DeadlineMissed):
        g.plan((-15.0, -15.0), (15.0, 15.0), 0.3, margin_cells=100, max_expansions=50)
    import numpy as np

    wall = np.column_stack((np.full(400, 1.0), np.linspace(-20, 20, 400)))
    for _ in range(3):
        g.add_points(wall)
    with pytest.raises(NoPathFound):
        g.plan((0.0, 0.0), (3.0, 0.0), 0.3, margin_cells=10)


@pytest.mark.parametrize("name", REFERENCE_PLANNERS)
def test_every_planner_reaches_the_goal_on_corridor_obstacles(name):
    r = run_scenario(load_scenario("corridor_obstacles"), name, seed=0)
    end = r.trajectory[-1]
    assert r.end_reason == "arrived", f"{name}: {r.end_reason} at ({end[1]:.2f}, {end[2]:.2f}) after {r.metrics.time_s:.1f} s"
    assert r.metrics.min_clearance_m > 0.0


@pytest.mark.parametrize("name", planner_names())
def test_declared_sensors_are_what_a_step_needs(name):
    """sensors_needed() (used to refuse a run before it starts) matches what each planner's step() does:
    without a scan a laser planner raises InvalidObservation, and so does a sonar planner without a frame."""
    import numpy as np

    from agnav_host.planning.base import InvalidObservation
    from agnav_host.planning.registry import sensors_needed
    from agnav_host.types import Goal, Observation, Pose2D

    from _planning_helpers import empty_scan, sonar_frame

    def fails(scan, sonar) -> bool:
        p = make_planner(name, RobotSpec())
        p.reset()
        try:
            p.step(Observation(0.0, Pose2D(), 0.0, 0.0, Goal(5.0, 0.0), scan, sonar, {}))
        except InvalidObservation:
            return True
        return False

    needs = sensors_needed(name)
    assert fails(None, sonar_frame(np.full(12, 3.0))) == ("laser" in needs)
    assert fails(empty_scan(), None) == ("sonar" in needs)
