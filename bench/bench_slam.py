"""Laser SLAM on the real MIT Killian Court log, scored with the relative-pose metric of Kuemmerle et al. 2009.

    .venv/bin/python bench/bench_slam.py [--scans N] [--out DIR] [--no-loops]

Reads ``killian.g2o.zip`` from PyPI's rtb-data and ``mit-killian.relations`` from the shared data folder
(``$AGNAV_KILLIAN_RELATIONS`` overrides), runs :class:`agnav_host.localisation.slam.Slam` over the scans on
one core, writes the trajectory, map and plot to ``--out`` (default: a temporary folder) and prints: the
translational and rotational error (mean +- sd, max) over the relations with both ends among the scans,
split into local relations (t2 - t1 < 20 s) and loop relations (the robot back at a place minutes
later), the same for the log's own odometry, the cost per scan (CPU and wall time) and the total against
the recording's length. A run over the whole log also writes what it printed to ``bench/results/slam.md`` and
the map with the trajectory to ``bench/results/slam_killian.png``. The figures go to BENCHMARKS.md ("Laser
SLAM") by hand.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from agnav_host.localisation.killian import PUBLISHED_TRANS_M, killian_log_path, killian_relations_path  # noqa: E402
from agnav_host.localisation.relations import Relations, read_relations, score_relations  # noqa: E402
from agnav_host.localisation.slam import Slam, SlamParams  # noqa: E402
from agnav_host.localisation.slam_io import read_slam_log, write_slam_outputs  # noqa: E402

LOOP_GAP_S = 20.0


def _subset(rel: Relations, keep: np.ndarray) -> Relations:
    return Relations(rel.t1_s[keep], rel.t2_s[keep], rel.dx_m[keep], rel.dy_m[keep], rel.dyaw_rad[keep])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scans", type=int, default=None, help="only the first N scans (default: all 3,873)")
    ap.add_argument("--out", default=None, help="output folder (default: a temporary one)")
    ap.add_argument("--no-loops", action="store_true", help="scan-matching odometry only")
    ns = ap.parse_args(argv)
    out = ns.out or tempfile.mkdtemp(prefix="agnav-slam-")
    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text)
        lines.append(text)

    log = read_slam_log(killian_log_path())
    rel = read_relations(killian_relations_path())
    scans = log.scans[: ns.scans] if ns.scans else log.scans
    say(f"log: {log.summary}")
    slam = Slam(SlamParams(loop_every=10**9) if ns.no_loops else SlamParams())
    cpu0, wall0 = time.process_time(), time.perf_counter()
    for k, s in enumerate(scans):
        slam.add(s)
        if (k + 1) % 500 == 0:
            print(f"  {k + 1} scans, {time.perf_counter() - wall0:.0f} s", file=sys.stderr, flush=True)
    result = slam.result()
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    write_slam_outputs(result, out, resolution_m=0.1)
    span = float(result.t_s[-1] - result.t_s[0])
    t = result.t_s
    odom = np.array([s.odom for s in scans])
    local = np.abs(rel.t2_s - rel.t1_s) < LOOP_GAP_S
    say(f"\n{len(scans)} scans, {span:.0f} s of recording; loop closures accepted {result.loops_accepted}, "
        f"tried {result.loops_tried}, taken back as conflicting {result.loops_conflicting}")
    say(f"cost: {1e3 * cpu / len(scans):.1f} ms CPU per scan ({cpu:.1f} s CPU in all, {span / cpu:.0f}x faster "
        f"than the recording), {1e3 * wall / len(scans):.1f} ms wall per scan ({wall:.1f} s)")
    say(f"per-scan wall time: median {np.median(result.per_scan_ms):.1f} ms, 99th percentile "
        f"{np.percentile(result.per_scan_ms, 99):.1f} ms, max {np.max(result.per_scan_ms):.0f} ms")
    say("\nrelative-pose error (Kuemmerle et al. 2009):")
    for name, poses in (("slam", result.poses), ("odometry", odom)):
        for part, keep in (("all", np.ones(len(rel), bool)), ("local", local), ("loop", ~local)):
            sc = score_relations(t, poses, _subset(rel, keep))
            say(f"  {name:9s} {part:6s} {sc.summary()}")
    say("\npublished translational errors on this run: " +
        "; ".join(f"{k} {m:.3f} +- {s:.3f} m" for k, (m, s) in PUBLISHED_TRANS_M.items()))
    print(f"outputs: {out}")
    if not ns.scans and not ns.no_loops:
        results = ROOT / "bench" / "results"
        (results / "slam.md").write_text("# Laser SLAM on the MIT Killian Court log\n\n`.venv/bin/python bench/bench_slam.py`"
                                         "\n\n```\n" + "\n".join(lines).strip() + "\n```\n", encoding="utf-8")
        shutil.copy(Path(out) / "map.png", results / "slam_killian.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
