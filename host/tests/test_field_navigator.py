"""The row navigator: a whole field by its turn pattern, rows counted on the headland from the laser, both robots."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.planning.registry import ControllerContext, FieldDescription, make_controller
from agnav_host.planning.row_navigator import RowEndMap, RowNavigator, row_reach_m
from agnav_host.sim.field_controllers import make_scenario_controller
from agnav_host.sim.field_gen import FieldLayout, FieldSpec, generate_field, with_pattern
from agnav_host.sim.metrics import count_reversals
from agnav_host.sim.runner import robot_spec, run_scenario
from agnav_host.sim.scenario import parse_scenario
from agnav_host.types import Goal, Observation, Pose2D


def _field(**kw: object) -> object:
    base = dict(rows=4, length_m=6.0, seed=3, weeds_per_m=0.3, missing_share=0.03)
    base.update(kw)
    return parse_scenario(generate_field(FieldSpec(**base)), "<field>")  # type: ignore[arg-type]


def _run(sc: object, seed: int = 0) -> tuple[object, RowNavigator]:
    nav = make_scenario_controller(sc, "row-navigator")  # type: ignore[arg-type]
    assert isinstance(nav, RowNavigator)
    return run_scenario(sc, "row-navigator", seed=seed, controller=nav), nav  # type: ignore[arg-type]


# ---- the pieces ------------------------------------------------------------------------------------------------

def _row_points(x0: float, x1: float, y: float, gaps: list[tuple[float, float]] = ()) -> np.ndarray:
    x = np.arange(x0, x1, 0.15)
    for a, b in gaps:
        x = x[(x < a) | (x > b)]
    return np.column_stack((x, np.full(len(x), y)))


def test_reach_counts_over_a_gap_on_both_sides_but_not_over_the_headland():
    gap = [(1.0, 2.0)]
    pts = np.vstack((_row_points(-0.5, 5.0, 0.375, gap), _row_points(-0.5, 5.0, -0.375, gap)))
    assert row_reach_m(pts, 0.0, 0.375, -0.375) == pytest.approx(5.0, abs=0.15)  # a 1 m gap on both sides
    pts = np.vstack((_row_points(-0.5, 0.3, 0.375), _row_points(-0.5, 0.3, -0.375),
                     np.column_stack((np.full(20, 2.3), np.linspace(-2, 2, 20)))))  # the row end, a fence 2 m on
    assert row_reach_m(pts, 0.0, 0.375, -0.375) == pytest.approx(0.3, abs=0.1)


def test_row_end_map_finds_each_row_and_where_it_ends_and_no_row_in_a_weed():
    m = RowEndMap(Pose2D(0.0, 0.0, 0.0), 3.0)
    ends = {-0.375: 0.0, 0.375: 0.2, 1.125: -0.3, 1.875: 0.45}
    for _ in range(3):  # three scans' worth
        for y, e in ends.items():
            m.add(_row_points(e - 2.0, e + 0.01, y))
        m.add(np.array([[-1.0, 0.75], [-1.0, 0.76], [-1.4, 1.5]]))  # weeds in the lanes
    rows = m.rows()
    assert [round(r.v_m, 1) for r in rows] == [-0.4, 0.4, 1.1, 1.9]
    for r, e in zip(rows, ends.values()):
        assert r.end_u_m == pytest.approx(e, abs=0.06)


# ---- whole fields in the simulator --------------------------------------------------------------------------

@pytest.mark.parametrize("robot", ["diff_drive", "ackermann"])
def test_navigator_drives_the_pattern_and_stops_at_the_finish(robot):
    sc = _field(robot=robot, gap_share=0.1, curvature=0.01, pattern="S-1L-1R-F", time_limit_s=120.0)
    r, nav = _run(sc)
    m = r.metrics
    assert (m.rows_completed, m.pattern_completed, m.plants_touched) == (3, True, 0), nav.events
    assert r.end_reason == "arrived" and nav.lanes == 3 and nav.turns == 2
    assert m.field_score_m > m.field_distance_m  # finished before the task's time: the bonus


def test_navigator_counts_the_rows_on_the_headland_to_skip_lanes():
    sc = _field(rows=6, length_m=5.0, pattern="S-3L-2L-F", ragged_m=0.3, seed=8)
    r, nav = _run(sc)
    f = r.metrics.field_detail
    assert [v.lane for v in f.lanes] == [0, 3, 1] and r.metrics.plants_touched == 0, nav.events


def test_navigator_crosses_gaps_on_both_sides_without_a_false_row_end():
    sc = _field(rows=4, length_m=14.0, gap_share=0.3, seed=21, pattern="S-1L-F", time_limit_s=120.0)
    bare = [(a, b) for st in sc.world.row_plants[1:3] for a, b in zip(np.sort(st[:, 0])[:-1], np.sort(st[:, 0])[1:])
            if b - a > 0.5]
    assert len(bare) >= 4  # the lane has gaps
    r, nav = _run(sc)
    ends = [t for t, e in nav.events if e.endswith("ends")]
    assert len(ends) == 2 and r.metrics.pattern_completed and r.metrics.plants_touched == 0, nav.events


def test_a_differential_drive_backs_up_between_close_lanes_and_an_omega_turn_does_without():
    sc = _field(pattern="S-1L-F")
    r, nav = _run(sc)
    assert "leg" in [e for _, e in nav.events] and r.metrics.pattern_completed
    assert count_reversals(r.trajectory[:, 1:3]) >= 2  # forward, back along the headland, forward
    ctx = ControllerContext(spec=robot_spec(sc), field=FieldDescription(pattern="S-1L-F", reverse=False),
                            laser_mount=sc.laser.mount)
    nav2 = make_controller("row-navigator", ctx)
    r2 = run_scenario(sc, "row-navigator", controller=nav2)
    assert "omega" in [e for _, e in nav2.events] and r2.metrics.pattern_completed
    assert count_reversals(r2.trajectory[:, 1:3]) == 0 and r2.metrics.plants_touched == 0


def test_the_rc_car_never_reverses_and_keeps_its_least_speed():
    sc = _field(robot="ackermann", pattern="S-1L-F")
    nav = make_scenario_controller(sc, "row-navigator")
    assert not nav.params.reverse and nav.params.follower.speed_m_s >= 0.435  # its speed table's first step
    r = run_scenario(sc, "row-navigator", controller=nav)
    assert r.metrics.pattern_completed and r.metrics.plants_touched == 0
    moving = r.trajectory[r.trajectory[:, 0] > 1.0, 4]
    assert moving.min() > -1e-6  # never backwards


def test_the_navigator_stands_still_once_the_pattern_is_done():
    sc = _field(pattern="S-F")
    sc = with_pattern(sc, "S-F")
    r, nav = _run(sc)
    assert nav.lanes == 1 and r.metrics.pattern_completed
    obs = Observation(0.0, Pose2D(50.0, 50.0, 0.0), 0.0, 0.0, Goal(0.0, 0.0))
    for _ in range(50):  # drive it on past the finish
        cmd = nav.step(obs)
    assert nav.done and cmd.speed_m_s == 0.0 and cmd.yaw_rate_rad_s == 0.0


def test_the_time_in_a_lane_is_its_length_at_the_lane_speed():
    sc = _field(rows=3, length_m=10.0, pattern="S-1L-F", ragged_m=0.0)
    r, nav = _run(sc)
    speed = nav.params.follower.speed_m_s
    for v in r.metrics.field_detail.lanes:
        assert v.t_out_s - v.t_in_s <= 1.10 * v.length_m / speed


def test_registry_takes_the_pattern_spacing_and_drive_limits_from_the_field():
    sc = _field(spacing_m=0.8, pattern="S-2L-F", rows=5)
    nav = make_scenario_controller(sc, "row-navigator")
    p = nav.params
    assert [str(t) for t in p.pattern] == ["2L"] and p.finish and p.row_spacing_m == 0.8
    assert p.follower.rows.expected_spacing_m == 0.8
    assert nav.turn_radius_m == pytest.approx(1.1 * 0.4)  # a differential drive turns no tighter than its track
    legacy = make_controller("row-navigator", ControllerContext(field=FieldDescription(first_turn="right", lanes_per_turn=2),
                                                                laser_mount=Pose2D()))
    assert not legacy.params.finish and [legacy._next_turn().side for _ in range(1)] == ["right"]
    legacy.turns = 1
    assert legacy._next_turn().side == "left" and legacy._next_turn().lanes == 2  # then alternating, for good


def test_a_bad_pattern_is_refused_when_the_controller_is_built():
    with pytest.raises(ValueError, match="turn pattern"):
        make_controller("row-navigator", ControllerContext(field=FieldDescription(pattern="S-2Q-F"), laser_mount=Pose2D()))


def test_field_layout_goals_lie_beyond_each_lanes_end_in_the_patterns_order():
    sc = _field(rows=6, pattern="S-1L-2R-F")
    lay = FieldLayout.of(sc)
    seq = lay.sequence(sc.field.pattern)
    for g, lane, d in zip(sc.goals, seq, lay.directions(seq)):
        c = lay.lanes[lane].centre
        end = c[-1] if d > 0 else c[0]
        assert math.hypot(g.x_m - end[0], g.y_m - end[1]) < 1.0
