"""Laser localisation in the host loop without surveyed posts (``--localise scan``): the host plans on wheel
odometry fused by scan matching against a map built online. Prints a markdown table of the host pose's error
from the true pose at the end of each run, and the distance driven.

* the simulator: greenhouse_cycles (ten cycles of the benches), on the simulator's drifting odometry, and on the
  same odometry alone; the 50 m curvy_row followed with the proximity follower (repetitive geometry along
  the rows);
* the SIL (the real firmware's odometry): greenhouse_cycles, and the timed scenarios with the posts taken out
  of the host's map (``bench_timed.run_sil``: final error, heading, arrival against 0.05 m, 2 deg, 0.2 s), on
  scan matching (seed 0) and on poles learnt online (``--localise poles``, seeds 0..N-1), and the same seeds with the
  surveyed posts in the map for the comparison; ``--laser tim561``
  runs them with another laser preset in place of the scenarios' TiM310 (4 m), for the comparison.

Usage: ``.venv/bin/python bench/bench_scan_localiser.py [--only sim,rows,sil,timed] [--seeds 5] [--no-walls]
[--laser NAME]``
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _path_m(traj: np.ndarray) -> float:
    return float(np.hypot(*np.diff(traj[:, 1:3], axis=0).T).sum())


def _row(label: str, run) -> None:  # type: ignore[no-untyped-def]
    b, p = run.believed
    err = math.hypot(b.x_m - p.x_m, b.y_m - p.y_m)
    yaw = math.degrees(abs(math.remainder(b.yaw_rad - p.yaw_rad, 2 * math.pi)))
    dist = _path_m(run.trajectory)
    print(f"| {label} | {run.end_reason} | {dist:.1f} | {err:.4f} | {yaw:.3f} | {100 * err / max(dist, 1e-9):.3f} |")


def _orchard(rows: int = 8, trunks: int = 30) -> None:
    """``--localise poles`` in a synthetic orchard: ``rows`` x ``trunks`` trunks (radius 0.1 m, 1.5 m apart, rows
    4 m apart), driven up and down every lane at 0.5 m/s on odometry that over-reads the distance by 1 % and
    the turns by 2 %, a 270 deg laser of 0.5 deg beams and 10 m. Prints the CPU per scan as the map grows and
    the pose error at the end."""
    from agnav_host.localisation.pole_slam import PoleSlam
    from agnav_host.types import Pose2D

    xs, ys = np.meshgrid(np.arange(trunks) * 1.5, np.arange(rows) * 4.0)
    cx, cy = xs.ravel(), ys.ravel()
    ang = np.radians(np.arange(-135.0, 135.01, 0.5))
    rng = np.random.default_rng(0)
    # the lanes between the rows, driven up and down, joined at the ends
    way = []
    for k in range(rows - 1):
        y = 4.0 * k + 2.0
        a, b = (-1.0, 1.5 * trunks) if k % 2 == 0 else (1.5 * trunks, -1.0)
        way += [(a, y), (b, y)]
    path = np.array(way)
    seg = np.hypot(*np.diff(path, axis=0).T)
    s_all = np.arange(0.0, seg.sum(), 0.5 / 15)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    px, py = np.interp(s_all, cum, path[:, 0]), np.interp(s_all, cum, path[:, 1])
    yaw = np.unwrap(np.arctan2(np.gradient(py), np.gradient(px)))
    loc = PoleSlam(Pose2D(float(px[0]), float(py[0]), float(yaw[0])))
    odo = np.zeros(3)
    cost: list[tuple[int, float]] = []
    for k in range(len(s_all)):
        if k:
            c, s_ = math.cos(yaw[k - 1]), math.sin(yaw[k - 1])
            dx, dy = px[k] - px[k - 1], py[k] - py[k - 1]
            fwd, side = (c * dx + s_ * dy) * 1.01, -s_ * dx + c * dy
            oc, os_ = math.cos(odo[2]), math.sin(odo[2])
            odo += [oc * fwd - os_ * side, os_ * fwd + oc * side, 1.02 * (yaw[k] - yaw[k - 1])]
        t = k / 15.0
        loc.odometry(float(odo[0]), float(odo[1]), float(odo[2]), t, 0.5, 0.0)
        # the scan from the true pose: nearest trunk along each beam
        bx, by = np.cos(yaw[k] + ang), np.sin(yaw[k] + ang)
        rx, ry = cx - px[k], cy - py[k]
        bproj = np.outer(bx, rx) + np.outer(by, ry)
        disc = bproj ** 2 - (rx ** 2 + ry ** 2 - 0.1 ** 2)
        tt = np.where(disc >= 0, bproj - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        tt = np.where(tt > 0, tt, np.inf).min(axis=1)
        r = np.where(tt < 10.0, tt + rng.normal(0.0, 0.01, len(tt)), np.nan)
        t0 = time.thread_time()
        loc.scan(r, ang, t, 10.0)
        cost.append((len(loc.poles), time.thread_time() - t0))
    c = np.array(cost)
    err = math.hypot(loc.X[0] - px[-1], loc.X[1] - py[-1])
    print(f"\norchard ({rows} rows x {trunks} trunks, {s_all[-1]:.0f} m driven, {len(c)} scans): poles learnt {int(c[-1, 0])}; "
          f"pose error at the end {err:.3f} m (the odometry alone "
          f"{math.hypot(loc.start.x_m + odo[0] - px[-1], loc.start.y_m + odo[1] - py[-1]):.2f} m)")
    for lo, hi in ((0, 50), (50, 100), (100, 200), (200, 400)):
        m = (c[:, 0] >= lo) & (c[:, 0] < hi)
        if m.any():
            print(f"  CPU per scan with {lo}-{hi} poles learnt: median {1e3 * np.median(c[m, 1]):.1f} ms, "
                  f"max {1e3 * c[m, 1].max():.1f} ms")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="sim,rows,sil,timed")
    ap.add_argument("--seeds", type=int, default=5, help="seeds of the timed SIL runs with --localise poles")
    ap.add_argument("--no-walls", action="store_true", help="--localise poles on poles alone (no wall landmarks)")
    ap.add_argument("--laser", default=None, help="the timed runs with this laser preset (tim561, lms200, tim310)")
    ns = ap.parse_args(argv)
    only = set(ns.only.split(","))
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import load_scenario

    print("| run | end | driven m | host pose error at the end m | heading error deg | error / distance % |")
    print("|---|---|---|---|---|---|")
    cost: list[float] = []
    if "sim" in only:
        from agnav_host.localisation.scan_localiser import ScanLocaliser

        scan = ScanLocaliser.scan

        def timed_scan(self, *a, **k):  # type: ignore[no-untyped-def]
            t0 = time.thread_time()
            out = scan(self, *a, **k)
            cost.append(time.thread_time() - t0)
            return out

        ScanLocaliser.scan = timed_scan  # type: ignore[method-assign]
        sc = load_scenario("greenhouse_cycles")
        for loc in ("scan", "odometry"):
            _row(f"simulator, greenhouse_cycles, him, --localise {loc}", run_scenario(sc, "him", 0, localise=loc))
        ScanLocaliser.scan = scan  # type: ignore[method-assign]
    if "rows" in only:
        for name, dur in (("curvy_row", 200.0),):
            _row(f"simulator, {name}, proximity, --localise scan",
                 run_scenario(load_scenario(name), "proximity", 0, dur, localise="scan"))
    if "orchard" in only:
        _orchard()
    if cost:
        c = 1e3 * np.array(cost)
        print(f"\nlocaliser CPU per scan (greenhouse_cycles, simulator, {len(c)} scans at 15 Hz): mean {c.mean():.1f} ms, "
              f"median {np.median(c):.1f}, p99 {np.percentile(c, 99):.1f}, max {c.max():.1f} ms\n")
    if "sil" in only:
        from agnav_host.sil.session import run_sil_scenario

        res = run_sil_scenario(load_scenario("greenhouse_cycles"), "him", 0, localise="scan")
        _row("SIL, greenhouse_cycles, him, --localise scan", res.run)
    if "timed" in only:
        import bench_timed as bt

        if ns.no_walls:  # the poles localiser without its wall landmarks, for the comparison
            import agnav_host.sim.runner as runner
            from agnav_host.localisation.pole_slam import PoleSlam, PoleSlamParams

            make = runner.make_localiser

            def poles_only(sc, localise, map_yaml=None):  # type: ignore[no-untyped-def]
                if localise == "poles":
                    return PoleSlam(sc.start, sc.laser.mount, PoleSlamParams(walls=False))
                return make(sc, localise, map_yaml)

            runner.make_localiser = poles_only  # type: ignore[assignment]

        laser = None
        if ns.laser:
            from agnav_host.sim.sensors import laser_preset

            try:
                laser = laser_preset(ns.laser)
            except ValueError as e:
                print(f"bench_scan_localiser: {e}", file=sys.stderr)
                return 2
        # the surveyed posts in the map (the post localiser) for the comparison
        for loc, seeds in (("scan", [0]), ("poles", list(range(ns.seeds))), ("posts", list(range(ns.seeds)))):
            where = "surveyed posts in the host's map" if loc == "posts" else f"posts out of the host's map, --localise {loc}"
            print(f"\n| timed SIL, {where}{f', laser {laser.name}' if laser else ''} "
                  "| seed | arrived | arrival err s | final pos err m | final hdg err deg | host pose err max m (driving) "
                  "| host pose err at the end m | all three met |")
            print("|---|---|---|---|---|---|---|---|---|")
            met = 0
            end_err: list[float] = []
            for nm in bt.SIL_SCENARIOS:
                for seed in seeds:
                    sc = bt._scenario(nm)
                    if loc != "posts":
                        sc = replace(sc, meta={**{k: v for k, v in sc.meta.items() if k != "landmarks"}, "localise": loc})
                    if laser is not None and sc.laser is not None:
                        sc = replace(sc, laser=replace(sc.laser, spec=laser))
                    r = bt.run_sil(sc, seed, localise=True)
                    good = (r.arrived and r.arrival_err_s is not None and abs(r.arrival_err_s) <= 0.2
                            and r.final_pos_err_m <= 0.05 and r.final_hdg_err_deg <= 2.0)
                    met += good
                    end_err.append(r.loc_err_final_m)
                    print(f"| {nm} | {seed} | {r.arrived} | {bt._fmt(r.arrival_err_s, 2)} | {r.final_pos_err_m:.3f} | "
                          f"{r.final_hdg_err_deg:.2f} | {r.loc_err_max_m:.3f} | {r.loc_err_final_m:.3f} | "
                          f"{'yes' if good else 'no'} |", flush=True)
            n = len(bt.SIL_SCENARIOS) * len(seeds)
            print(f"\n{'surveyed posts' if loc == 'posts' else '--localise ' + loc}: {met} of {n} runs meet 0.05 m, 2 deg and 0.2 s; host pose error at the end "
                  f"max {max(end_err):.3f} m, within 0.05 m in {sum(e <= 0.05 for e in end_err)} of {n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
