"""The robot path end to end: `agnav sil SCENARIO --laser KIND` in one process, `agnav run --laser URL` in another,
over TCP on loopback, in real time (agnav_host.sil.robot_path). The truth comes from the SIL's referee; the robot
side writes the same summary keys as `agnav sim`, a laser log that replays, and its laser-to-command latency."""

from __future__ import annotations

import json

import numpy as np

from agnav_host.lasers.log import laser_log_info, read_laser_log
from agnav_host.sil.robot_path import row_distance_of, run_robot_path, timed_errors
from agnav_host.sim.metrics import SUMMARY_KEYS
from agnav_host.sim.scenario import load_scenario


def _robot_side_outputs_are_complete(r, n_lasers: int) -> None:
    assert r.run_summary is not None and list(r.run_summary) == list(SUMMARY_KEYS), r.run_log[-2000:]
    info = laser_log_info(r.out / "run" / "laser.alog")
    assert len(info.lasers) == n_lasers and all(n > 50 for n in info.scans.values()), info.scans
    scans = list(read_laser_log(r.out / "run" / "laser.alog"))
    assert sum(bool(np.isfinite(s.scan.ranges_m).any()) for s in scans) > 50
    assert all(s.pose is not None for s in scans[5:])
    assert (r.out / "run" / "link.tlog").stat().st_size > 1000
    assert r.latency["scans"] > 50 and 0 < r.latency["median_ms"] < 150, r.latency


def test_row_following_on_a_tim5xx_over_cola_b(tmp_path):
    sc = load_scenario("crop_rows")
    r = run_robot_path(sc, "row-follower", tmp_path, ("tim5xx",))
    assert r.end_reason == "arrived", (r.sil_log[-1500:], r.run_log[-1500:])
    assert r.truth_summary["min_clearance_m"] > 0.05
    _robot_side_outputs_are_complete(r, 1)


def test_proximity_following_on_a_hokuyo_ust(tmp_path):
    sc = load_scenario("curvy_row")
    r = run_robot_path(sc, "proximity", tmp_path, ("ust",), duration_s=25.0)
    rd = row_distance_of(r, sc)
    assert rd is not None, r.run_log[-1500:]
    assert abs(rd.mean_m - 1.0) < 0.03 and 0.9 < rd.min_m and rd.max_m < 1.1, rd.to_dict()
    assert r.run_info is not None and r.run_info["lasers"][0]["model"].count("UST")
    _robot_side_outputs_are_complete(r, 1)


def test_hole_field_with_a_horizontal_and_a_tilted_sick(tmp_path):
    sc = load_scenario("hole_field")
    r = run_robot_path(sc, "goal_seek+ground-guard", tmp_path, ("lms1xx", "lms5xx"))
    assert r.end_reason == "arrived", (r.sil_log[-1500:], r.run_log[-1500:])
    roles = [x["role"] for x in r.run_info["lasers"]]
    assert roles == ["laser", "tilted_laser"]
    _robot_side_outputs_are_complete(r, 2)


def test_timed_arrival_on_a_urg_over_a_pty(tmp_path):
    sc = load_scenario("timed_static")
    r = run_robot_path(sc, "timed", tmp_path, ("urg",))
    assert r.end_reason == "arrived", (r.sil_log[-1500:], r.run_log[-1500:])
    e = timed_errors(r, sc)
    assert e["final_error_m"] <= 0.05 and e["heading_error_deg"] <= 2.0 and abs(e["arrival_error_s"]) <= 0.2, e
    assert json.loads((tmp_path / "run" / "run_info.json").read_text())["end_reason"] == "arrived"
    _robot_side_outputs_are_complete(r, 1)


def test_a_whole_field_by_its_pattern_on_a_tim5xx_over_cola_b(tmp_path):
    sc = load_scenario("field_easy")
    r = run_robot_path(sc, "row-navigator", tmp_path, ("tim5xx",), duration_s=70.0, run_args=("--pattern", "S-1L-F"))
    s = r.truth_summary  # scored on the field's own pattern, whose first turn is 1L too
    assert s["rows_completed"] == 2 and s["plants_touched"] == 0, (r.sil_log[-1500:], r.run_log[-1500:])
    assert r.run_info is not None and "pattern done" in [e for _, e in r.run_info["controller_events"]]
    assert abs(r.truth[-1, 4]) < 0.02  # the robot stands once the pattern is done
    _robot_side_outputs_are_complete(r, 1)
