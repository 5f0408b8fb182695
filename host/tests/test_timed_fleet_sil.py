"""Several robots through the firmware SIL in one shared world (agnav_host.sil.fleet): each robot has
its own firmware instance, and sees and can hit the others."""

from __future__ import annotations

import math

import pytest

from agnav_host.sil.fleet import Fleet, FleetTask, fleet_tasks, run_fleet
from agnav_host.sim import load_scenario
from agnav_host.types import Goal, Pose2D

# two cars whose direct plans meet at (2, 2) at the same time
CROSSING = [
    FleetTask("A", Pose2D(0.0, 2.0, 0.0), Goal(4.5, 2.0, 0.0, 9.0, 0.05)),
    FleetTask("B", Pose2D(2.0, -0.5, math.pi / 2), Goal(2.0, 4.5, math.pi / 2, 9.0, 0.05)),
]


def test_fleet_tasks_come_from_the_scenario_and_bad_entries_are_refused():
    sc = load_scenario("timed_fleet")
    tasks = fleet_tasks(sc)
    assert [t.name for t in tasks] == ["R1", "R2", "R3"]
    assert tasks[1].goal.arrival_s == 25.0 and tasks[1].start.yaw_rad == pytest.approx(math.radians(135))
    from dataclasses import replace
    with pytest.raises(ValueError, match="meta.fleet"):
        fleet_tasks(replace(sc, meta={"fleet": [{"name": "X", "start": [0, 0], "goal": [1, 1, 0], "arrival_s": 5}]}))


def test_each_robot_has_its_own_firmware_and_sees_the_others():
    f = Fleet(load_scenario("timed_fleet"), CROSSING, seed=0)
    try:
        libs = {id(s.fw._lib) for s in f.sessions}
        assert len(libs) == 2
        # A's world holds B's body where B stands (and not A's own)
        a_world = f.sessions[0].plant.world
        assert len(a_world.movers) == 1 and a_world.movers[0].position(0.0) == pytest.approx(f.bodies[1])
        # the plans were made conflict-free before the start
        assert f.coordination.before and not f.coordination.after
    finally:
        f.close()


def test_crossing_robots_in_the_sil_keep_apart_and_arrive_on_time():
    res = run_fleet(load_scenario("timed_fleet"), seed=1, tasks=CROSSING, extra_s=3.0)
    assert res.collisions == 0 and res.min_robot_gap_m > 0.0
    for o in res.robots:
        assert o.arrived, o
        assert abs(o.arrival_err_s) <= 0.2, o
        assert o.final_pos_err_m <= 0.05, o
