"""The benchmark scripts of a source checkout (``bench/*.py``) as sweep tasks.

The timed and perception benchmarks print their tables from their own loops (``bench/bench_timed.py``,
``bench/bench_perception.py``). ``agnav bench timed|perception`` runs a script's ``main`` with its run
functions handed to the sweep: each call of a run function becomes tasks (plain arguments in the spec, the
script's own hash too, so that an edited script never reuses a stored row), and the script prints what it
always prints from the results. A run's arrays (trajectories for the figures) are stored beside its row.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import importlib.util
import inspect
import sys
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

import numpy as np

__all__ = ["NoCheckout", "script", "script_digest", "encode", "decode", "TIMING_FIELDS", "stand_in", "run_script",
           "SCRIPT_SUITES", "scenario_sources"]


class NoCheckout(RuntimeError):
    """The benchmark script is not there: the package does not run from a source checkout."""


def _path(name: str) -> Path:
    from .._paths import CHECKOUT_ROOT

    if CHECKOUT_ROOT is None or not (CHECKOUT_ROOT / "bench" / f"{name}.py").is_file():
        raise NoCheckout(f"needs a source checkout of agnav (bench/{name}.py); this package is installed without one")
    return CHECKOUT_ROOT / "bench" / f"{name}.py"


def script(name: str) -> ModuleType:
    """The module of ``bench/NAME.py`` (loaded once per process, as ``NAME``)."""
    mod = sys.modules.get(name)
    if mod is not None and getattr(mod, "__file__", None) == str(_path(name)):
        return mod
    spec = importlib.util.spec_from_file_location(name, _path(name))
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def script_digest(name: str) -> str:
    """A short hash of ``bench/NAME.py``: part of its tasks' specs."""
    return hashlib.sha256(_path(name).read_bytes()).hexdigest()[:16]


#: Fields of a script's results that are measured times (machine-dependent): kept in the timings, not the row
TIMING_FIELDS = ("replan_times_s", "step_times_s", "replan_cpu_s")


def encode(value: Any, arrays: dict[str, np.ndarray], timing: dict[str, Any], path: str = "r") -> Any:
    """``value`` (a script's result: numbers, text, lists, tuples, dicts, dataclasses, numpy arrays) as plain
    values: every array of more than one element moved into ``arrays``, every :data:`TIMING_FIELDS` field of
    a dataclass into ``timing``, each replaced by a reference; tuples, dicts and dataclasses tagged so that
    :func:`decode` rebuilds them."""
    if isinstance(value, np.ndarray) and value.ndim > 0:
        arrays[path] = value
        return {"array": path}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {}
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            if f.name in TIMING_FIELDS:
                timing[f"{path}.{f.name}"] = [float(x) for x in v]
                fields[f.name] = {"timing": f"{path}.{f.name}"}
            else:
                fields[f.name] = encode(v, arrays, timing, f"{path}.{f.name}")
        cls = type(value)
        return {"dataclass": f"{cls.__module__}:{cls.__qualname__}", "fields": fields}
    if isinstance(value, (list, tuple)):
        items = [encode(v, arrays, timing, f"{path}.{i}") for i, v in enumerate(value)]
        return {"tuple": items} if isinstance(value, tuple) else items
    if isinstance(value, dict):
        return {"dict": {str(k): encode(v, arrays, timing, f"{path}.{k}") for k, v in value.items()}}
    return value


def _class(name: str) -> Any:
    module, _, qual = name.partition(":")
    mod = sys.modules.get(module)
    if mod is None:
        mod = script(module) if module.startswith("bench_") else importlib.import_module(module)
    obj: Any = mod
    for part in qual.split("."):
        obj = getattr(obj, part)
    return obj


def decode(value: Any, arrays: Callable[[], dict[str, np.ndarray]], timing: dict[str, Any]) -> Any:
    """The value :func:`encode` took apart; its arrays read with ``arrays()`` (called once, when one is
    needed), its measured times from ``timing``."""
    got: dict[str, np.ndarray] = {}

    def walk(v: Any) -> Any:
        if isinstance(v, dict):
            if set(v) == {"array"}:
                if not got:
                    got.update(arrays())
                return got[v["array"]]
            if set(v) == {"timing"}:
                return list(timing.get(v["timing"], []))
            if set(v) == {"tuple"}:
                return tuple(walk(x) for x in v["tuple"])
            if set(v) == {"dict"}:
                return {k: walk(x) for k, x in v["dict"].items()}
            if set(v) == {"dataclass", "fields"}:
                return _class(v["dataclass"])(**{k: walk(x) for k, x in v["fields"].items()})
            return {k: walk(x) for k, x in v.items()}
        if isinstance(v, list):
            return [walk(x) for x in v]
        return v

    return walk(value)


RUN = "agnav_host.sweep.scripts:run"
#: The run functions as the scripts define them, while a sweep stands in for them (a forked worker inherits
#: the stand-ins: it calls these)
_ORIGINAL: dict[tuple[str, str], Callable[..., Any]] = {}


def _module(name: str) -> ModuleType:
    return script(name) if name.startswith("bench_") else importlib.import_module(name)


def _scenario_from(mod: ModuleType, source: dict[str, str]) -> Any:
    from ..sim.scenario import load_scenario, parse_scenario

    if "builtin" in source:
        return load_scenario(source["builtin"])
    if "toml" in source:
        return parse_scenario(getattr(mod, source["toml"]))
    return parse_scenario(getattr(mod, source["toml_fn"])())


def scenario_sources(mod: ModuleType) -> dict[str, dict[str, str]]:
    """Where each scenario a script builds comes from, by scenario name: a TOML text the script holds (a
    constant, or a function ``*_toml()``) or a built-in scenario; what a worker rebuilds it from."""
    from ..sim.scenario import builtin_names, parse_scenario

    out: dict[str, dict[str, str]] = {n: {"builtin": n} for n in builtin_names()}
    for attr, v in list(vars(mod).items()):
        text, source = None, None
        if isinstance(v, str) and "[scenario]" in v:
            text, source = v, {"toml": attr}
        elif callable(v) and attr.endswith("_toml") and getattr(v, "__module__", None) == mod.__name__:
            try:
                text, source = v(), {"toml_fn": attr}
            except TypeError:  # takes arguments: not a fixed scenario
                continue
        if text is not None and source is not None:
            try:
                out[parse_scenario(text).name] = source
            except Exception:  # noqa: BLE001  (a fragment of a scenario, not one)
                continue
    return out


def _same(a: Any, b: Any) -> bool:
    """The same scenario (built the same way: the same pickled bytes)."""
    import pickle

    try:
        return pickle.dumps(a) == pickle.dumps(b)
    except Exception:  # noqa: BLE001  (something in it does not pickle: then it cannot go to a worker either)
        return False


def run(spec: Any, seed: int) -> dict[str, Any]:
    """One call of a script's run function: ``spec["call"]`` of ``spec["module"]`` with ``spec["args"]``
    (scenarios rebuilt from where the script builds them); the result as plain values, its arrays and its
    measured times apart."""
    name = spec["module"]
    mod = _module(name)
    if "digest" in spec and script_digest(name) != spec["digest"]:
        raise RuntimeError(f"bench/{name}.py changed while the sweep ran")
    f = _ORIGINAL.get((name, spec["call"])) or getattr(mod, spec["call"])
    args = decode(spec["args"], dict, {})
    for k, src in spec.get("scenarios", {}).items():
        args[k] = _scenario_from(mod, src)
    arrays: dict[str, np.ndarray] = {}
    timing: dict[str, Any] = {}
    res = f(**args)
    return {"result": encode(res, arrays, timing), "arrays": arrays, "timing": timing}


def stand_in(module: str, call: str, sweep: Callable[[list[Any]], list[dict[str, Any]]], store: Any,
             split: str | None = None) -> Callable[[], None]:
    """Put a sweep in the place of ``module.call``: each call becomes tasks (one per item of the argument
    ``split``, their results joined: lists end to end, dicts merged; without ``split``, one task) and returns
    what the function returns. A call whose scenario the worker cannot rebuild (see :func:`scenario_sources`)
    runs here as before. Returns the function that puts the original back."""
    from ..sim.scenario import Scenario
    from .runners import SweepFailed
    from .tasks import Task

    mod = _module(module)
    orig = getattr(mod, call)
    _ORIGINAL[(module, call)] = orig
    sig = inspect.signature(orig)
    sources = scenario_sources(mod)
    digest = {"digest": script_digest(module)} if module.startswith("bench_") else {}

    def call_through_sweep(*a: Any, **kw: Any) -> Any:
        bound = sig.bind(*a, **kw)
        bound.apply_defaults()
        args = dict(bound.arguments)
        scen = {}
        for k, v in list(args.items()):
            if isinstance(v, Scenario):
                src = sources.get(v.name)
                if src is None or not _same(v, _scenario_from(mod, src)):
                    return orig(*a, **kw)
                scen[k] = src
                del args[k]
        groups = [args] if split is None else [{**args, split: type(args[split])([x])} for x in args[split]]
        tasks = []
        for g in groups:
            spec = {"module": module, **digest, "call": call, "args": encode(g, {}, {}), "scenarios": scen}
            s = g.get("seed", g.get(split, [0])[0] if split else 0)
            tasks.append(Task(RUN, spec, int(s) if isinstance(s, (int, np.integer)) else 0))
        try:
            rows = sweep(tasks)
        except SweepFailed as e:  # the script sees its run function's own error, as without a sweep
            raise (e.error if isinstance(e.error, Exception) else e) from None
        results = [decode(r["result"], functools.partial(store.arrays, r["key"]), store.timing(r["key"])) for r in rows]
        if split is None:
            return results[0]
        if all(isinstance(r, dict) for r in results):
            return {k: v for r in results for k, v in r.items()}
        return [x for r in results for x in r]

    call_through_sweep.__wrapped__ = orig  # type: ignore[attr-defined]
    setattr(mod, call, call_through_sweep)

    def restore() -> None:
        setattr(mod, call, orig)
        _ORIGINAL.pop((module, call), None)

    return restore


#: The suites run from a script: the script, and its run functions a sweep stands in for (module, function,
#: the argument split into one task per item or None)
SCRIPT_SUITES: dict[str, tuple[str, tuple[tuple[str, str, str | None], ...]]] = {
    "timed": ("bench_timed", (("bench_timed", "run_single", None), ("bench_timed", "run_multi", None),
                              ("bench_timed", "run_sil", None), ("agnav_host.sil.fleet", "run_fleet", None))),
    "perception": ("bench_perception", (("bench_perception", "bench_rows", "methods"),
                                        ("bench_perception", "bench_proximity", "seeds"),
                                        ("bench_perception", "bench_holes", "seeds"),
                                        ("bench_perception", "bench_ruts", "seeds"),
                                        ("bench_perception", "bench_hole_field", "seeds"))),
}


def run_script(suite: str, argv: list[str], sweep: Callable[[list[Any]], list[dict[str, Any]]], store: Any) -> int:
    """The ``main(argv)`` of the suite's script (:data:`SCRIPT_SUITES`) with its run functions going through
    ``sweep`` (rows and arrays read back from ``store``); its exit code. The script's functions are its own
    again afterwards."""
    name, calls = SCRIPT_SUITES[suite]
    mod = script(name)
    restores = []
    try:
        for module, call, split in calls:
            restores.append(stand_in(module, call, sweep, store, split))
        return int(mod.main(argv) or 0)
    finally:
        for r in reversed(restores):
            r()
