"""Whole fields through `agnav sim` and the SIL: the summary's field keys, field.json and field.png, --pattern, and the
proximity follower measured against the row as planted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.sim.field_gen import FieldSpec, generate_field
from agnav_host.sim.metrics import FIELD_SUMMARY_KEYS, SUMMARY_KEYS, row_distance
from agnav_host.sim.scenario import parse_scenario


def test_sim_scores_a_field_and_writes_field_json_and_png(tmp_path, capsys):
    assert main(["sim", "field_easy", "--planner", "row-navigator", "--pattern", "S-1L-F", "--out", str(tmp_path),
                 "--quiet", "--no-rrd"]) == 0
    out = capsys.readouterr().out
    s = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(s) == SUMMARY_KEYS and set(FIELD_SUMMARY_KEYS) <= set(s)
    assert s["rows_completed"] == 2 and s["pattern_completed"] is True and s["plants_touched"] == 0
    f = json.loads((tmp_path / "field.json").read_text())
    assert f["pattern"] == "S-1L-F" and [v["lane"] for v in f["lanes"]] == [0, 1] and len(f["turns_s"]) == 1
    assert f["field_score_m"] == pytest.approx(s["field_score_m"])
    assert s["field_score_m"] == pytest.approx(s["field_distance_m"] * f["time_limit_s"] / s["field_time_s"], rel=1e-3)
    assert (tmp_path / "field.png").stat().st_size > 0
    assert "2/2 lanes in the pattern's order, pattern completed, 0 plants touched" in out


def test_a_run_off_a_field_has_no_field_figures(tmp_path):
    assert main(["sim", "crop_rows", "--planner", "row-follower", "--duration", "3", "--out", str(tmp_path),
                 "--quiet", "--no-plot", "--no-rrd"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    assert all(s[k] is None for k in FIELD_SUMMARY_KEYS)
    assert not (tmp_path / "field.json").exists()


@pytest.mark.parametrize("scenario,pattern,why", [("crop_rows", "S-1L-F", "no [field]"),
                                                  ("field_easy", "S-9L-F", "out of the field"),
                                                  ("field_easy", "S-1Q-F", "is not a turn")])
def test_sim_refuses_a_pattern_it_cannot_drive_with_exit_2(tmp_path, capsys, scenario, pattern, why):
    assert main(["sim", scenario, "--planner", "row-navigator", "--pattern", pattern, "--out", str(tmp_path),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert why in err and "Traceback" not in err


def test_a_field_run_may_brush_plants_without_ending_and_counts_the_stems():
    from agnav_host.sim.runner import run_scenario
    from agnav_host.types import DriveCommand

    class Straight:  # straight on at 8 deg across the rows
        def reset(self) -> None:
            pass

        def step(self, obs: object) -> DriveCommand:
            return DriveCommand(0.4, 0.0)

    text = generate_field(FieldSpec(rows=3, length_m=6.0, seed=2, pattern="S-F", weeds_per_m=0.0, ragged_m=0.0))
    start = text[text.index("start = {"):].splitlines()[0]
    sc = parse_scenario(text.replace(start, start.split("yaw_deg")[0] + "yaw_deg = 8.0 }"), "<field>")
    r = run_scenario(sc, "straight", duration_s=15.0, controller=Straight())
    assert r.end_reason == "timeout"  # through row 1 and on: plants are soft, only the fence is solid
    # the 0.4 m disc runs along a row for 0.4 / sin(8 deg) = 2.9 m: about 19 stems 0.15 m apart
    assert 15 <= r.metrics.plants_touched <= 24


def test_row_distance_against_the_row_as_planted():
    # stems 4 cm left of a straight design line: a path 1 m right of the line is 1.04 m from the row as planted
    line = np.array([[0.0, 0.0], [20.0, 0.0]])
    stems = np.column_stack((np.arange(0.0, 20.0, 0.35), np.full(58, 0.04)))
    x = np.linspace(0.0, 20.0, 400)
    rd = row_distance(x, np.full_like(x, -1.0), [line], set_m=1.0, plants=[stems])
    assert rd is not None and rd.mean_m == pytest.approx(1.0)
    pl = rd.planted()
    assert pl is not None and pl["mean_m"] == pytest.approx(1.04, abs=1e-6) and pl["window_m"] == 3.0
    assert rd.to_dict()["planted"]["mean_m"] == pytest.approx(1.04)
    wavy = stems.copy()
    wavy[:, 1] = 0.05 * np.sin(2 * np.pi * wavy[:, 0] / 12.0)  # a 12 m wave: followed by a 3 m mean
    pl = row_distance(x, np.full_like(x, -1.0), [line], set_m=1.0, plants=[wavy]).planted()
    assert pl["max_m"] == pytest.approx(1.05, abs=0.01) and pl["min_m"] == pytest.approx(0.95, abs=0.01)


def test_sim_prints_the_distance_to_the_row_as_planted_beside_the_design_line(tmp_path, capsys):
    assert main(["sim", "curvy_row", "--planner", "proximity", "--duration", "20", "--out", str(tmp_path),
                 "--quiet", "--no-rrd", "--no-plot"]) == 0
    out = capsys.readouterr().out
    rd = json.loads((tmp_path / "row_distance.json").read_text())
    assert "planted" in rd and 0.9 < rd["planted"]["min_m"] <= rd["planted"]["max_m"] < 1.1
    assert "from the row as planted" in out and "design line" in out
    assert out.index("as planted") < out.index("design line")


@pytest.mark.parametrize("robot", ["diff_drive", "ackermann"])
def test_a_field_through_the_sil(robot):
    from agnav_host.sil.session import run_sil_scenario

    sc = parse_scenario(generate_field(FieldSpec(rows=3, length_m=6.0, seed=4, robot=robot, pattern="S-1L-F",
                                                 gap_share=0.1)), "<field>")
    r = run_sil_scenario(sc, "row-navigator", seed=1).run
    m = r.metrics
    assert (m.rows_completed, m.pattern_completed, m.plants_touched) == (2, True, 0), r.end_reason
    assert r.end_reason == "arrived"
