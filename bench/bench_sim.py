"""Simulator benchmark: median ray-cast time (811 beams x 500 objects) and sim/wall-clock ratio.

Run: /tmp/v/bin/python bench/bench_sim.py   (numbers depend on the machine; nothing is written)
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from agnav_host.sim import cast_rays, laser_preset, load_scenario, run_scenario


def bench_raycast(repeats: int = 500) -> float:
    """Median seconds for one TiM561 scan (811 beams, 10 m) in a 30 m x 30 m world of 250 segments
    (up to 1.4 m long) and 250 circles (r 0.05-0.4 m) placed uniformly at random (seed 0)."""
    rng = np.random.default_rng(0)
    p = rng.uniform(-15, 15, (250, 2))
    segs = np.column_stack((p, p + rng.uniform(-1, 1, (250, 2))))
    circ = np.column_stack((rng.uniform(-15, 15, (250, 2)), rng.uniform(0.05, 0.4, 250)))
    spec = laser_preset("tim561")
    poses = rng.uniform(-5, 5, (repeats, 3))
    times = []
    for x, y, yaw in poses:
        t0 = time.perf_counter()
        cast_rays(x, y, yaw, spec.angle_min_rad, spec.resolution_rad, spec.n_beams, spec.max_range_m, segs, circ)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_scenario(name: str = "timed_yard", duration_s: float = 60.0) -> tuple[float, float, str]:
    sc = load_scenario(name)
    sc.goals = [sc.goals[0].__class__(1e3, 1e3)]  # unreachable goal: run the full duration
    t0 = time.perf_counter()
    r = run_scenario(sc, seed=0, duration_s=duration_s)
    wall = time.perf_counter() - t0
    return float(r.trajectory[-1, 0]), wall, r.end_reason


def main() -> None:
    med = bench_raycast()
    print(f"raycast 811 beams x 500 objects: median {med * 1e3:.3f} ms")
    for name in ("corridor_obstacles", "timed_yard"):
        sim_s, wall_s, why = bench_scenario(name)
        print(f"scenario {name}: {sim_s:.1f} s simulated in {wall_s:.2f} s wall ({sim_s / wall_s:.1f}x real time, ended: {why})")


if __name__ == "__main__":
    main()
