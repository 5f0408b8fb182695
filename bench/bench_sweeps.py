#!/usr/bin/env python3
"""What a benchmark sweep costs: the runner's overhead per run on Ray, the throughput of two local workers
against one, and a 10,000-yard sweep planned from these measurements.

    .venv/bin/python bench/bench_sweeps.py [--yards 6] [--first 200] [--repeats 2] [--no-ray]

Runs the same yard sweep (every reactive planner on ``--yards`` yards) on one local worker, on two, and on a
local Ray cluster with one CPU (``--repeats`` times each, in turn, so that the machine's other load falls on
all of them alike), and prints:

* the overhead per run: (sweep wall time x workers - the runs' own wall times) / runs, on one in-process
  worker and on one Ray worker, against the median run; and the round trip of an empty Ray task;
* the throughput of two local workers against one (wall time of one / wall time of two: a ratio within one
  run of this script, since the machine is shared);
* the peak memory of one worker process after the sweep's runs, the memory of the Ray node's own processes,
  the bytes per stored row;
* the 10,000-yard plan: 70,000 runs (7 planners), their time on 1-64 machines of this machine's cores (from
  the CPU per run with two workers side by side plus Ray's overhead, and at the rate measured on this shared
  machine), the memory per worker and the size of runs.jsonl.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PLANNERS = ("subsumption", "flb", "him", "vfh", "apf", "pbf", "follow-path")


def _tasks(yards: int, first: int) -> list:
    from agnav_host.sweep import yards as suite

    return suite.tasks(range(first, first + yards), PLANNERS)


CPU: list[float] = []  # CPU seconds of each sweep of _sweep: this process and the worker processes it waited for


def _sweep(tasks: list, backend: object) -> tuple[float, list[dict]]:
    from agnav_host.sweep import RunStore, run_sweep

    c0 = os.times()
    t0 = time.perf_counter()
    rows = run_sweep(tasks, backend, RunStore(None))  # type: ignore[arg-type]
    wall = time.perf_counter() - t0
    c1 = os.times()
    CPU.append(sum(getattr(c1, k) - getattr(c0, k) for k in ("user", "system", "children_user", "children_system")))
    return wall, rows


def _overhead_ms(wall: float, workers: int, rows: list[dict]) -> float:
    return 1e3 * (wall * workers - sum(r["wall_s"] for r in rows)) / len(rows)


WORKER_RSS = """
import resource, sys
from agnav_host.sweep import LocalBackend, RunStore, run_sweep
from agnav_host.sweep import yards
run_sweep(yards.tasks(range({first}, {first} + {yards}), {planners!r}), LocalBackend(1), RunStore(None))
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def _ray_processes_mb() -> tuple[float, float]:
    """(RSS of the Ray workers, RSS of the Ray node's other processes), MiB, summed."""
    import psutil

    workers = node = 0.0
    for p in psutil.process_iter(["cmdline", "memory_info"]):
        cmd = " ".join(p.info["cmdline"] or [])
        if "ray" not in cmd or p.pid == os.getpid() or p.info["memory_info"] is None:
            continue
        rss = p.info["memory_info"].rss / 2**20
        if "default_worker.py" in cmd:
            workers += rss
        elif any(k in cmd for k in ("raylet", "gcs_server", "dashboard", "log_monitor", "ray/_private", "monitor.py")):
            node += rss
    return workers, node


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--yards", type=int, default=6)
    ap.add_argument("--first", type=int, default=200, help="first yard (default 200: none of the tables' yards)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--no-ray", action="store_true")
    ns = ap.parse_args(argv)
    from agnav_host.sweep import LocalBackend
    from agnav_host.sweep.tasks import same_results

    tasks = _tasks(ns.yards, ns.first)
    n = len(tasks)
    print(f"# Sweep costs: {ns.yards} yards ({ns.first}-{ns.first + ns.yards - 1}) x {len(PLANNERS)} planners = {n} runs, "
          f"{ns.repeats} repeats, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start\n")
    one, two, ray1 = [], [], []
    ref: list[dict] | None = None
    backend_ray = None
    ray_start_s = float("nan")
    empty_ms = float("nan")
    ray_mb = (float("nan"), float("nan"))
    if not ns.no_ray:
        import ray

        from agnav_host.sweep import RayBackend

        backend_ray = RayBackend("local", jobs=1)
        t0 = time.perf_counter()
        backend_ray.open()
        ray_start_s = time.perf_counter() - t0
        noop = ray.remote(num_cpus=1)(lambda: None)
        ray.get(noop.remote())
        t0 = time.perf_counter()
        for _ in range(50):
            ray.get(noop.remote())
        empty_ms = (time.perf_counter() - t0) / 50 * 1e3
    cpu1, cpu2 = [], []
    for _ in range(ns.repeats):
        w, rows = _sweep(tasks, LocalBackend(1))
        one.append((w, rows))
        cpu1.append(CPU[-1])
        ref = ref or rows
        w, rows = _sweep(tasks, LocalBackend(2))
        two.append((w, rows))
        cpu2.append(CPU[-1])
        if backend_ray is not None:
            w, rows = _sweep(tasks, backend_ray)
            ray1.append((w, rows))
    if backend_ray is not None:
        ray_mb = _ray_processes_mb()
        backend_ray.close()
    assert ref is not None
    same = all(same_results(a, b) for _, rows in one + two + ray1 for a, b in zip(ref, rows))
    run_s = statistics.median(r["wall_s"] for _, rows in one for r in rows)
    mean_run_s = statistics.mean(r["wall_s"] for _, rows in one for r in rows)
    print("| back end | workers | sweep wall s (each repeat) | overhead per run ms (median) | overhead / median run |")
    print("|---|---|---|---|---|")
    for name, k, res in (("local, in process", 1, one), ("local processes", 2, two), ("Ray, local cluster", 1, ray1)):
        if not res:
            continue
        ov = statistics.median(_overhead_ms(w, k, rows) for w, rows in res)
        print(f"| {name} | {k} | {', '.join(f'{w:.1f}' for w, _ in res)} | {ov:.1f} | {ov / (run_s * 1e3) * 100:.2f} % |")
    ratios = [a / b for (a, _), (b, _) in zip(one, two)]
    print(f"\nmedian run {run_s:.3f} s, mean {mean_run_s:.3f} s; rows the same on every back end and worker count: {same}")
    print(f"throughput, 2 local workers / 1 (wall of one / wall of two, per repeat): {', '.join(f'{r:.2f}' for r in ratios)}; "
          f"load average {os.getloadavg()[0]:.1f} at the end")
    print(f"CPU per run, 1 worker / 2 workers (the sweep's own work, whatever the machine's other load): "
          f"{', '.join(f'{1e3 * a / n:.0f} / {1e3 * b / n:.0f} ms' for a, b in zip(cpu1, cpu2))}; two workers on two free "
          f"cores: {', '.join(f'{2 * a / b:.2f}' for a, b in zip(cpu1, cpu2))} x one")
    if backend_ray is not None:
        print(f"Ray: local cluster start {ray_start_s:.1f} s, empty task round trip {empty_ms:.2f} ms, "
              f"worker processes {ray_mb[0]:.0f} MiB, node processes {ray_mb[1]:.0f} MiB")
    code = WORKER_RSS.format(first=ns.first, yards=min(ns.yards, 3), planners=PLANNERS)
    rss_mb = int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
                 .stdout.split()[-1]) / 1024
    with tempfile.TemporaryDirectory() as d:
        from agnav_host.sweep import RunStore

        store = RunStore(d)
        for r in ref:
            store.add(r)
        row_b = (Path(d) / "runs.jsonl").stat().st_size / len(ref)
    print(f"worker process peak memory after {min(ns.yards, 3) * len(PLANNERS)} runs: {rss_mb:.0f} MiB; "
          f"stored row: {row_b:.0f} B")
    runs = 10_000 * len(PLANNERS)
    cores = os.cpu_count() or 1
    cpu_run = statistics.median(cpu2) / n  # one run's CPU with two workers side by side
    ray_ov = statistics.median(_overhead_ms(w, 1, rows) for w, rows in ray1) / 1e3 if ray1 else 0.0
    shared_run = statistics.median(w for w, _ in two) / n * 2  # one run's wall time per worker on this machine
    print(f"\n## 10,000 yards x {len(PLANNERS)} planners = {runs} runs, planned from these figures\n")
    print(f"({cores} workers per machine; dedicated cores: {1e3 * cpu_run:.0f} ms CPU per run (two workers side by side) "
          f"+ {1e3 * ray_ov:.1f} ms Ray overhead; this shared machine: {shared_run:.3f} s per run and worker as measured; "
          f"runs.jsonl {runs * row_b / 1e6:.0f} MB; {rss_mb:.0f} MiB per worker"
          + (f", plus about {ray_mb[1]:.0f} MiB of Ray's own processes per machine and a {ray_start_s:.0f} s cluster "
             "start" if backend_ray is not None else "") + ")\n")
    print("| machines | workers | time, dedicated cores | time at this shared machine's rate |")
    print("|---|---|---|---|")
    for m in (1, 4, 16, 64):
        dedicated = runs * (cpu_run + ray_ov) / (m * cores)
        shared = runs * shared_run / (m * cores)
        print(f"| {m} | {m * cores} | {dedicated / 3600:.2f} h | {shared / 3600:.2f} h |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
