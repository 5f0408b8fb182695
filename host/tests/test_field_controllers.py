"""Perception controllers by name (agnav_host.sim.field_controllers): built from a scenario's field and
[meta], run by the simulator's runner like any planner, refused with a clear reason when the scenario
lacks what they need."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.perception import GroundGuard, ProximityFollower, RowFollower, RutFollower
from agnav_host.sim.field_controllers import FieldControllerError, is_field_controller
from agnav_host.sim.metrics import signed_offset_m
from agnav_host.sim.runner import _make_controller, planner_names, run_scenario
from agnav_host.sim.scenario import load_scenario
from agnav_host.sim.world import sine_curve


def test_names_are_listed_and_recognised():
    names = planner_names()
    for n in ("row-follower", "proximity", "rut-follower"):
        assert n in names
    assert is_field_controller("goal_seek+ground-guard") and is_field_controller("him+ground_guard")
    assert is_field_controller("rut_follower") and not is_field_controller("him")


def test_each_name_builds_its_controller_from_the_scenario():
    curvy = load_scenario("curvy_row")
    prox = _make_controller(curvy, "proximity")
    assert isinstance(prox, ProximityFollower)
    # meta.follow_side = "right" is the robot's side: the row is on the robot's left
    assert prox.params.side == "left" and prox.params.distance_m == 1.0 and prox.params.row_half_width_m == 0.14
    assert prox.params.mount == curvy.laser.mount  # type: ignore[union-attr]
    assert isinstance(_make_controller(load_scenario("crop_rows"), "row-follower"), RowFollower)
    assert isinstance(_make_controller(load_scenario("ruts"), "rut_follower"), RutFollower)
    guard = _make_controller(load_scenario("hole_field"), "him+ground-guard")
    assert isinstance(guard, GroundGuard) and type(guard.inner).__name__ == "HimPlanner"


def test_missing_sensor_or_bad_meta_is_refused_with_the_reason():
    curvy = load_scenario("curvy_row")
    with pytest.raises(FieldControllerError, match=r"tilted_laser.*curvy_row"):
        _make_controller(curvy, "rut-follower")
    with pytest.raises(FieldControllerError, match="tilted_laser"):
        _make_controller(curvy, "goal_seek+ground-guard")
    with pytest.raises(FieldControllerError, match="follow_side"):
        _make_controller(replace(curvy, meta={**curvy.meta, "follow_side": "behind"}), "proximity")
    with pytest.raises(FieldControllerError, match="follow_offset_m"):
        _make_controller(replace(curvy, meta={**curvy.meta, "follow_offset_m": -1.0}), "proximity")
    with pytest.raises(FieldControllerError, match="row_method"):
        _make_controller(replace(load_scenario("crop_rows"), meta={"row_method": "magic"}), "row-follower")


def test_proximity_by_name_follows_the_curvy_row_at_its_meta_distance():
    sc = load_scenario("curvy_row")
    res = run_scenario(sc, "proximity", seed=0)
    tr = res.trajectory
    d = np.abs(signed_offset_m(tr[:, 1], tr[:, 2], sine_curve(0.0, 0.0, 0.0, 48.0, 1.5, 24.0)))[tr[:, 1] > 2.0]
    print(f"{res.end_reason} in {tr[-1, 0]:.1f} s; distance to the row's design line {d.mean():.3f} m, {d.min():.3f}-{d.max():.3f}")
    assert res.end_reason == "arrived"
    assert abs(d.mean() - 1.0) < 0.03 and d.min() > 0.9 and d.max() < 1.1


def test_cli_runs_a_field_controller_and_refuses_one_the_scenario_cannot_run(tmp_path, capsys):
    assert main(["sim", "hole_field", "--planner", "goal_seek+ground-guard", "--out", str(tmp_path / "ok"),
                 "--quiet", "--no-plot", "--no-rrd"]) == 0
    assert "hole_field: arrived" in capsys.readouterr().out
    assert main(["sim", "curvy_row", "--planner", "rut-follower", "--out", str(tmp_path / "no"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "needs a [tilted_laser]" in err and "curvy_row" in err
    assert not (tmp_path / "no").exists()
