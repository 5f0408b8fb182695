"""Bounded conflict resolution of the timed planner: a search cut into steps of at most
``max_candidates`` plans finds the same answer as the whole search in one call."""

import numpy as np

from agnav_host.planning.timed import BoundaryState, MovingObstacle, TimedLimits, first_conflict, plan_timed, resolve
from agnav_host.planning.timed._obstacles import first_blocked_s


def _crossing_walker(lim: TimedLimits, start: BoundaryState, goal: BoundaryState) -> MovingObstacle:
    p = plan_timed(start, goal, 0.0, 15.0, lim)
    x, y, *_ = p.at(7.0)
    return MovingObstacle(float(x), float(y) - 3.5, 0.0, 0.5, 0.25, speed_sigma_m_s=0.1, stamp_s=0.0)


def _wall_across(x_m: float, y0: float, y1: float) -> np.ndarray:
    ys = np.arange(y0, y1 + 1e-9, 0.05)
    return np.column_stack((np.full(len(ys), x_m), ys))


def test_search_in_bounded_steps_reaches_the_same_plan_as_one_call():
    lim = TimedLimits()
    start, goal = BoundaryState(0, 0, 0, 0.0, 0.0), BoundaryState(10, 0, 0)
    walker = _crossing_walker(lim, start, goal)
    pts = _wall_across(3.0, -0.4, 0.4)  # and a static blockage on the straight path
    kw = dict(horizon_s=15.0, static_range_m=6.0)
    whole = resolve(start, goal, 0.0, 15.0, lim, (), [walker], pts, **kw)
    assert whole.plan is not None and whole.next_index is None
    idx, late, steps, most = 0, None, 0, 0
    while True:
        part = resolve(start, goal, 0.0, 15.0, lim, (), [walker], pts, start_index=idx, max_candidates=2, late=late, **kw)
        steps += 1
        most = max(most, part.tried)
        if part.next_index is None:
            break
        assert part.plan is None and part.action.startswith("searching")
        assert part.next_index > idx, "each step moves the search on"
        idx, late = part.next_index, part.late
    assert most <= 2
    assert steps > 1, "this case needs more than two candidates"
    assert part.plan is not None and part.action == whole.action
    assert first_blocked_s(part.plan, pts, 0.0, 6.0, 0.1) is None
    assert first_conflict(part.plan, [walker], 0.0, 15.0, 0.1) is None


def test_via_points_inside_a_static_blockage_are_screened_without_building_a_plan():
    lim = TimedLimits()
    start, goal = BoundaryState(0, 0, 0, 0.0, 0.6), BoundaryState(10, 0, 0)
    pts = _wall_across(4.0, -1.5, 1.5)  # a wide wall: the offered deviation point sits inside it
    res = resolve(start, goal, 0.0, 20.0, lim, (), [], pts, static_clear_m=0.08, static_range_m=6.0,
                  extra_vias_xy=[("inside", (4.0, 0.5)), ("around", (4.0, 2.2))], try_yield=False, try_base=False)
    assert res.screened == 1
    assert res.tried == 1 and res.action == "around"


def test_planner_spreads_a_long_search_over_steps_and_never_exceeds_its_bound():
    """A walker will cross the route: with two candidates per call (the plain replan, rebuilt to order
    the list, and one more) the planner needs several control steps (reported as "searching"), builds
    at most two plans in each, and ends on a plan clear of the
    walker's predicted disc that keeps the arrival time."""
    from agnav_host.planning.base import RobotSpec
    from agnav_host.planning.timed import TimedParams, TimedPlanner
    from agnav_host.types import Goal, Observation, Pose2D

    lim = TimedLimits()
    walker = _crossing_walker(lim, BoundaryState(0, 0, 0, 0.0, 0.0), BoundaryState(10, 0, 0))
    spec = RobotSpec(kinematics="ackermann", radius_m=0.16, max_speed_m_s=2.0, min_speed_m_s=0.435, max_accel_m_s2=2.0,
                     wheelbase_m=0.174, footprint_offset_m=0.087, control_dt_s=0.05)
    pl = TimedPlanner(spec, TimedParams(max_candidates=2, use_sonar=False))
    goal = Goal(10.0, 0.0, 0.0, 15.0, 0.05)
    pose = Pose2D(0.0, 0.0, 0.0)
    for k in range(10):  # 0.5 s at the start
        t = 0.05 * k
        pl.step(Observation(t, pose, 0.0, 0.0, goal, None, None, {"goals": [goal], "goal_index": 0, "tracks": [walker]}))
    assert pl.replan_work and max(b for b, _ in pl.replan_work) <= 2
    assert sum("searching" in a for _, a in pl.events) >= 2
    assert pl.plan is not None and pl.plan.feasible and abs(pl.plan.arrival_s - 15.0) < 1e-6
    assert first_conflict(pl.plan, [walker], 0.5, 15.0, pl.params.moving_margin_m) is None
