"""The robot path against the SIL path: the laser scenarios of the perception and timed benchmarks run twice,

* **SIL**: the lock-step firmware SIL with the host loop in the same process (agnav_host.sil.session), and
* **robot**: `agnav sil SCENARIO --laser KIND` and `agnav run --laser URL` in two processes over TCP, the lasers
  served by the device emulators over their own protocols, in real time (agnav_host.sil.robot_path),

and prints the figures side by side with their targets, then the robot path's laser-to-command latency
(median and 99th percentile per scan, from the scan's mid-beam stamp to the setpoint sent).

    .venv/bin/python bench/bench_robot_path.py [--only NAME[,NAME]] [--out DIR]     # about 6 minutes, real time
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from agnav_host.sil.robot_path import row_distance_of, run_robot_path, timed_errors
from agnav_host.sil.session import run_sil_scenario
from agnav_host.sim.metrics import row_distance
from agnav_host.types import norm_angle_rad
from agnav_host.sim.scenario import load_scenario

# name, scenario, controller, emulated lasers, duration (None: the scenario's)
CASES = [
    ("rows", "crop_rows", "row-follower", ("tim5xx",), None),
    ("proximity", "curvy_row", "proximity", ("ust",), None),
    ("holes", "hole_field", "goal_seek+ground-guard", ("lms1xx", "lms5xx"), None),
    ("timed_static", "timed_static", "timed", ("tim5xx",), None),
    ("timed_dynamic", "timed_dynamic", "timed", ("urg",), None),
]
LANE_Y_M = 1.875  # crop_rows: the middle lane's centre line


def lane_error(tr: np.ndarray) -> float:
    """Mean |offset| from the crop_rows lane's centre line while inside the rows (0.5 <= x <= 7.5 m)."""
    m = (tr[:, 1] >= 0.5) & (tr[:, 1] <= 7.5)
    return float(np.mean(np.abs(tr[m, 2] - LANE_Y_M))) if m.any() else math.nan


def figures(name: str, sc, tr: np.ndarray, end: str, arrival_s: float | None) -> dict[str, object]:
    f: dict[str, object] = {"end": end}
    if name == "rows":
        f["lane error, mean m"] = lane_error(tr)
    elif name == "proximity":
        rd = row_distance(tr[:, 1], tr[:, 2], sc.world.row_lines, float(sc.meta.get("follow_offset_m", 1.0)))
        f["row distance, m"] = f"{rd.min_m:.3f}-{rd.max_m:.3f} (mean {rd.mean_m:.3f}, {100 * rd.within:.1f} % in band)" if rd else "-"
    elif name.startswith("timed"):
        g = sc.goals[-1]
        e = tr[-1]
        f["final error, m"] = math.hypot(e[1] - g.x_m, e[2] - g.y_m)
        f["heading error, deg"] = abs(math.degrees(norm_angle_rad(e[3] - g.yaw_rad)))
        f["arrival error, s"] = None if arrival_s is None else arrival_s - g.arrival_s
    return f


TARGETS = {"rows": "lane error <= 0.02 m (ref 004's field figures: 0.02-0.03 m)", "proximity": "1 +- 0.05 m",
           "holes": "arrived, not fallen in", "timed_static": "0.05 m, 2 deg, 0.2 s", "timed_dynamic": "0.05 m, 2 deg, 0.2 s"}


def fmt(v: object) -> str:
    if isinstance(v, float):
        return f"{v:.3f}"
    return "-" if v is None else str(v)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="comma-separated case names: " + ", ".join(c[0] for c in CASES))
    ap.add_argument("--out", default=None, help="keep the runs' folders here (default: a temporary folder)")
    ns = ap.parse_args()
    only = set(ns.only.split(",")) if ns.only else None
    out = Path(ns.out) if ns.out else Path(tempfile.mkdtemp(prefix="robot_path_"))
    rows = []
    lat = []
    for name, scen, ctrl, lasers, dur in CASES:
        if only and name not in only:
            continue
        sc = load_scenario(scen)
        print(f"[{name}] SIL ...", file=sys.stderr, flush=True)
        sil = run_sil_scenario(sc, ctrl, 0, dur).run
        sil_arr = sil.metrics.time_s if sil.end_reason == "arrived" else None
        a = figures(name, sc, sil.trajectory, sil.end_reason, sil_arr)
        print(f"[{name}] robot path ({', '.join(lasers)}) ...", file=sys.stderr, flush=True)
        r = run_robot_path(sc, ctrl, out / name, lasers, duration_s=dur)
        tr = r.truth.copy()
        arr = timed_errors(r, sc)["arrival_error_s"]
        b = figures(name, sc, tr, r.end_reason, None if arr is None else arr + (sc.goals[-1].arrival_s or 0.0))
        if name == "proximity":
            rd = row_distance_of(r, sc)
            b["row distance, m"] = f"{rd.min_m:.3f}-{rd.max_m:.3f} (mean {rd.mean_m:.3f}, {100 * rd.within:.1f} % in band)" if rd else "-"
        rows.append((name, scen, ctrl, "+".join(lasers), a, b))
        lat.append((name, "+".join(lasers), r.latency, (r.run_info or {}).get("scan_to_loop", {}),
                    (r.run_info or {}).get("controller_step", {})))
    print("\n| case | scenario, controller | scanners (robot path) | figure | SIL path | robot path | target |")
    print("|---|---|---|---|---|---|---|")
    for name, scen, ctrl, lasers, a, b in rows:
        for k in a:
            print(f"| {name} | {scen}, {ctrl} | {lasers} | {k} | {fmt(a[k])} | {fmt(b.get(k))} | {TARGETS[name]} |")
    print("\n| case | scanners | scans | laser to command, median ms | 99th percentile ms | scan to loop, median ms | controller step, median ms |")
    print("|---|---|---|---|---|---|---|")
    for name, lasers, lt, w, st in lat:
        print(f"| {name} | {lasers} | {lt.get('scans')} | {fmt(lt.get('median_ms'))} | {fmt(lt.get('p99_ms'))} | "
              f"{fmt(w.get('median_ms'))} | {fmt(st.get('median_ms'))} |")
    print(f"\nruns kept in {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
