"""People walking across a car's way, and the car's slowest speed: the findings of the random yards
with the ref-003 RC car (bench/bench_yards.py --robot ackermann [--walkers 2 --timed]).

* The timed planner stopped where a walker was heading and was hit there, crept towards what it yielded
  to, and stayed early after getting out of the way.
* The reactive planners' slow-downs near an obstacle were lost on a car whose slowest speed is its
  calibrated minimum (0.435 m/s): the braking guard in ``drive_command`` stops it instead.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from agnav_host.perception import Track
from agnav_host.planning.base import LocalView, RobotSpec, drive_command
from agnav_host.planning.timed import BoundaryState, TimedLimits, TrackingParams, TrackState, plan_timed, track
from agnav_host.sim.runner import _make_controller, run_scenario
from agnav_host.sim.scenario import parse_scenario
from agnav_host.types import DriveCommand, Goal, Observation, Pose2D

CAR = '''
[robot]
model = "ackermann"
start = {{ x_m = 0.5, y_m = {y0}, yaw_deg = 0.0 }}
max_speed_m_s = 1.0

[robot.calib]
tables = "default"

[laser]
model = "tim561"
mount = {{ x_m = 0.15, y_m = 0.0, yaw_deg = 0.0 }}

[[walls]]
points = [[-0.5, 0.0], [12.0, 0.0], [12.0, 6.0], [-0.5, 6.0]]
closed = true
'''


def car_yard(name: str, description: str, duration_s: float, y0: float) -> str:
    """The scenario header of these tests: the RC car at (0.5, ``y0``) heading along x in a walled 12 x 6 m
    yard, 0.02 s physics steps, planner at 15 Hz; goals and obstacles follow."""
    return f'''[scenario]
name = "{name}"
description = "{description}"
duration_s = {duration_s}
dt_s = 0.02
control_hz = 15.0
{CAR.format(y0=y0)}'''


def walker_crossing(start_s: float) -> str:
    """The car on a timed straight run along y = 2 m; a person pacing across it at x = 8.68 m, 0.99 m/s,
    setting off at ``start_s``."""
    return f'''{car_yard("walker_crossing", "RC car on a timed goal across a walker's beat", 40.0, 2.0)}
[[goals]]
x_m = 11.0
y_m = 2.0
tolerance_m = 0.25
arrival_s = 23.5

[[movers]]
radius_m = 0.25
speed_m_s = 0.99
waypoints = [[8.68, 0.4], [8.68, 5.6]]
loop = true
start_s = {start_s}
'''


def _run(toml: str, planner: str, **changes: object):
    sc = parse_scenario(toml, "<test>")
    ctl = _make_controller(sc, planner)
    for name, value in changes.items():  # switch one part of a fix off
        obj, attr = name.split("__")
        setattr(ctl, obj, dataclasses.replace(getattr(ctl, obj), **{attr: value}))
    return run_scenario(sc, planner, seed=0, controller=ctl), ctl


def _first_contact_speed(r) -> float | None:
    touch = np.flatnonzero(r.trajectory[:, 6] < 0.0)
    return None if len(touch) == 0 else float(abs(r.trajectory[touch[0], 4]))


# ---- timed planner and walkers -----------------------------------------------------------------------


@pytest.mark.parametrize("start_s", [0.5, 1.0])
def test_timed_car_hurries_out_of_a_walkers_way_rather_than_stop_in_it(start_s, monkeypatch):
    r, ctl = _run(walker_crossing(start_s), "timed")
    assert r.end_reason == "arrived"
    assert float(r.trajectory[:, 6].min()) > 0.3
    assert any("hurry" in a for _, a in ctl.events)
    # without the hurry candidate the car stops on the walker's line and is walked into
    import agnav_host.planning.timed._resolve as R
    import agnav_host.planning.timed.planner as P

    never = lambda start, goal, t, limits, vias, *a, **k: R.plan_timed(start, goal, t, t + 1e6, limits, vias)  # noqa: E731
    monkeypatch.setattr(R, "hurry_plan", never)
    monkeypatch.setattr(P, "hurry_plan", never)
    r2, _ = _run(walker_crossing(start_s), "timed")
    assert r2.end_reason == "collision"


@pytest.mark.parametrize("start_s", [5.5, 6.0])
def test_timed_car_yielding_to_a_walker_does_not_creep_into_its_way(start_s):
    r, _ = _run(walker_crossing(start_s), "timed")
    assert r.end_reason == "arrived" and float(r.trajectory[:, 6].min()) > 0.1
    # creeping at v_min to each new stop point carried it onto the walker's line
    r2, _ = _run(walker_crossing(start_s), "timed", track_params__hold_behind_m=-1.0)
    assert r2.end_reason == "collision" and _first_contact_speed(r2) > 0.1


def test_timed_car_is_retimed_to_its_arrival_after_hurrying():
    r, ctl = _run(walker_crossing(0.5), "timed")
    assert any("hurry" in a for _, a in ctl.events)
    assert any("re-timed" in a for _, a in ctl.events)
    # the run ends on entering the 0.25 m tolerance, about 0.5 s before the plan's arrival
    assert abs(r.metrics.arrival_time_error_s + 0.5) < 0.3
    r2, _ = _run(walker_crossing(0.5), "timed", params__early_retime_s=1e6)
    assert r2.metrics.arrival_time_error_s < -2.0


def test_a_stop_for_a_dwell_holds_the_car_unless_it_is_well_behind():
    lim = TimedLimits()
    plan = plan_timed(BoundaryState(0.0, 0.0, 0.0, 0.0, 0.5), BoundaryState(6.0, 0.0, 0.0), 0.0, 12.0, lim,
                      dwell_first_s=1.0, auto_via=False)
    for t in (0.2, 0.4, 0.8, 1.2):  # braking into the dwell (0.125 m from 0.5 m/s), then standing in it
        s_ref, _ = plan.profile.eval(t)
        assert plan.profile.coming_to_rest(t)
        # hold_behind_m 0.15 (default) holds it 5 cm behind; a smaller hold, or none (the old rule), sends v_min
        for tp, behind, moves in ((TrackingParams(), 0.05, False), (TrackingParams(hold_behind_m=0.04), 0.06, True),
                                  (TrackingParams(hold_behind_m=-1.0), 0.05, True)):
            x = float(s_ref) - behind
            v, _ = track(plan, Pose2D(x, 0.0, 0.0), 0.0, t, TrackState(s_m=x), tp)
            assert (v > 0.0) == moves, (t, behind, v)
    t_go = plan.profile.t_s[list(plan.profile.kind).index("dwell") + 1] + 0.3  # moving again: no hold
    assert not plan.profile.coming_to_rest(t_go)


def test_a_passive_stop_still_counts_walkers_while_a_static_blockage_is_searched():
    """The car deviating round a box must still stop for a walker; before, the static search (several
    control steps) kept the mover check off and the car drove into the walker at 0.28 m/s."""
    toml = f'''{car_yard("box_and_walkers", "timed run past boxes with two people pacing across", 60.0, 3.0)}
[[goals]]
x_m = 11.0
y_m = 4.26
tolerance_m = 0.25
arrival_s = 23.6

[[circles]]
x_m = 7.40
y_m = 1.28
radius_m = 0.29
[[circles]]
x_m = 9.89
y_m = 2.69
radius_m = 0.20
[[boxes]]
x_m = 5.91
y_m = 1.73
size_x_m = 0.69
size_y_m = 0.72
yaw_deg = 25
[[boxes]]
x_m = 9.21
y_m = 1.47
size_x_m = 0.30
size_y_m = 1.35
yaw_deg = 72
[[boxes]]
x_m = 6.87
y_m = 4.40
size_x_m = 0.96
size_y_m = 1.33
yaw_deg = 65
[[circles]]
x_m = 9.83
y_m = 4.27
radius_m = 0.26
[[circles]]
x_m = 2.44
y_m = 5.06
radius_m = 0.38
[[boxes]]
x_m = 6.04
y_m = 3.28
size_x_m = 0.33
size_y_m = 1.09
yaw_deg = 47

[[movers]]
radius_m = 0.25
speed_m_s = 0.84
waypoints = [[4.21, 0.4], [4.21, 5.6]]
loop = true
start_s = 4.7
[[movers]]
radius_m = 0.25
speed_m_s = 0.99
waypoints = [[4.77, 0.4], [4.77, 5.6]]
loop = true
start_s = 4.8
'''
    r, _ = _run(toml, "timed")
    speed = _first_contact_speed(r)
    assert speed is None or speed < 0.1  # passive safety: if anything touches, the car stands


# ---- the braking guard of drive_command ------------------------------------------------------------


def _view(*pts: tuple[float, float]) -> LocalView:
    xy = np.array(pts, dtype=float).reshape(-1, 2)
    b = np.arctan2(xy[:, 1], xy[:, 0])
    o = np.argsort(b)
    return LocalView(xy[o], np.hypot(xy[o, 0], xy[o, 1]), b[o], np.zeros(0))


CAR_SPEC = RobotSpec(kinematics="ackermann", radius_m=0.16, max_speed_m_s=1.0, min_speed_m_s=0.435, wheelbase_m=0.174,
                     max_steer_rad=math.radians(24.6), footprint_offset_m=0.087, stop_lag_s=0.25)
DIFF_SPEC = RobotSpec(radius_m=0.225, max_speed_m_s=0.5, stop_lag_s=0.12)


def test_braking_guard_stops_a_car_whose_slow_down_its_minimum_speed_would_eat():
    # a planner slowing to 0.1 m/s for a post 0.2 m ahead of the footprint: the car's slowest is 0.435 m/s
    assert drive_command(CAR_SPEC, 0.1, 0.0).speed_m_s == pytest.approx(0.435)
    post = _view((0.16 + 0.15, 0.0))
    cmd = drive_command(CAR_SPEC, 0.1, 0.0, post)
    assert cmd.speed_m_s == 0.0
    # the turn is kept (steering into a way out)
    assert drive_command(CAR_SPEC, 0.1, 0.5, post).steer_rad == pytest.approx(drive_command(CAR_SPEC, 0.1, 0.5).steer_rad)
    # far enough ahead, or beside the way, it drives on
    assert drive_command(CAR_SPEC, 0.1, 0.0, _view((1.0, 0.0))).speed_m_s == pytest.approx(0.435)
    assert drive_command(CAR_SPEC, 0.1, 0.0, _view((0.2, 0.4))).speed_m_s == pytest.approx(0.435)
    # along a hard left turn, a point straight ahead is not in the way, one on the arc is
    w = 1.2
    assert drive_command(CAR_SPEC, 0.5, w, _view((0.45, -0.05))).speed_m_s > 0.0
    k = math.tan(drive_command(CAR_SPEC, 0.5, w).steer_rad) / 0.174
    s = 0.15  # the footprint centre 0.15 m along that arc from the rear axle, in the view's frame
    on_arc = (math.sin(k * s) / k - 0.087 + 0.087 * math.cos(k * s), (1.0 - math.cos(k * s)) / k + 0.087 * math.sin(k * s))
    assert drive_command(CAR_SPEC, 0.5, w, _view(on_arc)).speed_m_s == 0.0


def test_braking_guard_reach_grows_with_speed_on_a_differential_drive():
    pt = _view((0.225 + 0.12, 0.0))  # 12 cm ahead of the footprint
    assert drive_command(DIFF_SPEC, 0.5, 0.0, pt).speed_m_s == 0.0  # 0.05 + 0.5 * (1/15 + 0.12) = 0.14 m
    assert drive_command(DIFF_SPEC, 0.2, 0.0, pt).speed_m_s == pytest.approx(0.2)  # 0.05 + 0.2 * 0.19 = 0.09 m
    assert drive_command(DIFF_SPEC, 0.0, 0.8, pt).yaw_rate_rad_s == pytest.approx(0.8)  # turning on the spot is left alone


def test_fuzzy_planner_on_the_rc_car_does_not_run_into_a_thin_post():
    toml = f'''{car_yard("post_ahead", "RC car, a thin post 2 m ahead", 60.0, 3.0)}
[sonar]
enabled = true

[[goals]]
x_m = 11.0
y_m = 2.35
tolerance_m = 0.25

[[circles]]
x_m = 4.38
y_m = 1.58
radius_m = 0.23
[[circles]]
x_m = 7.40
y_m = 2.94
radius_m = 0.41
[[circles]]
x_m = 2.66
y_m = 2.81
radius_m = 0.11
[[circles]]
x_m = 5.19
y_m = 5.09
radius_m = 0.49
'''
    r, _ = _run(toml, "flb")
    assert r.end_reason != "collision" and float(r.trajectory[:, 6].min()) > 0.0


def _rolling(speed_m_s: float, yaw_rate_rad_s: float) -> Observation:
    return Observation(0.0, Pose2D(), speed_m_s, yaw_rate_rad_s, Goal(5.0, 0.0), None, None, {})


def test_braking_guard_also_checks_the_arc_the_car_is_still_on():
    # asked to drive straight while the wheels still point right (servo lag): a post on that right arc
    post = _view((0.23, -0.22))
    assert drive_command(CAR_SPEC, 0.6, 0.0, post).speed_m_s > 0.0  # the straight way is clear
    assert drive_command(CAR_SPEC, 0.6, 0.0, post, _rolling(0.6, -0.9)).speed_m_s == 0.0
    assert drive_command(CAR_SPEC, 0.6, 0.0, post, _rolling(0.6, 0.0)).speed_m_s > 0.0


def test_a_car_told_to_stop_does_not_steer_its_roll_out_into_a_box():
    # a planner turning "on the spot" to the right (v = 0, right yaw rate) while the car still rolls at
    # 0.5 m/s: full right lock would carry the footprint into the box front right; straight is clear
    box = _view((0.25, -0.22))
    assert drive_command(CAR_SPEC, 0.0, -1.2, box).steer_rad == pytest.approx(-CAR_SPEC.max_steer_rad)
    cmd = drive_command(CAR_SPEC, 0.0, -1.2, box, _rolling(0.5, 0.0))
    assert cmd.speed_m_s == 0.0 and cmd.steer_rad == pytest.approx(0.0)
    # standing still there is no roll-out: the steering asked for is kept while the car stands (a box on the
    # other side too); with that side free it turns forward the other way round
    boxes = _view((0.25, -0.22), (0.25, 0.22))
    assert drive_command(CAR_SPEC, 0.0, -1.2, boxes, _rolling(0.0, 0.0)).steer_rad == pytest.approx(-CAR_SPEC.max_steer_rad)
    other_way = drive_command(CAR_SPEC, 0.0, -1.2, box, _rolling(0.0, 0.0))
    assert other_way.speed_m_s > 0.0 and other_way.steer_rad == pytest.approx(CAR_SPEC.max_steer_rad)


def test_a_car_rolling_one_way_does_not_swing_its_wheels_across_a_box():
    # rolling at 0.5 m/s on full left lock, the planner wants a turn on the spot to the right: full right
    # lock is clear and so is the arc it is on, but straight ahead (which the wheels pass through) is not
    lock = CAR_SPEC.max_steer_rad
    box = _view((0.33, 0.0))
    rolling_left = _rolling(0.5, 0.5 * math.tan(lock) / CAR_SPEC.wheelbase_m)
    cmd = drive_command(CAR_SPEC, 0.0, -1.2, box, rolling_left)
    assert cmd.speed_m_s == 0.0 and cmd.steer_rad == pytest.approx(lock)  # it keeps the arc it is on
    # nothing in the way of the swing: the car stops and steers as asked
    assert drive_command(CAR_SPEC, 0.0, -1.2, _view((3.0, 3.0)), rolling_left).steer_rad == pytest.approx(-lock)


def test_a_car_drives_forward_where_it_cannot_turn_on_the_spot():
    lock = CAR_SPEC.max_steer_rad
    standing = _rolling(0.0, 0.0)  # the goal 5 m ahead
    cmd = drive_command(CAR_SPEC, 0.0, 1.2, _view((3.0, -3.0)), standing)
    assert cmd.speed_m_s == pytest.approx(CAR_SPEC.min_speed_m_s) and cmd.steer_rad == pytest.approx(lock)
    # a post on the left full-lock arc: it turns forward the other way round (right lock), standing only; with
    # posts on both arcs it stands (and steers as asked)
    post = drive_command(CAR_SPEC, 0.0, 1.2, _view((0.3, 0.25)), standing)
    assert post.speed_m_s == pytest.approx(CAR_SPEC.min_speed_m_s) and post.steer_rad == pytest.approx(-lock)
    assert drive_command(CAR_SPEC, 0.0, 1.2, _view((0.3, 0.25)), _rolling(0.5, 0.0)).speed_m_s == 0.0  # rolling: stops
    posts = drive_command(CAR_SPEC, 0.0, 1.2, _view((0.3, 0.25), (0.3, -0.25)), standing)
    assert posts.speed_m_s == 0.0 and posts.steer_rad == pytest.approx(lock)
    # on the goal (turning to its heading) or without its obstacle points it stands
    at_goal = Observation(0.0, Pose2D(5.0, 0.0, 0.0), 0.0, 0.0, Goal(5.0, 0.0), None, None, {})
    assert drive_command(CAR_SPEC, 0.0, 1.2, _view((3.0, -3.0)), at_goal).speed_m_s == 0.0
    assert drive_command(CAR_SPEC, 0.0, 1.2).speed_m_s == 0.0
    # a differential drive turns on the spot
    assert drive_command(DIFF_SPEC, 0.0, 1.2, _view((3.0, -3.0)), standing).speed_m_s == 0.0


def _track(tid: int, x: float, y: float, vx: float, vy: float) -> Track:
    return Track(tid, x, y, vx, vy, 0.25, 0.05, tuple(tuple(0.0 for _ in range(4)) for _ in range(4)), 3.0, 30, 2.0)


def test_forward_turn_is_a_drive_command_marked_for_the_mover_guard():
    from agnav_host.planning.base import ForwardTurn

    standing = _rolling(0.0, 0.0)
    assert isinstance(drive_command(CAR_SPEC, 0.0, 1.2, _view((3.0, -3.0)), standing), ForwardTurn)
    # a car asked to drive, or one standing by a post: plain commands
    assert type(drive_command(CAR_SPEC, 0.5, 1.2, _view((3.0, -3.0)), standing)) is DriveCommand
    assert type(drive_command(CAR_SPEC, 0.0, 1.2, _view((0.3, 0.25), (0.3, -0.25)), standing)) is DriveCommand


def test_mover_guard_lets_a_forward_turn_go_only_well_clear_of_walkers():
    from agnav_host.planning.base import MoverGuard

    g = MoverGuard(CAR_SPEC, 2.0)
    standing = _rolling(0.0, 0.0)
    v = CAR_SPEC.min_speed_m_s
    w = v * math.tan(CAR_SPEC.max_steer_rad) / CAR_SPEC.wheelbase_m
    # a walker 2.5 m to the right walking away: a plain command goes, and so does a forward turn
    g.moving = g.walkers = [_track(1, 0.0, -2.5, 0.0, -1.0)]
    assert not g.stand(standing, v, w) and not g.stand(standing, v, w, forward_turn=True)
    # 1.8 m clear now, crossing 1 m ahead at 1 m/s: within its 2 s it comes closer to the left-lock arc than
    # the forward turn's 0.5 m extra margin allows, but not within the plain rule's 0.1 m
    g.moving = g.walkers = [_track(2, 1.0, -2.0, 0.0, 1.0)]
    assert not g.stand(standing, v, w) and g.stand(standing, v, w, forward_turn=True)
    # a walker turning round at the end of its beat, 1 m off and (for now) slower than "moving": the plain
    # rule sees no mover; a forward turn waits for any track that has moved within 1.5 m
    g.moving, g.walkers = [], [_track(3, 0.0, 1.2, 0.0, 0.05)]
    assert not g.stand(standing, v, w) and g.stand(standing, v, w, forward_turn=True)


@pytest.mark.parametrize("start_s", [1.0, 2.0, 3.0])
def test_follow_path_lets_a_walker_by_and_does_not_map_its_trail(start_s):
    r, ctl = _run(walker_crossing(start_s), "follow-path", params__mover_horizon_s=2.0)
    assert r.end_reason == "arrived" and float(r.trajectory[:, 6].min()) > 0.1
    assert ctl.mover_stops > 0 or start_s > 2.0
    # without the tracker (the default) the walker's trail walls off its beat in the map and the car is walked
    # into (setting off at 2 s the walker has passed when the car, turning forward where it wished to turn on
    # the spot, reaches the beat)
    r2, _ = _run(walker_crossing(start_s), "follow-path")
    assert r2.end_reason == ("arrived" if start_s == 2.0 else "collision")


def _with_params(toml: str, planner: str, **params: float) -> str:
    return toml + f"\n[meta.planner_params.{planner}]\n" + "".join(f"{k} = {v}\n" for k, v in params.items())


@pytest.mark.parametrize("planner, start_s, room_m", [("apf", 0.0, 0.15), ("flb", 0.0, 0.15), ("pbf", 0.0, 0.15),
                                                       ("him", 0.0, 0.15), ("vfh", 0.0, 0.05)])
def test_any_laser_planner_lets_a_walker_by_when_asked(planner, start_s, room_m):
    # the same walker crossing: by default these planners drive into the walker ...
    r0 = run_scenario(parse_scenario(walker_crossing(start_s), "<t>"), planner, seed=0)
    assert r0.end_reason == "collision"
    # ... with mover_horizon_s the registry wraps them in the MoverGuard (vfh's car, turning forward towards
    # the beat where it wished to turn on the spot, stands 0.07 m from the walker's path as it passes)
    r = run_scenario(parse_scenario(_with_params(walker_crossing(start_s), planner, mover_horizon_s=2.0), "<t>"), planner, seed=0)
    assert r.end_reason == "arrived" and float(r.trajectory[:, 6].min()) > room_m


def test_registry_wraps_a_planner_in_the_mover_guard_and_checks_the_horizon():
    from agnav_host.planning.base import WithMoverGuard
    from agnav_host.planning.registry import make_planner

    p = make_planner("vfh", CAR_SPEC, {"mover_horizon_s": 1.5})
    assert isinstance(p, WithMoverGuard) and p.guard.horizon_s == 1.5 and p.name == "vfh"
    assert not isinstance(make_planner("vfh", CAR_SPEC, {"mover_horizon_s": 0.0}), WithMoverGuard)
    assert not isinstance(make_planner("follow-path", CAR_SPEC, {"mover_horizon_s": 2.0}), WithMoverGuard)  # its own field
    for bad in (-1.0, 11.0, "2", True):
        with pytest.raises(ValueError, match="mover_horizon_s"):
            make_planner("apf", CAR_SPEC, {"mover_horizon_s": bad})
    with pytest.raises(ValueError, match="timed"):
        make_planner("timed", CAR_SPEC, {"mover_horizon_s": 2.0})
