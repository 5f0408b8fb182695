"""Several robots in the lock-step SIL, in one shared world.

Every robot has its own firmware instance (:class:`~agnav_host.sil.binding.Firmware` loads a private
copy of the native library, so the firmware's global state is per robot), its own radio link, host
and planner (:class:`~agnav_host.sil.session.PlannerHost` with the ``timed`` planner, localising on
its odometry and the surveyed posts). The world is shared: each robot's world holds the scenario's
static geometry and walkers plus the other robots' bodies, so a robot is seen by the others' lasers
(and tracked by their perception as a moving object) and counts in the collision checks.

Before the start the robots' timed plans are made conflict-free by
:func:`~agnav_host.planning.timed.coordinate` (earliest arrival first; a later plan is re-timed or
deviated around the fixed ones). While driving each planner also receives the others' current plans
(``peer_plans``) and replans around them, and around the tracks its laser makes of them.

One :meth:`Fleet.step` advances every session by one world step (10 ms); the other robots' bodies are
taken where they were at the start of the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..sim.scenario import Scenario
from ..sim.world import Mover
from ..types import Goal, Pose2D, norm_angle_rad
from .session import PlannerHost, SilConfig, SilSession

__all__ = ["FleetTask", "fleet_tasks", "RobotOutcome", "FleetResult", "Fleet", "run_fleet"]

ARRIVE_TOL_M = 0.05


@dataclass(frozen=True)
class FleetTask:
    """One robot of the fleet: name, start pose and timed goal (world frame)."""

    name: str
    start: Pose2D
    goal: Goal


def fleet_tasks(sc: Scenario) -> list[FleetTask]:
    """The fleet of a scenario's ``meta.fleet``: entries ``{name, start = [x_m, y_m, yaw_deg],
    goal = [x_m, y_m, yaw_deg], arrival_s}``. ValueError when missing or malformed."""
    entries = sc.meta.get("fleet")
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"scenario {sc.name!r} has no meta.fleet list")
    out = []
    for k, e in enumerate(entries):
        try:
            s, g = [float(v) for v in e["start"]], [float(v) for v in e["goal"]]
            name = str(e.get("name", f"R{k + 1}"))
            arrival = float(e["arrival_s"])
            if len(s) != 3 or len(g) != 3:
                raise ValueError("start and goal are [x_m, y_m, yaw_deg]")
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"scenario {sc.name!r}: meta.fleet[{k}]: {err}") from None
        out.append(FleetTask(name, Pose2D(s[0], s[1], math.radians(s[2])),
                             Goal(g[0], g[1], math.radians(g[2]), arrival, ARRIVE_TOL_M)))
    if len({t.name for t in out}) != len(out):
        raise ValueError(f"scenario {sc.name!r}: meta.fleet names must be unique")
    return out


class _Body:
    """Another robot as a moving obstacle of a world (the :class:`~agnav_host.sim.world.Mover`
    interface): its footprint disc where the fleet last recorded it."""

    def __init__(self, fleet: "Fleet", index: int, radius_m: float) -> None:
        self._fleet = fleet
        self._i = index
        self.radius_m = radius_m

    def position(self, t_s: float) -> tuple[float, float]:
        return self._fleet.bodies[self._i]


@dataclass
class RobotOutcome:
    """One robot's run, measured on its true pose (s, m, deg)."""

    name: str
    arrived: bool
    arrival_err_s: float | None
    final_pos_err_m: float
    final_hdg_err_deg: float
    pos_err_at_T_m: float
    min_clearance_m: float  # to walls, posts and the other robots
    host_pose_err_max_m: float  # worst |host pose - true pose| at a control step while moving
    replans: int
    events: list[tuple[float, str]] = field(default_factory=list)
    replan_times_s: list[float] = field(default_factory=list)
    replan_cpu_s: list[float] = field(default_factory=list)


@dataclass
class FleetResult:
    seed: int
    robots: list[RobotOutcome]
    collisions: int  # world steps with two robots' footprints overlapping, or a robot inside an obstacle
    min_robot_gap_m: float
    conflicts_before: int  # space-time conflicts between the robots' independent plans
    conflicts_after: int  # between the coordinated plans
    actions: dict[str, str]


class Fleet:
    """The SIL sessions of a fleet in one world (module docstring)."""

    def __init__(self, sc: Scenario, tasks: list[FleetTask], seed: int = 0, *, coordinated: bool = True,
                 margin_m: float = 0.15, config: SilConfig | None = None) -> None:
        from ..planning.timed import BoundaryState, RobotTask, TimedPlanner, coordinate

        if len(tasks) < 2:
            raise ValueError("a fleet needs at least two robots")
        self.sc = sc
        self.tasks = tasks
        radius = sc.make_robot().radius_m
        self.bodies: list[tuple[float, float]] = [(0.0, 0.0)] * len(tasks)
        self.hosts: list[PlannerHost] = []
        self.sessions: list[SilSession] = []
        ss = np.random.SeedSequence(seed)
        seeds = [int(s.generate_state(1)[0]) for s in ss.spawn(len(tasks))]
        try:
            for i, task in enumerate(tasks):
                others = [_Body(self, j, radius) for j in range(len(tasks)) if j != i]
                # a _Body stands in for a Mover: the world only asks a mover for position() and radius_m
                movers: list[Mover] = [*sc.world.movers, *others]  # type: ignore[list-item]
                w = replace(sc.world, movers=movers)
                sci = replace(sc, name=f"{sc.name}:{task.name}", world=w, start=task.start, goals=[task.goal])
                host = PlannerHost(sci, "timed")
                host.observation_extras = self._peer_extras(i)
                s = SilSession(sci, seeds[i], config, host)
                s.provision()
                self.hosts.append(host)
                self.sessions.append(s)
        except BaseException:
            self.close()
            raise
        self._record_bodies()
        self.t0_s = max(s.t_s for s in self.sessions)
        planners = [h.ctrl for h in self.hosts]
        assert all(isinstance(p, TimedPlanner) for p in planners)
        self.planners: list[TimedPlanner] = planners  # type: ignore[assignment]
        lim = self.planners[0].limits
        rtasks = [RobotTask(t.name, BoundaryState(t.start.x_m, t.start.y_m, t.start.yaw_rad),
                            BoundaryState(t.goal.x_m, t.goal.y_m, t.goal.yaw_rad or 0.0), t.goal.arrival_s, self.t0_s, lim)
                  for t in tasks]
        self.coordination = coordinate(rtasks, margin_m=margin_m)
        if coordinated:
            for pl, t in zip(self.planners, tasks):
                pl.set_plan(self.coordination.plans[t.name], t.goal)

    def _peer_extras(self, i: int) -> Any:
        def extras(_s: SilSession) -> dict[str, object]:
            return {"peer_plans": [p.plan for j, p in enumerate(self.planners) if j != i and p.plan is not None]}
        return extras

    def _record_bodies(self) -> None:
        self.bodies = [s.plant.robot.footprint_centre() for s in self.sessions]

    def step(self) -> None:
        for s in self.sessions:
            s.step()
        self._record_bodies()

    def close(self) -> None:
        for s in self.sessions:
            s.close()


def run_fleet(sc: Scenario, seed: int = 0, *, tasks: list[FleetTask] | None = None, coordinated: bool = True,
              extra_s: float = 6.0, config: SilConfig | None = None) -> FleetResult:
    """Run the fleet of ``sc`` (``meta.fleet`` unless ``tasks``) until every robot has been at rest
    for 1 s after its arrival time, or until the last arrival time + ``extra_s``. Stops at the first
    collision."""
    tasks = tasks if tasks is not None else fleet_tasks(sc)
    f = Fleet(sc, tasks, seed, coordinated=coordinated, config=config)
    try:
        n = len(tasks)
        goals = [t.goal for t in tasks]
        t_end = max(g.arrival_s or 0.0 for g in goals) + extra_s
        arrival: list[float | None] = [None] * n
        pos_T: list[float | None] = [None] * n
        rest_since: list[float | None] = [None] * n
        min_cl = [math.inf] * n
        loc_err = [0.0] * n
        n_cmd = [0] * n
        min_gap = math.inf
        collisions = 0
        radius = [s.plant.robot.radius_m for s in f.sessions]
        while True:
            f.step()
            t = f.sessions[0].t_s - f.t0_s
            for i in range(n):
                for j in range(i + 1, n):
                    (xi, yi), (xj, yj) = f.bodies[i], f.bodies[j]
                    min_gap = min(min_gap, math.hypot(xi - xj, yi - yj) - radius[i] - radius[j])
            done = True
            hit = False
            for i, (s, h, g) in enumerate(zip(f.sessions, f.hosts, goals)):
                cl = s.plant.clearance(s.t_s)
                min_cl[i] = min(min_cl[i], cl)
                hit |= cl < 0
                p = s.pose
                if len(h.commands) != n_cmd[i]:
                    n_cmd[i] = len(h.commands)
                    hp = h.localiser.pose_at(s.t_s) if h.localiser is not None else s.believed_pose()
                    if hp is not None and abs(s.plant.robot.speed_m_s) > 0.05:
                        loc_err[i] = max(loc_err[i], math.hypot(hp.x_m - p.x_m, hp.y_m - p.y_m))
                d = math.hypot(g.x_m - p.x_m, g.y_m - p.y_m)
                if arrival[i] is None and d <= ARRIVE_TOL_M:
                    arrival[i] = t
                assert g.arrival_s is not None
                if pos_T[i] is None and t >= g.arrival_s:
                    pos_T[i] = d
                if t >= g.arrival_s and abs(s.plant.robot.speed_m_s) < 0.005:
                    rest_since[i] = t if rest_since[i] is None else rest_since[i]
                else:
                    rest_since[i] = None
                since = rest_since[i]
                done &= since is not None and t - since > 1.0
            if hit:
                collisions += 1
                break
            if done or t > t_end:
                break
        out = []
        for i, (task, s, pl) in enumerate(zip(tasks, f.sessions, f.planners)):
            p, g = s.pose, task.goal
            a = arrival[i]
            at_T = pos_T[i]
            out.append(RobotOutcome(task.name, a is not None, None if a is None else a - (g.arrival_s or 0.0),
                                    math.hypot(g.x_m - p.x_m, g.y_m - p.y_m),
                                    math.degrees(abs(norm_angle_rad(p.yaw_rad - (g.yaw_rad or 0.0)))),
                                    math.nan if at_T is None else at_T, min_cl[i], loc_err[i],
                                    int(pl.status["replans"]), list(pl.events), list(pl.replan_times_s), list(pl.replan_cpu_s)))
        c = f.coordination
        return FleetResult(seed, out, collisions, min_gap, len(c.before), len(c.after), dict(c.actions))
    finally:
        f.close()
