"""Pure tasks: one benchmark run is ``run(spec, seed) -> dict``, named by ``module:function``.

The function returns its metrics as a dict of plain values (numbers, text, booleans, lists, dicts). Two keys
are kept apart from the row: ``"timing"``, the machine-dependent measurements (compute time per step,
replanning wall times: they differ between two runs of the same task), and ``"arrays"``, numpy arrays for the
plots (a trajectory). Everything else is the task's result and must depend on nothing but the spec and the
seed: no clock, no global random state, no worker number.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import time
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Callable, Mapping

import numpy as np

__all__ = ["Task", "Outcome", "execute", "task_key", "code_digest", "plain", "row_of", "same_results", "RESERVED"]

#: Row fields the runner writes itself: a spec or a result may not use them
RESERVED = ("key", "task", "seed", "wall_s")


@dataclass(frozen=True)
class Task:
    """One run: ``fn`` ("package.module:function") called as ``fn(spec, seed)``.

    ``spec`` holds plain values only (it is hashed into the run's key and copied into its row)."""

    fn: str
    spec: Mapping[str, Any]
    seed: int = 0

    @property
    def name(self) -> str:
        """The task's short name in the rows: the function's module and name, ``yards.run``."""
        module, _, func = self.fn.partition(":")
        return f"{module.rsplit('.', 1)[-1]}.{func}"


@dataclass
class Outcome:
    """What a worker sends back: the row's results, the measured times, the arrays, the run's wall time."""

    metrics: dict[str, Any]
    timing: dict[str, Any] = field(default_factory=dict)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    wall_s: float = 0.0


def plain(value: Any) -> Any:
    """``value`` as JSON reads it back: numpy scalars and arrays to Python numbers and lists, tuples to lists,
    dict keys to text. Raises TypeError for anything else (an object that JSON cannot hold)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    raise TypeError(f"a task's result must be plain values, got {type(value).__name__}")


def _canonical(value: Any) -> str:
    return json.dumps(plain(value), sort_keys=True, separators=(",", ":"), allow_nan=True)


@lru_cache(maxsize=1)
def code_digest() -> str:
    """A short hash of the code a run executes: the package's Python sources and data files, the sources the
    SIL builds (firmware, SIL harness, MAVLink dialect), the numpy version. Part of every run's key, so that
    a sweep never reuses a row that other code computed."""
    from .._paths import PACKAGE_DIR, SOURCE_ROOT, inputs_digest

    files = [p for p in PACKAGE_DIR.rglob("*") if p.suffix in (".py", ".toml", ".json", ".csv") and
             "__pycache__" not in p.parts]
    for sub in ("firmware/src", "firmware/lib", "hil/sil", "protocol"):
        if (SOURCE_ROOT / sub).is_dir():
            files += [p for p in (SOURCE_ROOT / sub).rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    return inputs_digest(sorted(files), extra=[f"numpy {np.__version__}"])


def task_key(task: Task, code: str | None = None) -> str:
    """The run's key: a hash of its function, spec, seed and :func:`code_digest` (or ``code``)."""
    text = _canonical({"fn": task.fn, "spec": task.spec, "seed": task.seed,
                       "code": code_digest() if code is None else code})
    return hashlib.sha256(text.encode()).hexdigest()[:20]


_FUNCTIONS: dict[str, Callable[[Mapping[str, Any], int], dict[str, Any]]] = {}


def _function(fn: str) -> Callable[[Mapping[str, Any], int], dict[str, Any]]:
    f = _FUNCTIONS.get(fn)
    if f is None:
        module, sep, name = fn.partition(":")
        if not sep or not module or not name:
            raise ValueError(f"a task names its function as 'module:function', got {fn!r}")
        f = getattr(importlib.import_module(module), name)
        _FUNCTIONS[fn] = f
    return f


def execute(task: Task) -> Outcome:
    """Run ``task`` here (in a worker); its result as plain values and its wall time."""
    f = _function(task.fn)
    t0 = time.perf_counter()
    out = dict(f(task.spec, task.seed))
    wall = time.perf_counter() - t0
    timing = plain(out.pop("timing", {}))
    arrays = {k: np.asarray(v) for k, v in out.pop("arrays", {}).items()}
    clash = [k for k in out if k in RESERVED or k in task.spec]
    if clash:
        raise ValueError(f"{task.fn}: result fields {', '.join(clash)} clash with the row's own or the spec's")
    return Outcome(plain(out), timing, arrays, wall)


def row_of(task: Task, key: str, outcome: Outcome) -> dict[str, Any]:
    """The stored row of a finished run: its key, task, spec, seed, results and wall time (JSON values)."""
    row: dict[str, Any] = {"key": key, "task": task.name, **plain(dict(task.spec)), "seed": task.seed,
                           **outcome.metrics, "wall_s": round(outcome.wall_s, 6)}
    stored: dict[str, Any] = json.loads(json.dumps(row, allow_nan=True))
    return stored


def same_results(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    """Two rows hold the same run and results, bit for bit (``wall_s`` aside; NaN equals NaN)."""
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in (a, b)]
    return _canonical(strip[0]) == _canonical(strip[1])
