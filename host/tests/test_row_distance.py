"""How far a run kept from a plant row's design line: the metric, and `agnav sim` writing it for the
proximity follower."""

import json
import math

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.sim.metrics import row_distance
from agnav_host.sim.scenario import load_scenario


def test_row_distance_of_a_path_beside_a_straight_row():
    x = np.linspace(0.0, 10.0, 201)
    y = np.full_like(x, -1.0)
    y[150] = -1.08  # one sample 8 cm further off
    rd = row_distance(x, y, [np.array([[0.0, 0.0], [10.0, 0.0]])], set_m=1.0, settle_m=2.0)
    assert rd is not None
    assert rd.travel_m[0] >= 2.0 and abs(len(rd.distance_m) - 161) <= 1  # the samples from 2 m of travel on
    assert rd.min_m == pytest.approx(1.0) and rd.max_m == pytest.approx(1.08)
    assert rd.within == pytest.approx(1.0 - 1.0 / len(rd.distance_m))
    assert rd.to_dict()["samples"] == len(rd.distance_m)


def test_row_distance_takes_the_nearest_of_several_rows():
    x = np.linspace(0.0, 5.0, 51)
    rows = [np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([[0.0, -1.7], [5.0, -1.7]])]  # robot at y = -1: 0.7 from the second
    rd = row_distance(x, np.full_like(x, -1.0), rows, set_m=0.7, settle_m=0.0)
    assert rd is not None and rd.mean_m == pytest.approx(0.7) and rd.within == 1.0


def test_row_distance_is_none_without_rows_or_travel():
    x = np.linspace(0.0, 1.0, 11)
    assert row_distance(x, x * 0.0, [], set_m=1.0) is None
    assert row_distance(x, x * 0.0, [np.array([[0.0, 1.0], [1.0, 1.0]])], set_m=1.0, settle_m=2.0) is None


def test_scenario_keeps_each_rows_design_line():
    sc = load_scenario("curvy_row")
    assert len(sc.world.row_lines) == 1
    line = sc.world.row_lines[0]
    k = 2.0 * math.pi / 24.0
    np.testing.assert_allclose(line[:, 1], 1.5 * np.sin(k * line[:, 0]), atol=1e-9)  # the sine the bushes were laid on
    assert len(load_scenario("crop_rows").world.row_lines) >= 2


def test_sim_proximity_writes_and_prints_the_row_distance(tmp_path, capsys):
    assert main(["sim", "curvy_row", "--planner", "proximity", "--duration", "20", "--out", str(tmp_path),
                 "--quiet", "--no-rrd"]) == 0
    out = capsys.readouterr().out
    rd = json.loads((tmp_path / "row_distance.json").read_text())
    assert rd["set_m"] == 1.0 and rd["samples"] > 100
    assert 0.9 < rd["min_m"] <= rd["mean_m"] <= rd["max_m"] < 1.1  # it follows at about 1 m
    assert "distance from the row" in out and f"{rd['mean_m']:.3f} m" in out
    assert (tmp_path / "row_distance.png").stat().st_size > 0


def test_sim_other_planners_write_no_row_distance(tmp_path):
    assert main(["sim", "curvy_row", "--duration", "2", "--out", str(tmp_path), "--quiet", "--no-plot", "--no-rrd"]) == 0
    assert not (tmp_path / "row_distance.json").exists()


def test_sim_proximity_too_short_to_measure_says_so(tmp_path, capsys):
    assert main(["sim", "curvy_row", "--planner", "proximity", "--duration", "0.5", "--out", str(tmp_path),
                 "--quiet", "--no-plot", "--no-rrd"]) == 0
    assert "not measured" in capsys.readouterr().out
    assert not (tmp_path / "row_distance.json").exists()
