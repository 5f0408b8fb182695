"""Whole fields benchmark: the row navigator on generated fields of each difficulty, both robots, in the simulator's
runner and in the SIL (native firmware, radio link, the firmware's odometry), scored as the Field Robot Event does
(sim.field_gen); and the proximity follower on curvy_row against the row as planted.

Run:  .venv/bin/python bench/bench_fields.py                       (runner and SIL, 20 fields per difficulty)
      .venv/bin/python bench/bench_fields.py --only runner --seeds 20 --jobs 2
      .venv/bin/python bench/bench_fields.py --only sil --seeds 5
      .venv/bin/python bench/bench_fields.py --only proximity
Prints the BENCHMARKS.md rows and writes them with every run to bench/results/fields_<parts>.md.

* fields: ``difficulty_spec(level, seed, robot)`` for seeds 0..N-1 of easy, medium and hard (sim.field_gen
  DIFFICULTIES), each with its own random pattern; the run's noise seed is the field's seed. A run counts when its
  pattern is completed (``pattern_completed``) with 0 plants touched (``plants_touched``: stems that were ever inside
  the footprint).
* time per lane: each lane driven in the pattern's order (from field.json's lanes: the footprint centre inside the
  lane, end to end) against its length at the navigator's lane speed (0.4 m/s; the RC car 0.457 m/s, 5 % over its
  speed table's least step); the turns are the times between lanes.
* proximity: curvy_row, world seeds 7..16 (``--worlds 10``; seed n: its bushes from world_seed 7 + n), the proximity
  follower, the distance from the row as planted (each bush's centre averaged over 3 m of row,
  sim.metrics.row_distance) and from the design line beside it, every sample past the first 2 m of travel; runner
  and SIL.
* floor: in the same worlds, how far the row as planted moves against what a laser sees of it (``_proximity_floor``).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
LEVELS = ("easy", "medium", "hard")
ROBOTS = ("diff_drive", "ackermann")


def _field_run(job: tuple[str, int, str, str]) -> dict[str, Any]:
    from agnav_host.sim.field_controllers import make_scenario_controller
    from agnav_host.sim.field_gen import difficulty_spec, generate_field
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import parse_scenario

    level, seed, robot, backend = job
    sc = parse_scenario(generate_field(difficulty_spec(level, seed, robot)), f"<{level} {seed} {robot}>")
    ctrl: Any = make_scenario_controller(sc, "row-navigator")
    speed = float(ctrl.params.follower.speed_m_s)
    t0 = time.perf_counter()
    if backend == "sil":
        from agnav_host.sil.session import run_sil_scenario

        run = run_sil_scenario(sc, "row-navigator", seed=seed).run
    else:
        run = run_scenario(sc, "row-navigator", seed=seed, controller=ctrl)
    wall = time.perf_counter() - t0
    m = run.metrics
    f = m.field_detail
    lanes = [(v.t_out_s - v.t_in_s) / (v.length_m / speed) for v in f.lanes] if f is not None else []
    turns = [b.t_in_s - a.t_out_s for a, b in zip(f.lanes, f.lanes[1:])] if f is not None else []
    assert sc.field is not None
    return {"level": level, "seed": seed, "robot": robot, "backend": backend, "pattern": sc.field.pattern,
            "end": run.end_reason, "rows": m.rows_completed, "expected": len(f.expected) if f is not None else 0,
            "completed": bool(m.pattern_completed), "touched": m.plants_touched, "score": m.field_score_m,
            "distance": m.field_distance_m, "time": m.field_time_s, "lane_ratio": lanes, "turns": turns,
            "speed": speed, "wall": wall}


def _proximity_run(job: tuple[int, str]) -> dict[str, Any]:
    from agnav_host.sim.metrics import row_distance
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import builtin_text, parse_scenario

    seed, backend = job
    text = builtin_text("curvy_row").replace("world_seed = 7", f"world_seed = {7 + seed}")
    sc = parse_scenario(text, f"<curvy_row world {7 + seed}>")
    if backend == "sil":
        from agnav_host.sil.session import run_sil_scenario

        run = run_sil_scenario(sc, "proximity", seed=seed).run
    else:
        run = run_scenario(sc, "proximity", seed=seed)
    tr = run.trajectory
    rd = row_distance(tr[:, 1], tr[:, 2], sc.world.row_lines, 1.0, plants=sc.world.row_plants)
    assert rd is not None
    pl = rd.planted()
    assert pl is not None
    return {"seed": seed, "backend": backend, "end": run.end_reason, "planted": pl,
            "design": {"mean_m": rd.mean_m, "min_m": rd.min_m, "max_m": rd.max_m, "within_band": rd.within}}


def _proximity_floor(seed: int) -> dict[str, Any]:
    """What a laser on the robot's side cannot see of the row as planted, in world ``seed``. Each plant is a cluster
    of circles; its planted position is the mean of their centres, while a laser at the robot's height sees the face
    of the nearest circle. The gap between the two varies from plant to plant; its mean over the metric's 3 m of row
    (less its mean over the row) moves the row as planted against anything a face follower can measure. Its range
    is a floor under the follower's range about 1 m, before any control error."""
    import numpy as np

    from agnav_host.sim.metrics import PLANTED_WINDOW_M, along_and_offset_m
    from agnav_host.sim.scenario import builtin_text, parse_scenario

    sc = parse_scenario(builtin_text("curvy_row").replace("world_seed = 7", f"world_seed = {7 + seed}"), "<curvy_row>")
    line = np.asarray(sc.world.row_lines[0], dtype=float)
    plants = np.asarray(sc.world.row_plants[0], dtype=float)
    circles = np.asarray(sc.world.circles, dtype=float)
    sp, npl = along_and_offset_m(plants[:, 0], plants[:, 1], line)
    sc_, nc = along_and_offset_m(circles[:, 0], circles[:, 1], line)
    side = -1.0 if sc.meta.get("follow_side", "right") == "right" else 1.0
    face = np.full(len(plants), -np.inf)  # how far each plant's nearest circle reaches towards the robot's side
    for i in range(len(circles)):
        j = int(np.argmin(np.hypot(sc_[i] - sp, nc[i] - npl)))
        face[j] = max(face[j], side * nc[i] + circles[i, 2])
    hidden = face - side * npl
    hidden -= hidden.mean()
    grid = np.arange(2.0, float(sp.max()) - 2.0, 0.05)
    win = np.array([hidden[np.abs(sp - s) <= 0.5 * PLANTED_WINDOW_M].mean() for s in grid])
    return {"seed": seed, "plant_sd_m": float(hidden.std()), "min_m": float(win.min()), "max_m": float(win.max()),
            "sd_m": float(win.std())}


def _pool(fn: Any, jobs: list[Any], n: int) -> list[Any]:
    if n <= 1:
        return [fn(j) for j in jobs]
    with ProcessPoolExecutor(n) as ex:
        return list(ex.map(fn, jobs))


def _field_rows(runs: list[dict[str, Any]], backend: str, cmd: str) -> list[str]:
    out = []
    for robot in ROBOTS:
        cells = []
        ok_all = True
        for level in LEVELS:
            rs = [r for r in runs if r["robot"] == robot and r["level"] == level and r["backend"] == backend]
            if not rs:
                continue
            ok = sum(r["completed"] and r["touched"] == 0 for r in rs)
            touched = sum(r["touched"] for r in rs)
            ok_all &= ok == len(rs)
            cells.append(f"{level} {ok}/{len(rs)} ({touched} plants touched)")
        if cells:
            n = len([r for r in runs if r["robot"] == robot and r["backend"] == backend]) // max(1, len(cells))
            out.append(f"| {n} generated fields per difficulty, {backend}, {robot}, row-navigator: pattern completed "
                       f"and 0 plants touched | {'; '.join(cells)} | every field | {'yes' if ok_all else '**no**'} | "
                       f"`{cmd}` |")
    return out


def _time_rows(runs: list[dict[str, Any]], backend: str, cmd: str) -> list[str]:
    out = []
    for robot in ROBOTS:
        rs = [r for r in runs if r["robot"] == robot and r["backend"] == backend]
        ratios = [x for r in rs for x in r["lane_ratio"]]
        turns = [x for r in rs for x in r["turns"]]
        if not ratios:
            continue
        over = sum(x > 1.10 for x in ratios)
        out.append(f"| time per lane against its length at the lane speed ({rs[0]['speed']:.3g} m/s), {backend}, "
                   f"{robot}, {len(ratios)} lanes | median {statistics.median(ratios):.3f}, worst {max(ratios):.3f}; "
                   f"{over} over 1.10. Turns between lanes: median {statistics.median(turns):.1f} s, "
                   f"{min(turns):.1f}-{max(turns):.1f} s | <= 1.10 | {'yes' if over == 0 else '**no**'} | `{cmd}` |")
    return out


def _detail(runs: list[dict[str, Any]]) -> list[str]:
    lines = ["| level | robot | backend | seed | pattern | end | lanes | plants touched | distance m | time s | "
             "score m | worst lane ratio | wall s |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        worst = max(r["lane_ratio"]) if r["lane_ratio"] else float("nan")
        lines.append(f"| {r['level']} | {r['robot']} | {r['backend']} | {r['seed']} | {r['pattern']} | {r['end']} | "
                     f"{r['rows']}/{r['expected']} | {r['touched']} | {r['distance']:.1f} | {r['time']:.1f} | "
                     f"{r['score']:.1f} | {worst:.3f} | {r['wall']:.0f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="runner,sil,proximity,floor", help="runner, sil, proximity, floor (comma-separated)")
    ap.add_argument("--seeds", type=int, default=20, help="fields per difficulty and robot (default 20)")
    ap.add_argument("--sil-seeds", type=int, default=None, help="fields per difficulty in the SIL (default --seeds)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--worlds", type=int, default=10, help="proximity and floor: curvy_row worlds (default 10)")
    ap.add_argument("--out", default=None, help="the results file (default bench/results/fields_<only>.md)")
    a = ap.parse_args(argv)
    parts = {p.strip() for p in a.only.split(",") if p.strip()}
    runs: list[dict[str, Any]] = []
    table: list[str] = []
    cmd = "python bench/bench_fields.py"
    for backend in ("runner", "sil"):
        if backend not in parts:
            continue
        n = a.seeds if backend == "runner" or a.sil_seeds is None else a.sil_seeds
        jobs = [(lv, s, rb, backend) for lv in LEVELS for rb in ROBOTS for s in range(n)]
        t0 = time.perf_counter()
        got = _pool(_field_run, jobs, a.jobs)
        print(f"{backend}: {len(got)} runs in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        runs += got
        c = f".venv/bin/{cmd} --only {backend} --seeds {n}"
        table += _field_rows(got, backend, c) + _time_rows(got, backend, c)
    prox: list[dict[str, Any]] = []
    fl: list[dict[str, Any]] = []
    wcmd = "" if a.worlds == 10 else f" --worlds {a.worlds}"
    if "proximity" in parts:
        prox = _pool(_proximity_run, [(s, b) for b in ("runner", "sil") for s in range(a.worlds)], a.jobs)
        for b in ("runner", "sil"):
            ps = [p for p in prox if p["backend"] == b]
            lo = min(p["planted"]["min_m"] for p in ps)
            hi = max(p["planted"]["max_m"] for p in ps)
            dlo = min(p["design"]["min_m"] for p in ps)
            dhi = max(p["design"]["max_m"] for p in ps)
            means = [p["planted"]["mean_m"] for p in ps]
            inside = min(p["planted"]["within_band"] for p in ps)
            met = lo >= 0.95 and hi <= 1.05
            table.append(f"| proximity at 1 m on curvy_row (5 cm planting jitter), {a.worlds} worlds, {b}: distance from the row "
                         f"as planted (each bush's centre averaged over 3 m of row) | means {min(means):.3f}-"
                         f"{max(means):.3f} m, range {lo:.3f}-{hi:.3f} m, every world >= {100 * inside:.1f} % inside; "
                         f"from the design line beside it {dlo:.3f}-{dhi:.3f} m | 1 +- 0.05 m | "
                         f"{'yes' if met else '**no**'} | `.venv/bin/{cmd} --only proximity{wcmd}` |")
    if "floor" in parts:
        fl = [_proximity_floor(s) for s in range(a.worlds)]
        table.append(f"| the part of the row as planted a laser cannot see (each plant's nearest circle against the mean of its "
                     f"circles, over 3 m of row), {a.worlds} worlds of curvy_row: a floor under the follower's range "
                     f"about 1 m | per plant sd {1e3 * min(f['plant_sd_m'] for f in fl):.0f}-"
                     f"{1e3 * max(f['plant_sd_m'] for f in fl):.0f} mm; over 3 m of row "
                     f"{1e3 * min(f['min_m'] for f in fl):+.0f} to {1e3 * max(f['max_m'] for f in fl):+.0f} mm "
                     f"(sd {1e3 * min(f['sd_m'] for f in fl):.0f}-{1e3 * max(f['sd_m'] for f in fl):.0f} mm); worst world "
                     f"spread {1e3 * max(f['max_m'] - f['min_m'] for f in fl):.0f} mm of the band's 100 mm | - | - | "
                     f"`.venv/bin/{cmd} --only floor{wcmd}` |")
    print("| What | Figure | Target | Met | Command |\n|---|---|---|---|---|")
    print("\n".join(table))
    out = Path(a.out) if a.out else ROOT / "bench" / "results" / f"fields_{'_'.join(sorted(parts))}.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    text = ["# Whole fields", "", "`.venv/bin/python bench/bench_fields.py` (bench/bench_fields.py has what is run and "
            "how it is counted). Summary:", "", "| What | Figure | Target | Met | Command |", "|---|---|---|---|---|",
            *table, "", "Every run:", "", *(_detail(runs) if runs else ["(no field runs)"])]
    if prox:
        text += ["", "Proximity, per world:", "", "| backend | seed | end | planted mean | planted range | inside | "
                 "design-line range |", "|---|---|---|---|---|---|---|"]
        text += [f"| {p['backend']} | {p['seed']} | {p['end']} | {p['planted']['mean_m']:.3f} | "
                 f"{p['planted']['min_m']:.3f}-{p['planted']['max_m']:.3f} | {100 * p['planted']['within_band']:.1f} % | "
                 f"{p['design']['min_m']:.3f}-{p['design']['max_m']:.3f} |" for p in prox]
    if fl:
        text += ["", "What a laser cannot see of the row as planted, per world (over 3 m of row, less its mean):", "",
                 "| seed | per plant sd mm | over 3 m of row mm | sd mm |", "|---|---|---|---|"]
        text += [f"| {f['seed']} | {1e3 * f['plant_sd_m']:.1f} | {1e3 * f['min_m']:+.1f} to {1e3 * f['max_m']:+.1f} | "
                 f"{1e3 * f['sd_m']:.1f} |" for f in fl]
    out.write_text("\n".join(text) + "\n", encoding="utf-8")
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
