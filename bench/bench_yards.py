"""Random cluttered yards: how often does each planner arrive, run out of time, or touch something?

The fixed scenarios of `agnav bench planners` are the references' set-ups; this draws many small worlds
instead, to find the layouts nobody thought of. Each yard is 12 x 6 m, walled, with 4-8 boxes (0.2-1.2 x
0.2-1.5 m, any yaw) and posts (radius 0.1-0.5 m) at least 1.2 m apart between x = 2 and 10 m; the robot
(the 0.45 m differential drive of refs 001/002, TiM561 laser and the 12-sonar ring) starts at (0.5, 3)
and must reach (11, y) with y drawn in 1-5 m, within 90 s. Yard k is the same on every machine
(numpy seed 1000 + k).

    .venv/bin/python bench/bench_yards.py [--yards 100] [--first 0] [--planners subsumption,flb,vfh] [--jobs 2]

Prints one row per planner (arrived / timeout / collision counts, the smallest clearance) and every run
that did not end in arrived or timeout, so it can be replayed with `agnav sim` on the printed yard.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def yard_toml(k: int) -> str:
    """Scenario TOML of yard ``k``."""
    rng = np.random.default_rng(1000 + k)
    gy = float(rng.uniform(1.0, 5.0))
    parts = [f'''[scenario]
name = "yard{k}"
description = "random cluttered yard {k} (bench/bench_yards.py)"
duration_s = 90.0
dt_s = 0.02
control_hz = 15.0

[robot]
model = "diff_drive"
start = {{ x_m = 0.5, y_m = 3.0, yaw_deg = 0.0 }}
radius_m = 0.225
max_speed_m_s = 0.5

[laser]
model = "tim561"
mount = {{ x_m = 0.15, y_m = 0.0, yaw_deg = 0.0 }}

[sonar]
enabled = true

[[goals]]
x_m = 11.0
y_m = {gy:.2f}
tolerance_m = 0.25

[[walls]]
points = [[-0.5, 0.0], [12.0, 0.0], [12.0, 6.0], [-0.5, 6.0]]
closed = true
''']
    placed: list[tuple[float, float]] = []
    for _ in range(int(rng.integers(4, 9))):
        x = y = 0.0
        for _try in range(30):
            x, y = float(rng.uniform(2.0, 10.0)), float(rng.uniform(0.3, 5.7))
            if all(np.hypot(x - a, y - b) > 1.2 for a, b in placed):
                break
        placed.append((x, y))
        if rng.random() < 0.5:
            parts.append(f"[[boxes]]\nx_m = {x:.2f}\ny_m = {y:.2f}\nsize_x_m = {rng.uniform(0.2, 1.2):.2f}\n"
                         f"size_y_m = {rng.uniform(0.2, 1.5):.2f}\nyaw_deg = {rng.uniform(0, 90):.0f}\n")
        else:
            parts.append(f"[[circles]]\nx_m = {x:.2f}\ny_m = {y:.2f}\nradius_m = {rng.uniform(0.1, 0.5):.2f}\n")
    return "\n".join(parts)


def run_one(job: tuple[int, str]) -> tuple[int, str, str, float]:
    """(yard, planner, end reason or error, smallest clearance m) of one run."""
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import parse_scenario

    k, planner = job
    try:
        r = run_scenario(parse_scenario(yard_toml(k), f"<yard {k}>"), planner, seed=0)
        return k, planner, r.end_reason, float(r.trajectory[:, 6].min())
    except Exception as e:  # a planner that raises is a finding too
        return k, planner, f"error: {type(e).__name__}: {e}"[:160], float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--yards", type=int, default=100, help="how many yards (default 100)")
    ap.add_argument("--first", type=int, default=0, help="number of the first yard (default 0): --first 100 gives yards the fixes were not tried on")
    ap.add_argument("--planners", default="subsumption,flb,him,vfh,apf,pbf,follow-path",
                    help="comma-separated planner names (default: every reactive planner)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ns = ap.parse_args(argv)
    if ns.yards < 1 or ns.jobs < 1 or ns.first < 0:
        ap.error("--yards and --jobs must be >= 1, --first >= 0")
    planners = [p.strip() for p in ns.planners.split(",") if p.strip()]
    from agnav_host.sim.runner import planner_names

    unknown = [p for p in planners if p not in planner_names()]
    if unknown:
        ap.error(f"unknown planner(s) {', '.join(unknown)}; known: {', '.join(planner_names())}")
    t0 = time.time()
    jobs = [(k, p) for p in planners for k in range(ns.first, ns.first + ns.yards)]
    with ProcessPoolExecutor(ns.jobs) as ex:
        res = list(ex.map(run_one, jobs))
    print(f"# {ns.yards} random cluttered yards {ns.first}-{ns.first + ns.yards - 1} (bench/bench_yards.py), {len(res)} runs\n")
    print("| planner | arrived | timeout | collision | other | smallest clearance m |")
    print("|---|---|---|---|---|---|")
    for p in planners:
        rs = [r for r in res if r[1] == p]
        n = {e: sum(r[2] == e for r in rs) for e in ("arrived", "timeout", "collision")}
        other = len(rs) - sum(n.values())
        clear = min((r[3] for r in rs if r[3] == r[3]), default=float("nan"))
        print(f"| {p} | {n['arrived']} | {n['timeout']} | {n['collision']} | {other} | {clear:.3f} |")
    bad = [r for r in res if r[2] not in ("arrived", "timeout")]
    if bad:
        print("\nruns that touched something or failed (yard k: `python -c 'from bench_yards import yard_toml; print(yard_toml(k))'`):")
        for k, p, end, clear in bad:
            print(f"- yard {k}, {p}: {end}, clearance {clear:.3f} m")
    print(f"\nwall time {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
