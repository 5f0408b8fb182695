"""The timed planner through the firmware SIL (native firmware, calibration dead band, radio link):
the host localises on the marker posts and meets the timed targets; on odometry alone it does not."""

from __future__ import annotations

import math
from dataclasses import replace

from agnav_host.sil import run_sil_scenario
from agnav_host.sil.session import PlannerHost
from agnav_host.sim import load_scenario


def test_sil_host_uses_the_post_localiser_only_when_the_scenario_lists_posts():
    sc = load_scenario("timed_static")
    assert PlannerHost(sc, "timed").localiser is not None
    bare = replace(sc, meta={})
    assert PlannerHost(bare, "timed").localiser is None


def test_timed_run_in_the_sil_arrives_on_time_with_posts_and_misses_on_odometry_alone():
    sc = load_scenario("timed_static")
    goal = sc.goals[-1]
    with_posts = run_sil_scenario(sc, "timed", seed=1)
    m = with_posts.run.metrics
    assert with_posts.run.end_reason == "arrived", with_posts.run.end_reason
    assert m.arrival_time_error_s is not None and abs(m.arrival_time_error_s) <= 0.2, m.arrival_time_error_s
    assert m.final_heading_error_deg is not None and m.final_heading_error_deg <= 2.0, m.final_heading_error_deg
    # odometry alone: the drift keeps the car out of the 5 cm circle
    alone = run_sil_scenario(replace(sc, meta={}), "timed", seed=1)
    assert alone.run.end_reason == "timeout"
    p = alone.run.trajectory[-1]
    assert math.hypot(goal.x_m - p[1], goal.y_m - p[2]) > 0.1
