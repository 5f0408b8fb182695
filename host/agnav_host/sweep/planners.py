"""The planner benchmark's runs as sweep tasks: one (scenario, planner entry, seed) of
:data:`agnav_host.planning.bench.SUITE` each, the planners' wall-time backstops lifted
(:data:`agnav_host.sweep.yards.NO_WALL_BACKSTOPS`) so that a run does not depend on the machine's load.

The row holds the run's metrics; the compute time per step goes to the timings, and the thinned trajectory
and curvature that the plots draw are kept (as arrays) for the lowest seed of each scenario and planner, the
run the plots show.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from .storage import RunStore
from .tasks import Task

__all__ = ["RUN", "run", "tasks", "results"]

RUN = "agnav_host.sweep.planners:run"
#: Fields of the planner benchmark's result that are measured times (machine-dependent)
TIMING = ("step_median_ms", "step_p95_ms")


def run(spec: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """One run of the suite (:func:`agnav_host.planning.bench.run_case`)."""
    from ..planning.bench import run_case
    from .yards import NO_WALL_BACKSTOPS

    r = run_case((str(spec["scenario"]), str(spec["planner"]), seed), NO_WALL_BACKSTOPS)
    out = {k: v for k, v in r.items() if k not in ("scenario", "planner", "seed", "wall_s", "traj", "kappa") + TIMING}
    out["timing"] = {k: r[k] for k in TIMING}
    if spec.get("traces"):
        out["arrays"] = {"traj": r["traj"], "kappa": r["kappa"]}
    return out


def tasks(suite: Iterable[Any]) -> list[Task]:
    """Every run of ``suite`` (BenchCase items), in the suite's order; the lowest seed of each case keeps
    its traces for the plots."""
    return [Task(RUN, {"scenario": c.scenario, "planner": p, "firmware": "none", "traces": s == min(c.seeds)}, s)
            for c in suite for p in c.planners for s in c.seeds]


def results(rows: Sequence[Mapping[str, Any]], store: RunStore) -> list[dict[str, Any]]:
    """The rows as the benchmark's report reads them: with their timings, and their traces (or empty ones)."""
    out = []
    for r in rows:
        arrays = store.arrays(r["key"])
        res = {k: v for k, v in r.items() if k not in ("key", "task", "firmware", "traces")}
        res.update(store.timing(r["key"]))
        res["traj"] = arrays.get("traj", np.zeros((0, 4)))
        res["kappa"] = arrays.get("kappa", np.zeros(0))
        out.append(res)
    return out
