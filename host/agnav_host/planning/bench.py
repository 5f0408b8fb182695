"""The planner benchmark: the reference experiments as simulator runs, in parallel, with tables and plots.

``agnav bench planners --out DIR`` (or ``bench/bench_planners.py``) runs :data:`SUITE` as a sweep (local
processes or Ray, :mod:`agnav_host.sweep`), shows a progress bar on stderr and writes to DIR:

``runs.jsonl``    one JSON row per run as it ends (beside it ``timings.jsonl`` and ``arrays/``): a killed run
                  resumes where it stopped
``runs.csv``      one row per run (scenario, planner, seed, metrics, compute time per step)
``summary.csv``   one row per scenario and planner (success rate, means, medians)
``planners.md``   the summary as markdown tables plus the reference figures next to ours
``paths_<scenario>.png``, ``speed_<scenario>.png``, ``curvature_<scenario>.png`` (matplotlib)

A planner entry may carry parameters after ``@``: ``flb@0.3`` is FLB with Trsh = 0.3.
"""

from __future__ import annotations

import csv
import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

__all__ = ["SUITE", "BenchCase", "run_case", "run_suite", "write_report", "REFERENCE"]

ALL = ("flb", "him", "vfh", "pbf", "apf", "subsumption", "follow-path")


@dataclass(frozen=True)
class BenchCase:
    scenario: str
    planners: tuple[str, ...]
    seeds: tuple[int, ...]
    group: str  # which reference experiment it stands for


SUITE: tuple[BenchCase, ...] = (
    BenchCase("corridor_obstacles", ALL, (0, 1, 2, 3, 4), "ref 002 corridor (experiment I)"),
    BenchCase("canyon", ALL, (0, 1, 2), "ref 002 dead-end canyon"),
    BenchCase("flb_setup1", ("flb@0.6", "flb@0.3", "pbf", "vfh", "him"), (0, 1, 2), "ref 000 FLB/PBF/VFH comparison"),
    BenchCase("flb_setup2", ("flb@0.6", "flb@0.3", "pbf", "vfh", "him"), (0, 1, 2), "ref 000 FLB/PBF/VFH comparison"),
    BenchCase("flb_setup3", ("flb@0.6", "flb@0.3", "pbf", "vfh", "him"), (0, 1, 2), "ref 000 FLB/PBF/VFH comparison"),
    BenchCase("him_setup1", ("flb", "him", "vfh", "pbf"), (0, 1, 2), "ref 000 FLB vs HIM, set-up 1"),
    BenchCase("him_wall", ("flb", "him", "vfh", "pbf"), (0, 1, 2), "ref 000 FLB vs HIM, high-speed wall"),
    BenchCase("him_moving", ("flb", "him", "vfh", "pbf"), (0, 1, 2), "ref 000 FLB vs HIM, moving person"),
    BenchCase("greenhouse_shuttle", ALL, (0, 1), "ref 001 waypoints 0-1-2-3-2-0"),
    BenchCase("greenhouse_cycles", ALL, (0,), "ref 001 ten cycles 0-2-3-4-0"),
)

#: Reference figures quoted by the issue (ref 000 tables 1-I / 3-III; BE x 1e-2 is the mean over ten set-ups).
REFERENCE = {
    "flb_pbf_vfh": "ref 000 (mean of 10 set-ups): PL cm FLB 540.5, PBF 521.4, VFH 499.8; BE x1e-2 FLB 0.86 (Trsh 0.6) / 0.34 (Trsh 0.3), PBF 10.0, VFH 6.15",
    "him_setup1": "ref 000 experiment set-up 1: FLB 4.500 m / 82.28 s, HIM 4.465 m / 64.00 s",
    "him_wall": "ref 000 high-speed test: FLB 7.223 m / 78.75 s, HIM 6.866 m / 55.46 s",
    "him_moving": "ref 000 moving obstacle: FLB 10.35 m / 125.9 s, HIM 7.038 m / 54.56 s",
}


def _split(entry: str) -> tuple[str, dict[str, Any] | None]:
    if "@" in entry:
        name, arg = entry.split("@", 1)
        if name == "flb":
            return name, {"trsh": float(arg)}
        raise ValueError(f"no parameter shorthand for {name!r}")
    return entry, None


def run_case(job: tuple[str, str, int], planner_params: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Run one (scenario, planner entry, seed); returns the metrics and a thinned trajectory.
    ``planner_params``: {planner: {parameter: value}} over the scenario's (the entry's own still win)."""
    from ..sim.metrics import menger_curvature, resample_path
    from ..sim.runner import run_scenario
    from ..sim.scenario import load_scenario

    scenario, entry, seed = job
    sc = load_scenario(scenario)
    name, params = _split(entry)
    extra = {k: dict(v) for k, v in (planner_params or {}).items()}
    if params is not None:
        extra[name] = {**extra.get(name, {}), **params}
    if extra:
        table = {k: dict(v) for k, v in sc.meta.get("planner_params", {}).items()}
        for k, v in extra.items():
            table[k] = {**table.get(k, {}), **v}
        sc = replace(sc, meta={**sc.meta, "planner_params": table})
    t0 = time.perf_counter()
    r = run_scenario(sc, name, seed)
    wall = time.perf_counter() - t0
    m = r.metrics
    st = r.step_times_s
    tr = r.trajectory
    keep = tr[:: max(1, len(tr) // 1500)]
    xy = resample_path(tr[:, 1:3], 0.05)
    kappa = menger_curvature(xy) if len(xy) >= 3 else np.zeros(0)
    return {
        "scenario": scenario, "planner": entry, "seed": seed, "end": r.end_reason, "success": m.success,
        "time_s": m.time_s, "path_length_m": m.path_length_m, "bending_energy": m.bending_energy,
        "min_clearance_m": m.min_clearance_m, "stops": m.stops, "heading_oscillations": m.heading_oscillations,
        "reversals": m.reversals,
        "step_median_ms": float(np.median(st) * 1e3) if len(st) else math.nan,
        "step_p95_ms": float(np.percentile(st, 95) * 1e3) if len(st) else math.nan,
        "wall_s": wall, "traj": keep[:, [0, 1, 2, 4]], "kappa": kappa,
    }


def jobs_of(suite: Iterable[BenchCase]) -> list[tuple[str, str, int]]:
    return [(c.scenario, p, s) for c in suite for p in c.planners for s in c.seeds]


def workers(processes: int | None, n_jobs: int) -> int:
    """How many worker processes a suite of ``n_jobs`` runs on: ``processes`` (default: all cores), never more
    than the jobs, so ``--jobs 100000`` does not start 100,000 processes."""
    return max(1, min(processes or os.cpu_count() or 1, n_jobs))


def run_suite(suite: Iterable[BenchCase] = SUITE, processes: int | None = None,
              progress: Callable[[int, int, dict[str, Any]], None] | None = None, backend: Any = None,
              store: Any = None, sweep_progress: Callable[[Any], None] | None = None) -> list[dict[str, Any]]:
    """Run every job of ``suite`` as a sweep (:mod:`agnav_host.sweep`) on ``backend`` (default: :func:`workers`
    local processes), the rows kept in ``store`` (a :class:`~agnav_host.sweep.RunStore`; default: in memory,
    so nothing resumes); results in job order. ``progress(done, total, row)`` or ``sweep_progress(Progress)``
    (with the rate and the time left) as each run ends."""
    from ..sweep import LocalBackend, RunStore, run_sweep
    from ..sweep.planners import results, tasks

    tasks_ = tasks(suite)
    # longest jobs first so the workers end together
    order = sorted(range(len(tasks_)), key=lambda i: (tasks_[i].spec["scenario"] != "greenhouse_cycles",
                                                      tasks_[i].spec["planner"] != "subsumption"))
    store = store if store is not None else RunStore(None)
    backend = backend if backend is not None else LocalBackend(workers(processes, len(tasks_)))
    show = sweep_progress if progress is None else (lambda p: progress(p.done, p.total, p.row))
    rows = run_sweep(tasks_, backend, store, show, order)
    return results(rows, store)


RUN_FIELDS = ("scenario", "planner", "seed", "end", "success", "time_s", "path_length_m", "bending_energy", "min_clearance_m",
              "stops", "heading_oscillations", "reversals", "step_median_ms", "step_p95_ms", "wall_s")
SUMMARY_FIELDS = ("scenario", "planner", "runs", "success_rate", "time_s", "path_length_m", "bending_energy",
                  "min_clearance_m", "stops", "step_median_ms")


def summarise(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (scenario, planner): success rate; means over successful runs (all runs when none succeeded)
    of time, length, bending energy and stops; the smallest clearance; the median step time."""
    keys: list[tuple[str, str]] = []
    for r in results:
        if (r["scenario"], r["planner"]) not in keys:
            keys.append((r["scenario"], r["planner"]))
    rows = []
    for sc, pl in keys:
        rs = [r for r in results if r["scenario"] == sc and r["planner"] == pl]
        ok = [r for r in rs if r["success"]] or rs
        rows.append({
            "scenario": sc, "planner": pl, "runs": len(rs), "success_rate": sum(r["success"] for r in rs) / len(rs),
            "time_s": float(np.mean([r["time_s"] for r in ok])),
            "path_length_m": float(np.mean([r["path_length_m"] for r in ok])),
            "bending_energy": float(np.mean([r["bending_energy"] for r in ok])),
            "min_clearance_m": float(min(r["min_clearance_m"] for r in rs if r["min_clearance_m"] is not None)),
            "stops": float(np.mean([r["stops"] for r in ok])),
            "step_median_ms": float(np.median([r["step_median_ms"] for r in rs])),
        })
    return rows


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3f}" if abs(v) < 100 else f"{v:.1f}"
    return str(v)


def write_report(results: list[dict[str, Any]], out_dir: str | Path, command: str = "", wall_s: float | None = None,
                 plots: bool = True) -> list[Path]:
    """Write runs.csv, summary.csv, planners.md and (matplotlib permitting) the plots; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    with open(out / "runs.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(RUN_FIELDS)
        for r in results:
            w.writerow([_fmt(r[k]) for k in RUN_FIELDS])
    written.append(out / "runs.csv")
    summ = summarise(results)
    with open(out / "summary.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(SUMMARY_FIELDS)
        for s in summ:
            w.writerow([_fmt(s[k]) for k in SUMMARY_FIELDS])
    written.append(out / "summary.csv")
    lines = ["# Planner benchmark", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    if wall_s is not None:
        lines += [f"{len(results)} runs, {wall_s:.0f} s wall clock on {os.cpu_count()} cores.", ""]
    lines += ["Means over successful runs (all runs when none succeeded); clearance is the smallest of all runs;",
              "bending energy is AgNav's integral form (sum kappa^2 ds, 1/m), not ref 000's plain sum.", ""]
    for sc in dict.fromkeys(s["scenario"] for s in summ):
        group = next((c.group for c in SUITE if c.scenario == sc), "")
        lines += [f"## {sc}" + (f" ({group})" if group else ""), ""]
        ref = REFERENCE.get(sc) or (REFERENCE["flb_pbf_vfh"] if sc.startswith("flb_setup") else None)
        if ref:
            lines += [f"Reference: {ref}", ""]
        lines += ["| planner | runs | success | time s | length m | bending energy | min clearance m | stops | step ms (median) |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for s in summ:
            if s["scenario"] == sc:
                lines.append(f"| {s['planner']} | {s['runs']} | {100 * s['success_rate']:.0f} % | {s['time_s']:.1f} | "
                             f"{s['path_length_m']:.2f} | {s['bending_energy']:.3f} | {s['min_clearance_m']:.3f} | "
                             f"{s['stops']:.1f} | {s['step_median_ms']:.3f} |")
        lines.append("")
    steps: dict[str, list[float]] = {}
    for r in results:
        steps.setdefault(r["planner"].split("@")[0], []).append(r["step_median_ms"])
    lines += ["## Compute time per step (median over runs of the per-run median, ms)", "", "| planner | median | worst run |", "|---|---|---|"]
    for pl, v in steps.items():
        lines.append(f"| {pl} | {float(np.median(v)):.3f} | {float(np.max(v)):.3f} |")
    lines.append("")
    (out / "planners.md").write_text("\n".join(lines), encoding="utf-8")
    written.append(out / "planners.md")
    if plots:
        written += _plots(results, out)
    return written


def _plots(results: list[dict[str, Any]], out: Path) -> list[Path]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    from ..sim.scenario import load_scenario
    from ..viz.world_plot import draw_goals, draw_world

    paths = []
    for sc_name in dict.fromkeys(r["scenario"] for r in results):
        rs = [r for r in results if r["scenario"] == sc_name]
        first: dict[str, dict[str, Any]] = {}
        for r in rs:  # the lowest seed of each planner
            if r["planner"] not in first or r["seed"] < first[r["planner"]]["seed"]:
                first[r["planner"]] = r
        sc = load_scenario(sc_name)
        fig, ax = plt.subplots(figsize=(7, 6))
        draw_world(ax, sc, legend_entries=False)
        draw_goals(ax, sc.goals, sc.start)
        for pl, r in first.items():
            ax.plot(r["traj"][:, 1], r["traj"][:, 2], lw=1.2, label=f"{pl} ({r['end']})", zorder=4)
        ax.set_title(f"{sc_name}: paths (seed {min(r['seed'] for r in rs)})")
        ax.legend(fontsize=7, loc="best")
        p = out / f"paths_{sc_name}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for pl, r in first.items():
            ax.plot(r["traj"][:, 0], r["traj"][:, 3], lw=1, label=pl)
        ax.set_xlabel("t, s")
        ax.set_ylabel("speed, m/s")
        ax.legend(fontsize=7)
        ax.set_title(f"{sc_name}: speed")
        p = out / f"speed_{sc_name}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for pl, r in first.items():
            k = r["kappa"]
            ax.plot(0.05 * np.arange(len(k)), np.minimum(k, 10.0), lw=0.8, label=pl)
        ax.set_xlabel("arc length, m")
        ax.set_ylabel("curvature, 1/m (clipped at 10)")
        ax.legend(fontsize=7)
        ax.set_title(f"{sc_name}: curvature")
        p = out / f"curvature_{sc_name}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
    return paths
