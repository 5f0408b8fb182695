"""Random cluttered yards: how often does each planner arrive, run out of time, or touch something?

The fixed scenarios of `agnav bench planners` are the references' set-ups; this draws many small worlds
instead, to find the layouts nobody thought of. Each yard is 12 x 6 m, walled, with 4-8 boxes (0.2-1.2 x
0.2-1.5 m, any yaw) and posts (radius 0.1-0.5 m) at least 1.2 m apart between x = 2 and 10 m; the robot
(the 0.45 m differential drive of refs 001/002, TiM561 laser and the 12-sonar ring) starts at (0.5, 3)
and must reach (11, y) with y drawn in 1-5 m, within 90 s. Yard k is the same on every machine
(numpy seed 1000 + k).

    .venv/bin/python bench/bench_yards.py [--yards 100] [--first 0] [--planners subsumption,flb,vfh] [--jobs 2]
    .venv/bin/python bench/bench_yards.py --robot ackermann [--walkers 2] [--timed]

Options: ``--robot ackermann`` puts the ref-003 RC car (0.38 m turning radius, no reverse, 0.435 m/s
slowest) in the same yards; ``--walkers N`` adds N people pacing across each yard on lines clear of the
boxes (0.4-1.0 m/s, oblivious of the robot; the laser planners then track them and let them by,
``mover_horizon_s`` 2 s, which the timed planner always does); ``--timed`` gives the goal an arrival time (straight line at
0.6 m/s plus 6 s) and reports the arrival-time error (the run ends on entering the 0.25 m goal
tolerance, about half a second before the car's centre reaches the goal, so on-time runs show about -0.5 s).

Prints one row per planner (arrived / timeout / collision counts, the smallest clearance) and every run
that did not end in arrived or timeout, so it can be replayed with `agnav sim` on the printed yard. A
contact is counted as "hit standing" when the robot was below 0.1 m/s at the first touch and what it
touched is a walker (the walker walked into it; ref 001's passive motion safety allows that), as
"collision" otherwise (a car rolling to rest against a box has hit it).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np


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
description = "random cluttered yard {k} (bench/bench_yards.py)"
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


def run_one(job: tuple[int, str, str, int, bool, float]) -> tuple[int, str, str, float, float]:
    """(yard, planner, end reason or error, smallest clearance m, arrival-time error s or nan) of one run.
    A collision's end reason is "collision" while the robot moved at the first contact, "hit standing"
    when it was (nearly) at rest: a walker walked into it."""
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import parse_scenario

    k, planner, robot, walkers, timed, horizon = job
    try:
        sc = parse_scenario(yard_toml(k, robot, walkers, timed, horizon), f"<yard {k}>")
        r = run_scenario(sc, planner, seed=0)
        late = r.metrics.arrival_time_error_s
        end = r.end_reason
        touch = np.flatnonzero(r.trajectory[:, 6] < 0.0)
        if end == "collision" and len(touch) and abs(r.trajectory[touch[0], 4]) < STANDING_M_S and sc.world.movers:
            # standing: only when what it touches is a walker (a car rolling to rest against a box hit it)
            from agnav_host.sim.world import distance_to_objects

            _t, x, y, yaw = r.trajectory[touch[0], :4]
            p = sc.robot_params
            off = 0.5 * p.wheelbase_m if hasattr(p, "wheelbase_m") else 0.0
            cx, cy = np.atleast_1d(x + off * np.cos(yaw)), np.atleast_1d(y + off * np.sin(yaw))
            if float(distance_to_objects(cx, cy, sc.world.segments, sc.world.circles)[0]) - p.radius_m > 0.0:
                end = "hit standing"
        return k, planner, end, float(r.trajectory[:, 6].min()), float("nan") if late is None else float(late)
    except Exception as e:  # a planner that raises is a finding too
        return k, planner, f"error: {type(e).__name__}: {e}"[:160], float("nan"), float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--yards", type=int, default=100, help="how many yards (default 100)")
    ap.add_argument("--first", type=int, default=0, help="number of the first yard (default 0): --first 100 gives yards the fixes were not tried on")
    ap.add_argument("--planners", default=None,
                    help="comma-separated planner names (default: every reactive planner; with --robot ackermann "
                         "those that drive a car, and timed)")
    ap.add_argument("--robot", choices=sorted(ROBOTS), default="diff",
                    help="diff: the 0.45 m differential drive (default); ackermann: the ref-003 RC car")
    ap.add_argument("--walkers", type=int, default=0, help="people pacing across each yard (default 0)")
    ap.add_argument("--timed", action="store_true",
                    help=f"give the goal an arrival time (straight line at {ARRIVE_SPEED_M_S} m/s + {ARRIVE_SLACK_S:.0f} s)")
    ap.add_argument("--mover-horizon", type=float, default=2.0, metavar="S",
                    help="with --walkers: mover_horizon_s given to the laser planners (default 2; 0: they do not track people)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ns = ap.parse_args(argv)
    if ns.yards < 1 or ns.jobs < 1 or ns.first < 0 or ns.walkers < 0 or not 0.0 <= ns.mover_horizon <= 10.0:
        ap.error("--yards and --jobs must be >= 1, --first and --walkers >= 0, --mover-horizon 0-10 s")
    if ns.planners is None:
        ns.planners = ("subsumption,flb,him,vfh,apf,pbf,follow-path" if ns.robot == "diff"
                       else "flb,him,vfh,apf,pbf,follow-path,timed")
    planners = [p.strip() for p in ns.planners.split(",") if p.strip()]
    from agnav_host.sim.runner import planner_names

    unknown = [p for p in planners if p not in planner_names()]
    if unknown:
        ap.error(f"unknown planner(s) {', '.join(unknown)}; known: {', '.join(planner_names())}")
    t0 = time.time()
    jobs = [(k, p, ns.robot, ns.walkers, ns.timed, ns.mover_horizon) for p in planners for k in range(ns.first, ns.first + ns.yards)]
    res: list[tuple[int, str, str, float, float]] = [None] * len(jobs)  # type: ignore[list-item]
    show = sys.stderr.isatty()  # a progress line for people at a terminal, none in logs
    from agnav_host.planning.bench import workers

    with ProcessPoolExecutor(workers(ns.jobs, len(jobs))) as ex:
        futures = {ex.submit(run_one, job): i for i, job in enumerate(jobs)}
        for done, fut in enumerate(as_completed(futures), 1):
            res[futures[fut]] = fut.result()
            if show:
                k, p, end = res[futures[fut]][:3]
                bar = "#" * (30 * done // len(jobs))
                eta = (time.time() - t0) / done * (len(jobs) - done)
                print(f"\r[{bar:<30}] {done}/{len(jobs)} runs, about {eta:.0f} s left; yard {k} {p}: {end:<14.14}",
                      end="" if done < len(jobs) else "\n", file=sys.stderr, flush=True)
    what = f"{ns.robot} robot" + (f", {ns.walkers} walker(s), mover_horizon_s {ns.mover_horizon:g}" if ns.walkers else "") + (", timed goal" if ns.timed else "")
    print(f"# {ns.yards} random cluttered yards {ns.first}-{ns.first + ns.yards - 1} (bench/bench_yards.py), {what}, {len(res)} runs\n")
    print("| planner | arrived | timeout | collision (moving) | hit standing | other | smallest clearance m | "
          "arrival error s (median, worst) |")
    print("|---|---|---|---|---|---|---|---|")
    for p in planners:
        rs = [r for r in res if r[1] == p]
        n = {e: sum(r[2] == e for r in rs) for e in ("arrived", "timeout", "collision", "hit standing")}
        other = len(rs) - sum(n.values())
        clear = min((r[3] for r in rs if r[3] == r[3]), default=float("nan"))
        late = np.array([r[4] for r in rs if r[2] == "arrived" and r[4] == r[4]])
        when = f"{np.median(late):+.2f}, {late[np.argmax(np.abs(late))]:+.2f}" if late.size else "-"
        print(f"| {p} | {n['arrived']} | {n['timeout']} | {n['collision']} | {n['hit standing']} | {other} | {clear:.3f} | {when} |")
    bad = [r for r in res if r[2] not in ("arrived", "timeout")]
    if bad:
        print("\nruns that touched something or failed (yard k: `python -c 'from bench_yards import yard_toml; "
              "print(yard_toml(k, ROBOT, WALKERS, TIMED, HORIZON))'`):")
        for k, p, end, clear, _late in bad:
            print(f"- yard {k}, {p}: {end}, clearance {clear:.3f} m")
    print(f"\nwall time {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
