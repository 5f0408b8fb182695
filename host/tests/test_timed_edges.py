"""Time-critical planning at its edges: requests the planner cannot serve must come back as plans that
say so (never an exception, never a "feasible" plan the car cannot drive), and the calibration lookups
must agree with the firmware's."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agnav_host import cli
from agnav_host.calib import default_speed_table, default_steering_table
from agnav_host.calibration import fit as F
from agnav_host.link.calib_wire import TABLE_SPEED, TABLE_STEER, from_calib_table, round_trips
from agnav_host.planning.timed import BoundaryState, build_path, TimedLimits, TimedPlanner, TrackingParams, TrackState, plan_timed, steer_from_arc, track
from agnav_host.perception import Track
from agnav_host.planning.timed._obstacles import moving_obstacles_from
from agnav_host.types import Goal, LaserScan, Observation, Pose2D


def _speeds(plan, n=4000):
    t = np.linspace(0.0, plan.profile.duration_s, n)
    _, v = plan.profile.eval(t)
    return t, v


def test_planner_with_no_path_to_its_goal_stands_still_and_says_why():
    # the goal is the start pose itself: there is nothing to drive
    pl = TimedPlanner()
    pl.reset()
    goal = Goal(0.0, 0.0, 0.0, 20.0, 0.05)
    for k in range(5):
        cmd = pl.step(Observation(k * 0.05, Pose2D(), 0.0, 0.0, goal, None, None, {}))
        assert (cmd.speed_m_s, cmd.steer_rad) == (0.0, 0.0)
    assert pl.status["feasible"] is False
    assert "the start is the goal" in pl.status["reason"]


def test_a_goal_straight_behind_with_the_same_heading_is_reached_by_a_loop():
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(-3.0, 0.0, 0.0), 0.0, 20.0)
    assert p.feasible, p.reason
    assert p.path.kind.startswith("clothoid") and p.path.reverse_m == 0.0
    assert p.max_steering_rad <= TimedLimits().plan_steer_rad + 1e-9


@pytest.mark.parametrize("accel, v_min, dist", [(0.3, 0.435, 0.3), (0.5, 0.9, 1.0), (0.3, 0.435, 0.5)])
def test_too_short_to_reach_the_band_before_the_stop_is_a_plan_not_an_exception(accel, v_min, dist):
    lim = TimedLimits(accel_m_s2=accel, v_min_m_s=v_min)
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(dist, 0.0, 0.0), 0.0, 10.0, lim)
    t, v = _speeds(p)
    dv = np.diff(v) / np.diff(t)
    if p.feasible:
        # then it really reaches the band and ramps within the limit (the stop tail excepted)
        assert v.max() >= v_min - 1e-9
        ramps = [a for a, k in zip(p.profile.a_m_s2, p.profile.kind) if k != "stop"]
        assert max(abs(a) for a in ramps) <= accel + 1e-9
    else:
        assert "smallest move" in p.reason
        # the straight move is too short; a loop of the path families gets there later
        assert p.earliest_arrival_s is None or p.earliest_arrival_s > 10.0
    assert np.all(np.isfinite(dv))


def test_plan_cli_reports_a_too_short_move_with_exit_3(capsys):
    # too short a move straight ahead, and too little time for a loop round to it
    rc = cli.main(["plan", "--start", "0,0,0", "--goal", "0.3,0,0", "--arrive-in", "4", "--accel", "0.3", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 3
    assert out["feasible"] is False and "smallest move" in out["reason"]
    assert out["earliest_arrival_s"] > 4.0 and out["path_type"].startswith("clothoid")


@pytest.mark.parametrize("dist, feasible", [(0.05, False), (0.10, False), (0.15, False), (0.25, True), (1.0, True)])
def test_a_move_that_never_reaches_the_speed_band_is_not_feasible(dist, feasible):
    lim = TimedLimits()
    straight = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(dist, 0.0, 0.0), 0.0, 5.0, lim,
                          path=build_path([BoundaryState(0.0, 0.0, 0.0), BoundaryState(dist, 0.0, 0.0)], lim.wheelbase_m))
    assert straight.feasible is feasible, straight.reason
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(dist, 0.0, 0.0), 0.0, 5.0, lim)
    assert p.feasible, p.reason  # a loop of the path families when the straight move is too short
    if not feasible:
        assert p.path.kind.startswith("clothoid") and p.path.length_m > 1.0
    _, v = _speeds(p)
    assert v.max() >= lim.v_min_m_s - 1e-9


def test_stop_and_wait_without_room_to_brake_is_not_feasible_and_keeps_the_speed_continuous():
    lim = TimedLimits()
    v0, S = 1.8, 1.2  # braking at 1 m/s^2 needs 1.62 m
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0, 0.0, v0), BoundaryState(S, 0.0, 0.0), 0.0, 10.0, lim, dwell_first_s=1.0)
    assert p.feasible is False and "stop and wait" in p.reason
    _, v0_plan = p.profile.eval(0.0)
    assert float(v0_plan) == pytest.approx(v0)  # no jump from the car's speed to 0
    assert p.profile.kind[0] == "ramp" and p.profile.a_m_s2[0] == pytest.approx(-v0 * v0 / (2.0 * S))
    # with room to brake it stays feasible, braking at the limit
    q = plan_timed(BoundaryState(0.0, 0.0, 0.0, 0.0, 1.0), BoundaryState(3.0, 0.0, 0.0), 0.0, 10.0, lim, dwell_first_s=1.0)
    assert q.feasible and q.profile.a_m_s2[0] == pytest.approx(-lim.accel_m_s2)


def test_summary_reports_the_cars_own_stop_apart_from_the_ramp_limit():
    lim = TimedLimits(accel_m_s2=0.5)
    s = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(4.0, 0.0, 0.0), 0.0, 12.0, lim).summary()
    assert s["accel_limit_mps2"] == 0.5
    assert s["stop_decel_mps2"] == pytest.approx(lim.v_min_m_s / (2.0 * lim.stop_lag_s), abs=1e-3)


@pytest.mark.parametrize("yaw_deg", [100.0, 150.0, 175.0, 179.9, -100.0, -179.9])
def test_tracker_turns_at_full_lock_when_the_reference_point_is_behind(yaw_deg):
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(5.0, 0.0, 0.0), 0.0, 10.0)
    _, steer = track(p, Pose2D(1.0, 0.0, math.radians(yaw_deg)), 0.5, 2.0, TrackState(s_m=1.0), TrackingParams())
    # the path runs along +x: turning back towards it is clockwise for a robot heading left-back
    assert steer == pytest.approx(-math.copysign(p.limits.max_steer_rad, yaw_deg))


def test_arc_steering_with_the_reference_point_on_the_robot():
    lim = math.radians(20.0)
    assert steer_from_arc(0.0, 0.4, 0.174, lim) == pytest.approx(lim)
    assert steer_from_arc(0.0, -0.4, 0.174, lim) == pytest.approx(-lim)
    assert steer_from_arc(0.0, 0.0, 0.174, lim) == 0.0


def test_inverse_lookup_below_the_first_breakpoint_stops_like_the_firmware():
    for t, tid, unit in ((default_speed_table(), TABLE_SPEED, 1000.0), (default_steering_table(), TABLE_STEER, 18000.0 / math.pi)):
        wire = from_calib_table(t, tid)
        for value in np.linspace(-t.value_max, t.value_max, 241):
            pwm = t.pwm_from_value(float(value))
            if abs(value) * unit < min(abs(wire.pos[0][1]), abs(wire.neg[0][1]) if wire.neg else math.inf) - 1.0:
                assert pwm == t.neutral_pwm or round(pwm) == round(t.neutral_pwm), (t.name, value, pwm)
    sp = default_speed_table()
    assert sp.pwm_from_value(0.9 * sp.pos_value[0]) == sp.neutral_pwm  # too slow to move: stop, not a creep
    assert sp.pwm_from_value(sp.pos_value[0]) == pytest.approx(round(sp.pos_pwm[0]), abs=1)


@pytest.mark.parametrize("offset", [-4.75, -2.75, -0.75, 1.25, 3.25])
def test_steering_sweep_with_a_fractional_trim_fits(offset):
    true = default_steering_table().miscalibrated(1.0, offset)
    cdeg = 18000.0 / math.pi
    p, v = F.synthetic_sweep(true, np.arange(90, 176), cdeg, repeats=1)
    res = F.fit_table(p, v, TABLE_STEER, dead_band=50)
    assert round_trips(res.table)
    # every swept integer PWM within a count's worth of angle (0.65 deg) of the car's own value
    err = [abs(res.table.value(int(q)) - true.value_from_pwm(float(q)) * cdeg) for q in range(90, 176)]
    assert max(err) <= 70.0


def test_small_steering_corrections_go_out_as_the_cars_smallest_step():
    # the firmware steers straight below its table's first point (0.65 deg left, 1.03 deg right by
    # default): a smaller correction is sent as that step, not lost
    goal = Goal(20.0, 0.0, 0.0, 40.0, 0.05)
    for y_m, want in ((0.005, -1.03), (-0.002, 0.65)):  # a few mm left (right) of the planned straight line
        pl = TimedPlanner()
        pl.reset()
        pl.step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))  # plans along +x
        cmd = pl.step(Observation(0.05, Pose2D(0.02, y_m, 0.0), 0.5, 0.0, goal, None, None, {}))
        assert cmd.speed_m_s > 0
        assert math.degrees(cmd.steer_rad) == pytest.approx(want, abs=1e-9)


def test_static_clearance_is_squeezed_after_searches_that_found_nothing():
    from agnav_host.planning.timed.planner import SQUEEZE_STEPS

    pl = TimedPlanner()
    pl.reset()
    full = pl.params.static_clear_m
    seen = []
    for k in range(SQUEEZE_STEPS + 2):
        pl._squeeze = min(k, SQUEEZE_STEPS)
        seen.append(pl._static_clear_m("static"))
    assert seen[0] == full and seen[1] == full / 2 and seen[-1] == 0.0
    assert all(a >= b for a, b in zip(seen, seen[1:]))
    pl._squeeze = SQUEEZE_STEPS
    assert pl._static_clear_m("moving") == full  # only static searches are squeezed


def _wall_ahead_scan(pose: Pose2D, dist_m: float) -> LaserScan:
    a = np.radians(np.arange(-90.0, 90.5, 1.0))
    r = np.where(np.abs(a) < math.radians(75), dist_m / np.cos(a), np.inf)
    return LaserScan(float(a[0]), math.radians(1.0), r, 10.0, 0.0, pose)


def _mover_at(x_m, y_m, unseen_s, radius_m=0.3):
    cov = tuple(tuple(0.0025 if i == j else 0.0 for j in range(4)) for i in range(4))
    return Track(7, x_m, y_m, 0.0, 1.0, radius_m, 0.05, cov, 2.0, 10, 1.0, unseen_s)


@pytest.mark.parametrize("unseen_s", [0.0, 0.5])
def test_a_return_in_the_way_stops_the_car_even_where_a_track_is_predicted(unseen_s):
    # a box face 0.3 m ahead, the car still at its start 0.5 s into its plan (the tracker asks for speed);
    # a moving track beside the face, going away from the plan (no space-time conflict), seen now or
    # coasting on its velocity: its disc covers the face's returns straight ahead (a phantom coasting over
    # a box once took the face's returns out of every check and the car drove into the box at 0.5 m/s)
    goal = Goal(20.0, 0.0, 0.0, 40.0, 0.05)
    pl = TimedPlanner()
    pl.reset()
    pl.step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))  # plans along +x
    pose = Pose2D(0.0, 0.0, 0.0)
    free = pl.step(Observation(0.5, pose, 0.0, 0.0, goal, None, None, {"tracks": []}))
    assert free.speed_m_s > 0  # nothing in the way: it goes
    pl.reset()
    pl.step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))
    cmd = pl.step(Observation(0.5, pose, 0.0, 0.0, goal, _wall_ahead_scan(pose, 0.3), None,
                              {"tracks": [_mover_at(0.6, 0.3, unseen_s, 0.2)]}))
    assert cmd.speed_m_s == 0.0


def test_a_coasting_track_does_not_hide_a_box_from_replanning():
    # the returns a track takes out of the static checks are only those of movers seen in this scan
    pl = TimedPlanner()
    pts = np.array([[0.3, 0.0], [0.3, 0.1], [3.0, 2.0]])
    seen = moving_obstacles_from([_mover_at(0.35, 0.0, 0.0)], 1.0)
    kept = pl._static_points(pts, seen, 1.0)
    assert len(kept) == 1 and tuple(kept[0]) == (3.0, 2.0)
    assert len(pl._static_points(pts, [], 1.0)) == 3


def test_the_last_line_of_defence_also_watches_the_arc_the_car_is_on():
    # the plan runs along +x; the car lags it, turned 0.5 rad left, and a post stands 0.4 m ahead along the
    # car's heading, 0.19 m from the plan's line (clear of the plan's footprint disc, 0.16 m): the car
    # must stop (turning into a gap, a car lagging its plan once swept a crate's corner the plan cleared)
    goal = Goal(20.0, 0.0, 0.0, 40.0, 0.05)
    pose = Pose2D(0.0, 0.0, 0.5)
    a = np.radians(np.arange(-90.0, 90.5, 1.0))
    r = np.full(len(a), np.inf)
    r[90] = 0.4  # the beam straight ahead of the car
    scan = LaserScan(float(a[0]), math.radians(1.0), r, 10.0, 0.5, pose)
    cmds = []
    for with_post in (False, True):
        pl = TimedPlanner()
        pl.reset()
        pl.step(Observation(0.0, Pose2D(), 0.0, 0.0, goal, None, None, {}))
        cmds.append(pl.step(Observation(0.5, pose, 0.5, 0.0, goal, scan if with_post else None, None, {"tracks": []})))
    assert cmds[0].speed_m_s > 0
    assert cmds[1].speed_m_s == 0.0


def test_blocked_checks_reach_the_end_of_their_stretch():
    # first_blocked_s and arc_blocked sample every 5 cm; the end of the stretch itself is checked too
    # (a return just beyond the last whole sample was missed, up to 5 cm of the braking distance)
    from agnav_host.planning.base import arc_blocked
    from agnav_host.planning.timed._obstacles import first_blocked_s

    plan = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(8.0, 0.0, 0.0), 0.0, 16.0, TimedLimits())
    lim = plan.limits
    reach = 0.34  # samples at 0, 0.05, ..., 0.30, and 0.34
    tip = reach + lim.footprint_offset_m + lim.radius_m  # the footprint's front at the end of the stretch
    pts = np.array([[tip - 0.02, 0.0]])
    assert first_blocked_s(plan, pts, 0.0, reach, 0.0) is not None
    assert arc_blocked(0.0, 0.0, 0.0, 0.0, reach, pts, lim.radius_m, lim.footprint_offset_m)
    far = np.array([[tip + 0.02, 0.0]])
    assert first_blocked_s(plan, far, 0.0, reach, 0.0) is None
    assert not arc_blocked(0.0, 0.0, 0.0, 0.0, reach, far, lim.radius_m, lim.footprint_offset_m)
