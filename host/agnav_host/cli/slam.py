"""``agnav slam``: laser SLAM over a recorded log, offline.

    agnav slam LOG --out DIR [--relations FILE] [--laser ID] [--resolution M] [--json] [--quiet]

LOG is an AgNav laser log (``.alog``) or a CARMEN log (FLASER / ROBOTLASER1 / RAWLASER + ODOM lines; a zip
archive holding one is read too). DIR gets ``trajectory.csv`` (``t,x,y,yaw``, one row per scan, t as written
in the log, m and rad), ``map.pgm`` + ``map.yaml`` (ROS map_server) and ``map.png`` (the map with the
trajectory). ``--relations FILE`` scores the trajectory against ground-truth relations (Kuemmerle et al.
2009: ``t1 t2 dx dy dz roll pitch yaw`` a line). Exit codes: 0 done, 2 bad input (a log that cannot be
read or holds no scan, a bad relations file, a bad option), 1 an output that cannot be written.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from .argtypes import nonneg_int, positive_float_at_most
from .outputs import clear_earlier_outputs, report_write_failure, unusable_out_dir
from .progress import ProgressLine
from .registry import subcommand

__all__: list[str] = []

_PROGRESS_EVERY_S = 0.5


def _progress(total: int, quiet: bool) -> tuple[ProgressLine, object]:
    line = ProgressLine(every_s=_PROGRESS_EVERY_S)
    t0 = time.perf_counter()

    def show(done: int) -> None:
        if quiet:
            return
        el = time.perf_counter() - t0
        rate = done / el if el > 0 else 0.0
        left = (total - done) / rate if rate > 0 else 0.0
        line.show(f"agnav slam: scan {done}/{total} ({100 * done // max(total, 1)}%), {rate:.0f} scans/s, "
                  f"{left:.0f} s left")

    return line, show


@subcommand(
    "slam",
    help="laser SLAM over a recorded log (AgNav .alog or CARMEN): trajectory, occupancy grid, plot",
    epilog="exit codes: 0 = done, 2 = bad input (unreadable or empty log, bad relations file, bad option), "
           "1 = an output that cannot be written. Units: m, rad; trajectory times as written in the log.",
    args=[
        (("log",), {"metavar": "LOG", "help": "the log: an AgNav laser log (.alog) or a CARMEN log (text or zip)"}),
        (("--out",), {"required": True, "metavar": "DIR",
                      "help": "output folder: trajectory.csv, map.pgm, map.yaml, map.png"}),
        (("--relations",), {"default": None, "metavar": "FILE",
                            "help": "ground-truth relations to score the trajectory against (t1 t2 dx dy dz roll "
                                    "pitch yaw a line; Kuemmerle et al. 2009)"}),
        (("--laser",), {"type": nonneg_int, "default": None, "metavar": "ID",
                        "help": "the laser of an AgNav log (default: the first declared)"}),
        (("--resolution",), {"type": positive_float_at_most(1.0, "1 m"), "default": 0.05, "metavar": "M",
                             "help": "the occupancy grid's cell size, m, <= 1 (default 0.05)"}),
        (("--no-loops",), {"action": "store_true", "help": "scan-matching odometry only: no loop closure"}),
        (("--json",), {"action": "store_true", "help": "print the summary as JSON"}),
        (("--quiet",), {"action": "store_true", "help": "no progress line, no notes on stderr"}),
    ],
)
def _cmd_slam(ns: argparse.Namespace) -> int:
    import numpy as np

    from ..localisation.relations import RelationsError, read_relations, score_relations
    from ..localisation.slam import Slam, SlamParams
    from ..localisation.slam_io import OUTPUT_FILES, SlamLogError, read_slam_log, write_slam_outputs

    def fail(msg: str, code: int = 2) -> int:
        print(f"agnav slam: {msg}", file=sys.stderr)
        return code

    rel = None
    if ns.relations is not None:
        try:
            rel = read_relations(ns.relations)
        except RelationsError as e:
            return fail(str(e))
        except OSError as e:
            return fail(f"--relations {ns.relations}: cannot read it: {e.strerror or e}")
    try:
        log = read_slam_log(ns.log, ns.laser)
    except SlamLogError as e:
        return fail(str(e))
    except OSError as e:
        return fail(f"{ns.log}: cannot read the log: {e.strerror or e}")
    bad_out = unusable_out_dir(ns.out) or clear_earlier_outputs("slam", ns.out, OUTPUT_FILES, ns.quiet)
    if bad_out:
        return fail(f"--out {ns.out}: {bad_out}", 1)
    if not ns.quiet:
        print(f"agnav slam: {ns.log}: {log.summary}", file=sys.stderr)
    params = SlamParams(loop_every=10**9) if ns.no_loops else SlamParams()
    slam = Slam(params)
    line, show = _progress(len(log.scans), ns.quiet)
    t0 = time.perf_counter()
    try:
        for k, scan in enumerate(log.scans):
            slam.add(scan)
            show(k + 1)  # type: ignore[operator]
    finally:
        line.end()
    result = slam.result()
    wall = time.perf_counter() - t0
    try:
        write_slam_outputs(result, ns.out, ns.resolution)
    except OSError as e:
        return report_write_failure("slam", ns.out, e)
    span = float(result.t_s[-1] - result.t_s[0]) if len(result.t_s) > 1 else 0.0
    per_scan = np.asarray(result.per_scan_ms)
    out = {"log": str(ns.log), "scans": len(result.t_s), "skipped": log.skipped, "log_span_s": round(span, 3),
           "seconds": round(wall, 3), "per_scan_ms_mean": round(1e3 * wall / max(len(result.t_s), 1), 3),
           "per_scan_ms_median": round(float(np.median(per_scan)), 3) if len(per_scan) else 0.0,
           "per_scan_ms_max": round(float(per_scan.max()), 3) if len(per_scan) else 0.0,
           "loops_tried": result.loops_tried, "loops_accepted": result.loops_accepted,
           "loops_conflicting": result.loops_conflicting, "without_odometry": result.no_odometry,
           "out": str(ns.out)}
    score = None
    if rel is not None:
        score = score_relations(result.t_s, result.poses, rel)
        out["relations"] = score.as_dict()
    if ns.json:
        print(json.dumps(out, indent=1))
        return 0
    speed = f", {span / wall:.1f}x the log's own time" if wall > 0 and span > 0 else ""
    print(f"{out['scans']} scans in {wall:.1f} s ({out['per_scan_ms_mean']:.1f} ms per scan{speed}); "
          f"loop closures {result.loops_accepted} of {result.loops_tried} tried; wrote {ns.out}")
    if score is not None:
        print(f"relations: {score.summary()}")
    return 0
