"""``agnav planners`` and ``agnav bench planners``: CLI wrappers around the registry and the benchmark."""

from __future__ import annotations

import argparse
import sys
import time

from ..cli import subcommand

__all__: list[str] = []


@subcommand("planners", help="list the host planners and perception controllers (names for agnav sim --planner)")
def _cmd_planners(ns: argparse.Namespace) -> int:
    from .registry import describe

    from ..sim.field_controllers import FIELD_CONTROLLERS, GUARD_SUFFIX

    for name, summary in describe().items():
        print(f"{name:13s} {summary}")
    print("perception controllers (agnav sim only: built from the scenario's field and [meta]):")
    for name, summary in FIELD_CONTROLLERS.items():
        print(f"{name:13s} {summary}")
    print(f"(any name{GUARD_SUFFIX}: the same with the tilted laser's holes and steps as obstacles; goal_seek = the "
          "simulator's stand-in)")
    return 0


@subcommand(
    "bench",
    help="run a benchmark suite (planners: the reference experiments on every planner)",
    args=[
        (("suite",), {"choices": ["planners"], "help": "which benchmark"}),
        (("--out",), {"default": "bench/results/planners", "help": "output folder (default bench/results/planners)"}),
        (("--jobs",), {"type": int, "default": None, "help": "worker processes (default: all cores)"}),
        (("--scenarios",), {"default": None, "help": "comma-separated subset of the suite's scenarios"}),
        (("--planners",), {"default": None, "help": "comma-separated subset of planner entries (e.g. flb@0.3,him)"}),
        (("--seeds",), {"type": int, "default": None, "help": "use only the first N seeds of each case"}),
        (("--no-plot",), {"action": "store_true", "help": "skip the PNG plots"}),
        (("--quiet",), {"action": "store_true", "help": "no progress bar"}),
    ],
)
def _cmd_bench(ns: argparse.Namespace) -> int:
    from dataclasses import replace

    from .bench import SUITE, progress_bar, run_suite, write_report

    suite = list(SUITE)
    if ns.scenarios:
        want = [s.strip() for s in ns.scenarios.split(",") if s.strip()]
        unknown = [s for s in want if s not in {c.scenario for c in SUITE}]
        if unknown:
            print(f"agnav bench: unknown scenario(s) {', '.join(unknown)}; suite: {', '.join(c.scenario for c in SUITE)}", file=sys.stderr)
            return 2
        suite = [c for c in suite if c.scenario in want]
    if ns.planners:
        want_p = {p.strip() for p in ns.planners.split(",") if p.strip()}
        suite = [replace(c, planners=tuple(p for p in c.planners if p in want_p)) for c in suite]
        suite = [c for c in suite if c.planners]
    if ns.seeds is not None:
        suite = [replace(c, seeds=c.seeds[: max(1, ns.seeds)]) for c in suite]
    if not suite:
        print("agnav bench: nothing to run", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    results = run_suite(suite, ns.jobs, None if ns.quiet else progress_bar)
    wall = time.perf_counter() - t0
    cmd = f"agnav bench planners --out {ns.out}" + (f" --jobs {ns.jobs}" if ns.jobs else "") + \
        (f" --scenarios {ns.scenarios}" if ns.scenarios else "") + (f" --planners {ns.planners}" if ns.planners else "") + \
        (f" --seeds {ns.seeds}" if ns.seeds is not None else "")
    paths = write_report(results, ns.out, cmd, wall, plots=not ns.no_plot)
    print(f"{len(results)} runs in {wall:.0f} s; wrote {len(paths)} files to {ns.out}")
    return 0
