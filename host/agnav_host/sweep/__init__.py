"""Benchmark sweeps: many pure runs, on local processes or a Ray cluster, stored as each run ends.

A run is a :class:`Task`: ``run(spec, seed) -> metrics``, a function named by ``module:function`` and a spec
of plain values (the scenario or generator parameters, the planner and its parameters, the robot, the firmware
mode). :func:`run_sweep` runs a list of them on a back end (:class:`LocalBackend`, ``--jobs N``;
:class:`RayBackend`, ``--ray local|auto|ADDRESS``) and appends one JSON line per finished run to
``OUT/runs.jsonl`` (:class:`RunStore`), so that a killed sweep resumes where it stopped. A row holds the
spec, the seed, the metrics and ``wall_s``; it is the same on every back end and any number of workers (the
seeds belong to the tasks). Measured compute times go to ``OUT/timings.jsonl`` and arrays for plots to
``OUT/arrays/KEY.npz``, beside the rows. The suites (:mod:`.yards`, :mod:`.planners`, :mod:`.timed`,
:mod:`.perception`) build their tasks and their tables; ``agnav bench SUITE`` runs them. docs/sweeps.md.
"""

from __future__ import annotations

from .runners import (Backend, LocalBackend, Progress, RayBackend, RayMissing, RayUnreachable, SweepFailed, make_backend,
                      run_sweep)
from .storage import RunStore
from .tasks import Outcome, Task, code_digest, execute, task_key

__all__ = ["Task", "Outcome", "execute", "task_key", "code_digest", "RunStore", "Backend", "LocalBackend",
           "RayBackend", "RayMissing", "RayUnreachable", "SweepFailed", "Progress", "make_backend", "run_sweep"]
