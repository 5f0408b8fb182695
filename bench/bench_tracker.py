"""Benchmark of the obstacle tracker as the timed planner uses it: how often does it call something
moving that is not?

Runs the ``timed`` planner (which runs perception's ``ObstacleTracker`` on its own laser scans) through
the built-in timed scenarios in the world simulator, and at every control step compares each track the
planner uses as *moving* with the scenario's walkers at that time.

    .venv/bin/python bench/bench_tracker.py [--seeds 3] [--reacquire 0.8]
    .venv/bin/python bench/bench_tracker.py --timing    # only the cost of one tracker update per scan

*Timing*: median wall time of ``ObstacleTracker.update`` (clustering, association, Kalman filters, the track
records) per scan, with the planners' settings (``MoverGuard``: 1 s coasting, 0.15 m size gates), on 150 scans
taken along the straight line from each scene's start to its first goal. Scenes with many plants (crop_rows,
the greenhouses) have the most clusters and tracks.

Columns: *moving reports* = moving tracks summed over the control steps; *off a walker* = those more than
0.5 m from every walker's true position, split into tracks seen in that scan (a phantom: a static object
taken for a moving one) and coasting tracks (unseen for up to 1 s, predicted on their velocity: a walker
that turned or stopped at the end of its path). Coasting predictions are expected; phantoms are the
defect this measures. Scenarios without walkers can only have phantoms. *Walkers walking in view*: control steps
at which a walker walks (over 0.2 m/s) within 6 m of the robot and 135 deg of its heading (the TiM561's field
of view; hidden behind something or not), and of them the steps with a moving track within 0.5 m of him:
how soon and how steadily people are recognised. A second table drives the ``him`` planner with the
``MoverGuard`` on through plant rows without people, where every moving track is a phantom (a track
hopping from plant to plant). ``--reacquire M`` sets the tracker's
``reacquire_m`` (a walker track missed in a scan takes a free cluster within M of where it was last seen:
one who turned round) on the planner's tracker, to compare.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import sys
import time

import numpy as np

from agnav_host.perception import ObstacleTracker, TrackerParams
from agnav_host.sim.runner import _make_controller, run_scenario
from agnav_host.sim.scenario import load_scenario
from agnav_host.types import Pose2D

SCENARIOS = ("timed_static", "timed_dynamic", "timed_delay", "timed_gap", "timed_yard", "timed_003_case1")
OFF_M = 0.5


SEEN_RANGE_M = 6.0  # a walker this near, inside the laser's field of view and walking, should be tracked as moving
SEEN_FOV_RAD = math.radians(135.0)
WALKING_M_S = 0.2


def count(name: str, seed: int, reacquire_m: float = 0.0) -> tuple[str, int, int, int, int, int]:
    """(end reason, moving reports, phantoms seen now, coasting off a walker, walker-steps in view, of them
    with a moving track within 0.5 m) of one run."""
    sc = load_scenario(name)
    ctrl = _make_controller(sc, "timed")
    if reacquire_m > 0.0:  # on the tracker that reset() makes
        reset = ctrl.reset

        def reset_reacquiring() -> None:
            reset()
            ctrl.tracker.params = dataclasses.replace(ctrl.tracker.params, reacquire_m=reacquire_m)

        ctrl.reset = reset_reacquiring  # type: ignore[method-assign]
        reset_reacquiring()
    movers = list(getattr(sc.world, "movers", []))
    n = [0, 0, 0, 0, 0]
    step = ctrl.step

    def counted(obs):  # noqa: ANN001, ANN202
        cmd = step(obs)
        at = [np.asarray(m.position(obs.t_s), dtype=float) for m in movers]
        for tr in ctrl.tracked_moving:
            n[0] += 1
            d = min((float(np.hypot(*(p - (tr.x_m, tr.y_m)))) for p in at), default=np.inf)
            if d > OFF_M:
                n[1 if tr.unseen_s <= 0.0 else 2] += 1
        for m, p in zip(movers, at):  # recall: a walker walking in view has a moving track on him
            walked = float(np.hypot(*(p - np.asarray(m.position(obs.t_s - 0.1), dtype=float)))) / 0.1
            dx, dy = p[0] - obs.pose.x_m, p[1] - obs.pose.y_m
            bearing = abs(math.remainder(math.atan2(dy, dx) - obs.pose.yaw_rad, math.tau))
            if walked > WALKING_M_S and math.hypot(dx, dy) < SEEN_RANGE_M and bearing < SEEN_FOV_RAD:
                n[3] += 1
                n[4] += any(math.hypot(tr.x_m - p[0], tr.y_m - p[1]) <= OFF_M for tr in ctrl.tracked_moving)
        return cmd

    ctrl.step = counted  # type: ignore[method-assign]
    r = run_scenario(sc, "timed", seed=seed, controller=ctrl)
    return r.end_reason, n[0], n[1], n[2], n[3], n[4]


ROW_SCENES = ("crop_rows", "curvy_row", "greenhouse", "greenhouse_shuttle")


def count_rows(name: str, seed: int, planner: str = "him") -> tuple[str, int, int]:
    """Plant rows without walkers, ``planner`` with the mover guard on (2 s): (end reason, control steps,
    moving reports: every one a phantom)."""
    sc = load_scenario(name)
    meta = dict(sc.meta)
    table = dict(meta.get("planner_params", {}))
    table[planner] = {**dict(table.get(planner, {})), "mover_horizon_s": 2.0}
    meta["planner_params"] = table
    sc = dataclasses.replace(sc, meta=meta)
    ctrl = _make_controller(sc, planner)
    n = [0, 0]
    step = ctrl.step

    def counted(obs):  # noqa: ANN001, ANN202
        cmd = step(obs)
        n[0] += 1
        n[1] += len(ctrl.guard.moving)
        return cmd

    ctrl.step = counted  # type: ignore[method-assign]
    r = run_scenario(sc, planner, seed=seed, controller=ctrl)
    return r.end_reason, n[0], n[1]


TIMING_SCENES = ("crop_rows", "greenhouse", "greenhouse_shuttle", "corridor_obstacles", "canyon", "timed_dynamic", "timed_yard")


def timing(name: str, n_scans: int = 150, repeats: int = 3, movers_only: bool = False) -> tuple[float, int]:
    """(median ms per update over the repeats' per-scan minimum, most confirmed tracks in a scan); ``movers_only``:
    the update as the planners' MoverGuard calls it (records built only for tracks that are or were moving)."""
    sc = load_scenario(name)
    assert sc.laser is not None
    rng = np.random.default_rng(0)
    start, g = sc.make_robot().pose, sc.goals[0]
    yaw = math.atan2(g.y_m - start.y_m, g.x_m - start.x_m)
    scans = [sc.laser.scan(sc.world, Pose2D(start.x_m + i / n_scans * (g.x_m - start.x_m),
                                            start.y_m + i / n_scans * (g.y_m - start.y_m), yaw), 0.1 * i, rng)
             for i in range(n_scans)]
    best = np.full(n_scans, np.inf)
    most = 0
    for _ in range(repeats):
        tr = ObstacleTracker(TrackerParams(max_coast_s=1.0, max_grow_m=0.15, max_shrink_m=0.15))
        for i, s in enumerate(scans):
            t0 = time.perf_counter()
            out = tr.update(s, movers_only=movers_only)
            best[i] = min(best[i], time.perf_counter() - t0)
            most = max(most, len(out))
    return float(np.median(best)) * 1e3, most


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 per scenario (default 3)")
    ap.add_argument("--timing", action="store_true", help="only the cost of one tracker update per scan")
    ap.add_argument("--reacquire", type=float, default=0.0, metavar="M",
                    help="the tracker's reacquire_m, m (default 0: off, as the planners run it)")
    ns = ap.parse_args(argv)
    if ns.seeds < 1:
        ap.error("--seeds must be >= 1")
    if not (math.isfinite(ns.reacquire) and 0.0 <= ns.reacquire <= 5.0):
        ap.error(f"--reacquire must be 0-5 m, got {ns.reacquire:g}")
    t0 = time.time()
    if ns.timing:
        print(f"# obstacle tracker update per scan ({platform.python_implementation()} {platform.python_version()}, "
              f"load average {os.getloadavg()[0]:.1f})\n")
        print("| scene | median ms per scan | most confirmed tracks | median ms, movers only (the MoverGuard's call) |")
        print("|---|---|---|---|")
        for name in TIMING_SCENES:
            ms, most = timing(name)
            ms_movers, _ = timing(name, movers_only=True)
            print(f"| {name} | {ms:.3f} | {most} | {ms_movers:.3f} |")
            sys.stdout.flush()
        return 0
    print(f"# obstacle tracker in the timed planner ({platform.python_implementation()} {platform.python_version()}), "
          f"seeds 0-{ns.seeds - 1}{f', reacquire_m {ns.reacquire:g}' if ns.reacquire > 0 else ''}\n")
    print("| scenario | walkers | runs arrived | moving reports | phantoms (seen now, > 0.5 m off every walker) | "
          "coasting predictions > 0.5 m off | walkers walking in view tracked as moving (steps) |")
    print("|---|---|---|---|---|---|---|")
    total_ph = 0
    for name in SCENARIOS:
        rows = [count(name, s, ns.reacquire) for s in range(ns.seeds)]
        total_ph += sum(r[2] for r in rows)
        walkers = len(getattr(load_scenario(name).world, "movers", []))
        seen, tracked = sum(r[4] for r in rows), sum(r[5] for r in rows)
        print(f"| {name} | {walkers} | {sum(r[0] == 'arrived' for r in rows)}/{len(rows)} | {sum(r[1] for r in rows)} | "
              f"{sum(r[2] for r in rows)} | {sum(r[3] for r in rows)} | "
              f"{f'{tracked}/{seen} ({100.0 * tracked / seen:.0f} %)' if seen else '-'} |")
        sys.stdout.flush()
    print(f"\nphantom moving reports in all: {total_ph}\n")
    print("Plant rows, no walkers: the him planner with the mover guard on (mover_horizon_s 2); every moving track is a phantom\n")
    print("| scene | runs arrived | control steps | moving reports (phantoms) |")
    print("|---|---|---|---|")
    for name in ROW_SCENES:
        rows2 = [count_rows(name, s) for s in range(ns.seeds)]
        print(f"| {name} | {sum(r[0] == 'arrived' for r in rows2)}/{len(rows2)} | {sum(r[1] for r in rows2)} | {sum(r[2] for r in rows2)} |")
        sys.stdout.flush()
    print(f"\nwall time {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
