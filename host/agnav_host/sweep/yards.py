"""Random cluttered yards: how often does each planner arrive, run out of time, or touch something?

The fixed scenarios of ``agnav bench planners`` are the references' set-ups; this draws many small worlds
instead, to find the layouts nobody thought of. Each yard is 12 x 6 m, walled, with 4-8 boxes (0.2-1.2 x
0.2-1.5 m, any yaw) and posts (radius 0.1-0.5 m) at least 1.2 m apart between x = 2 and 10 m; the robot
(the 0.45 m differential drive of refs 001/002, TiM561 laser and the 12-sonar ring) starts at (0.5, 3)
and must reach (11, y) with y drawn in 1-5 m, within 90 s. Yard k is the same on every machine
(numpy seed 1000 + k).

``robot = "ackermann"`` puts the ref-003 RC car (0.38 m turning radius, no reverse, 0.435 m/s slowest) in
the same yards; ``walkers = N`` adds N people pacing across each yard on lines clear of the boxes (0.4-1.0
m/s, oblivious of the robot; the laser planners then track them and let them by, ``mover_horizon_s`` 2 s,
which the timed planner always does); ``timed`` gives the goal an arrival time (straight line at 0.6 m/s
plus 6 s) and reports the arrival-time error (the run ends on entering the 0.25 m goal tolerance, about half
a second before the car's centre reaches the goal, so on-time runs show about -0.5 s).

A run is the task :func:`run` (spec: yard, planner entry, robot, walkers, timed, mover horizon, firmware
mode; seed: the simulator's noise). :func:`report` prints one row per planner (arrived / timeout / collision
counts, the smallest clearance) and every run that did not end in arrived or timeout, so it can be replayed
with ``agnav sim`` on the printed yard. A contact is counted as "hit standing" when the robot was below
0.1 m/s at the first touch and what it touched is a walker (the walker walked into it; ref 001's passive
motion safety allows that), as "collision" otherwise (a car rolling to rest against a box has hit it).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from .tasks import Task

__all__ = ["ROBOTS", "WALKER_AWARE", "yard_toml", "run", "tasks", "report", "default_planners", "RUN"]

RUN = "agnav_host.sweep.yards:run"


ROBOTS = {
    "diff": '''[robot]
model = "diff_drive"
start = { x_m = 0.5, y_m = 3.0, yaw_deg = 0.0 }
radius_m = 0.225
max_speed_m_s = 0.5
''',
    # the ref-003 RC car (wheelbase 174 mm, steering to 24.6 deg: 0.38 m turning radius, 0.435 m/s slowest
    # through its PWM tables), controller and car on the same fits
    "ackermann": '''[robot]
model = "ackermann"
start = { x_m = 0.5, y_m = 3.0, yaw_deg = 0.0 }
max_speed_m_s = 1.0

[robot.calib]
tables = "default"
''',
}
WALKER_AWARE = ("follow-path", "flb", "him", "vfh", "apf", "pbf")  # --walkers: these get mover_horizon_s 2 s
ARRIVE_SPEED_M_S = 0.6  # --timed: the goal's arrival time is its straight-line distance at this speed, plus slack
ARRIVE_SLACK_S = 6.0


def yard_toml(k: int, robot: str = "diff", walkers: int = 0, timed: bool = False, mover_horizon_s: float = 2.0) -> str:
    """Scenario TOML of yard ``k``: ``robot`` one of ROBOTS; ``walkers`` people crossing the yard on
    looped paths (drawn from their own seed, so the boxes and posts stay those of yard ``k``); ``timed``
    gives the goal an arrival time (ARRIVE_SPEED_M_S, ARRIVE_SLACK_S); with walkers the WALKER_AWARE planners get
    ``mover_horizon_s`` (0: not)."""
    rng = np.random.default_rng(1000 + k)
    gy = float(rng.uniform(1.0, 5.0))
    arrival = f"arrival_s = {np.hypot(11.0 - 0.5, gy - 3.0) / ARRIVE_SPEED_M_S + ARRIVE_SLACK_S:.1f}\n" if timed else ""
    parts = [f'''[scenario]
name = "yard{k}"
description = "random cluttered yard {k} (agnav bench yards)"
duration_s = 90.0
dt_s = 0.02
control_hz = 15.0

{ROBOTS[robot]}
[laser]
model = "tim561"
mount = {{ x_m = 0.15, y_m = 0.0, yaw_deg = 0.0 }}

[sonar]
enabled = true

[[goals]]
x_m = 11.0
y_m = {gy:.2f}
tolerance_m = 0.25
{arrival}
[[walls]]
points = [[-0.5, 0.0], [12.0, 0.0], [12.0, 6.0], [-0.5, 6.0]]
closed = true
''']
    placed: list[tuple[float, float]] = []
    extent: list[float] = []  # each obstacle's reach from its centre, m (half diagonal or radius)
    for _ in range(int(rng.integers(4, 9))):
        x = y = 0.0
        for _try in range(30):
            x, y = float(rng.uniform(2.0, 10.0)), float(rng.uniform(0.3, 5.7))
            if all(np.hypot(x - a, y - b) > 1.2 for a, b in placed):
                break
        placed.append((x, y))
        if rng.random() < 0.5:
            sx, sy = rng.uniform(0.2, 1.2), rng.uniform(0.2, 1.5)
            parts.append(f"[[boxes]]\nx_m = {x:.2f}\ny_m = {y:.2f}\nsize_x_m = {sx:.2f}\n"
                         f"size_y_m = {sy:.2f}\nyaw_deg = {rng.uniform(0, 90):.0f}\n")
            extent.append(0.5 * float(np.hypot(sx, sy)))
        else:
            r = float(rng.uniform(0.1, 0.5))
            parts.append(f"[[circles]]\nx_m = {x:.2f}\ny_m = {y:.2f}\nradius_m = {r:.2f}\n")
            extent.append(r)
    if walkers and mover_horizon_s > 0:  # the planners track people only when asked (the tracker's cost); timed always does
        for name in WALKER_AWARE:
            parts.append(f"[meta.planner_params.{name}]\nmover_horizon_s = {mover_horizon_s}\n")
    walk = np.random.default_rng(5000 + k)
    for _ in range(walkers):
        # a person pacing across the yard (y = 0.4 .. 5.6 m and back) on a line clear of every obstacle by 0.35 m
        for _try in range(30):
            wx = float(walk.uniform(3.0, 9.5))
            if all(abs(wx - a) > e + 0.6 for (a, _b), e in zip(placed, extent)):
                parts.append(f"[[movers]]\nradius_m = 0.25\nspeed_m_s = {walk.uniform(0.4, 1.0):.2f}\n"
                             f"waypoints = [[{wx:.2f}, 0.4], [{wx:.2f}, 5.6]]\nloop = true\n"
                             f"start_s = {walk.uniform(0.0, 6.0):.1f}\n")
                break
    return "\n".join(parts)


STANDING_M_S = 0.1  # a contact below this speed is the robot hit standing (ref 001's passive safety holds)
#: The planners' wall-time backstops, lifted in a sweep: their work bounds (A* expansions, timed candidates)
#: end every search alone, so that a run does not depend on how loaded its machine is
NO_WALL_BACKSTOPS: dict[str, dict[str, float]] = {"follow-path": {"plan_deadline_s": 60.0},
                                                  "timed": {"replan_budget_s": 60.0}}


def with_params(sc: Any, extra: Mapping[str, Mapping[str, Any]]) -> Any:
    """Scenario ``sc`` with ``extra`` ({planner: {parameter: value}}) over its ``[meta.planner_params]``."""
    from dataclasses import replace

    table = {k: dict(v) for k, v in sc.meta.get("planner_params", {}).items()}
    for name, params in extra.items():
        table[name] = {**table.get(name, {}), **params}
    return replace(sc, meta={**sc.meta, "planner_params": table})


def default_planners(robot: str) -> list[str]:
    """Every reactive planner (the differential drive), or those that drive a car and timed (ackermann)."""
    return (["subsumption", "flb", "him", "vfh", "apf", "pbf", "follow-path"] if robot == "diff"
            else ["flb", "him", "vfh", "apf", "pbf", "follow-path", "timed"])


def run(spec: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """One planner in one yard (the planners' wall-time backstops lifted: :data:`NO_WALL_BACKSTOPS`): the end reason ("arrived", "timeout", "collision", "hit standing", or the
    error a planner raised: a finding too), the smallest clearance (m), the arrival-time error (s, NaN when
    the goal has no time or was not reached), the time and path length of the run.

    A collision's end reason is "collision" while the robot moved at the first contact, "hit standing" when it
    was (nearly) at rest and what it touched is a walker."""
    from ..planning.bench import _split
    from ..sim.runner import run_scenario
    from ..sim.scenario import parse_scenario

    k = int(spec["yard"])
    nan = float("nan")
    try:
        sc = parse_scenario(yard_toml(k, spec["robot"], int(spec["walkers"]), bool(spec["timed"]),
                                      float(spec["mover_horizon_s"])), f"<yard {k}>")
        name, params = _split(str(spec["planner"]))
        sc = with_params(sc, {**NO_WALL_BACKSTOPS, **({name: params} if params else {})})
        r = run_scenario(sc, name, seed=seed)
        late = r.metrics.arrival_time_error_s
        end = r.end_reason
        touch = np.flatnonzero(r.trajectory[:, 6] < 0.0)
        if end == "collision" and len(touch) and abs(r.trajectory[touch[0], 4]) < STANDING_M_S and sc.world.movers:
            # standing: only when what it touches is a walker (a car rolling to rest against a box hit it)
            from ..sim._raycast import distance_to_objects

            _t, x, y, yaw = r.trajectory[touch[0], :4]
            p = sc.robot_params
            off = 0.5 * p.wheelbase_m if hasattr(p, "wheelbase_m") else 0.0
            cx, cy = np.atleast_1d(x + off * np.cos(yaw)), np.atleast_1d(y + off * np.sin(yaw))
            if float(distance_to_objects(cx, cy, sc.world.segments, sc.world.circles)[0]) - p.radius_m > 0.0:
                end = "hit standing"
        return {"end": end, "min_clearance_m": float(r.trajectory[:, 6].min()),
                "arrival_error_s": nan if late is None else float(late), "time_s": float(r.metrics.time_s),
                "path_length_m": float(r.metrics.path_length_m)}
    except Exception as e:  # noqa: BLE001  (a planner that raises is a finding too)
        return {"end": f"error: {type(e).__name__}: {e}"[:160], "min_clearance_m": nan, "arrival_error_s": nan,
                "time_s": nan, "path_length_m": nan}


def tasks(yards: Sequence[int], planners: Sequence[str], robot: str = "diff", walkers: int = 0, timed: bool = False,
          mover_horizon_s: float = 2.0, seeds: Sequence[int] = (0,)) -> list[Task]:
    """The runs of a yard sweep: every planner on every yard and seed (planner by planner)."""
    return [Task(RUN, {"yard": k, "planner": p, "robot": robot, "walkers": walkers, "timed": timed,
                       "mover_horizon_s": mover_horizon_s, "firmware": "none"}, s)
            for p in planners for k in yards for s in seeds]


def report(rows: Sequence[Mapping[str, Any]], planners: Sequence[str], first: int, n_yards: int, robot: str,
           walkers: int, timed: bool, mover_horizon_s: float) -> list[str]:
    """The yard sweep's tables (markdown), from its stored rows."""
    what = f"{robot} robot" + (f", {walkers} walker(s), mover_horizon_s {mover_horizon_s:g}" if walkers else "") + \
        (", timed goal" if timed else "")
    seeds = sorted({int(r["seed"]) for r in rows})
    lines = [f"# {n_yards} random cluttered yards {first}-{first + n_yards - 1} (agnav bench yards), {what}, "
             f"{len(rows)} runs" + (f", seeds {seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else ""), "",
             "| planner | arrived | timeout | collision (moving) | hit standing | other | smallest clearance m | "
             "arrival error s (median, worst) |", "|---|---|---|---|---|---|---|---|"]
    for p in planners:
        rs = [r for r in rows if r["planner"] == p]
        n = {e: sum(r["end"] == e for r in rs) for e in ("arrived", "timeout", "collision", "hit standing")}
        other = len(rs) - sum(n.values())
        clear = min((r["min_clearance_m"] for r in rs if r["min_clearance_m"] == r["min_clearance_m"]), default=float("nan"))
        late = np.array([r["arrival_error_s"] for r in rs if r["end"] == "arrived" and r["arrival_error_s"] == r["arrival_error_s"]])
        when = f"{np.median(late):+.2f}, {late[np.argmax(np.abs(late))]:+.2f}" if late.size else "-"
        lines.append(f"| {p} | {n['arrived']} | {n['timeout']} | {n['collision']} | {n['hit standing']} | {other} | "
                     f"{clear:.3f} | {when} |")
    bad = [r for r in rows if r["end"] not in ("arrived", "timeout")]
    if bad:
        lines += ["", "runs that touched something or failed (yard k: `python -c 'from agnav_host.sweep.yards import "
                  "yard_toml; print(yard_toml(k, ROBOT, WALKERS, TIMED, HORIZON))'`):"]
        for r in bad:
            seed = f" seed {r['seed']}" if len(seeds) > 1 else ""
            lines.append(f"- yard {r['yard']}{seed}, {r['planner']}: {r['end']}, clearance {r['min_clearance_m']:.3f} m")
    return lines
