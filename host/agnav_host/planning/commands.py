"""``agnav planners`` and ``agnav bench planners``: CLI wrappers around the registry and the benchmark.

``agnav bench`` exits 0 after a run, 1 when the output folder cannot be made or written, 2 for a bad
option (an unknown scenario or planner entry is named, with the known ones; an empty ``--scenarios`` or
``--planners``; a subset run without ``--out``).

The default output folder, ``bench/results/planners``, holds the whole suite's tables (committed): a subset
run (``--scenarios``, ``--planners`` or ``--seeds``) must name its own ``--out``. Before a run, the files a
previous run left in the folder (tables and plots) are removed, so that it never mixes two runs.
"""

from __future__ import annotations

import argparse
import sys
import time

from ..cli import clear_earlier_outputs, positive_int, subcommand, unusable_out_dir

__all__: list[str] = []

DEFAULT_OUT = "bench/results/planners"
#: What a run writes into its folder (write_report): removed before a run when an earlier one left them.
BENCH_OUTPUTS = ("runs.csv", "summary.csv", "planners.md", "paths_*.png", "speed_*.png", "curvature_*.png")


@subcommand("planners", help="list every controller (names for agnav sim / agnav run --planner) and the sensors each needs")
def _cmd_planners(ns: argparse.Namespace) -> int:
    from .registry import CONTROLLERS, WRAPPERS

    heads = {"planner": "planners:", "field": "field controllers (built from the field: --row-side, --row-offset, "
                                                "--row-method, --turns or [field] in the host config; a scenario's [meta] "
                                                "in agnav sim):", "stand-in": "stand-in:"}
    for kind, head in heads.items():
        print(head)
        for name, e in CONTROLLERS.items():
            if e.kind == kind:
                print(f"  {name:13s} {e.summary} [needs: {', '.join(e.sensors) or 'odometry only'}]")
    print("wrappers (NAME+WRAPPER, e.g. him+ground-guard):")
    for name, (summary, sensors) in WRAPPERS.items():
        print(f"  +{name:12s} {summary} [needs: {', '.join(sensors)}]")
    return 0


@subcommand(
    "bench",
    help="run a benchmark suite (planners: the reference experiments on every planner)",
    epilog="exit codes: 0 = done, 1 = the output folder cannot be made or written, 2 = a bad option",
    args=[
        (("suite",), {"choices": ["planners"], "help": "which benchmark"}),
        (("--out",), {"default": None,
                      "help": f"output folder (default {DEFAULT_OUT}, for the whole suite only: a run with --scenarios, "
                              "--planners or --seeds must name its own --out, so that it never replaces the suite's "
                              "committed tables); the tables and plots of an earlier run in it are removed first"}),
        (("--jobs",), {"type": positive_int, "default": None, "metavar": "N",
                       "help": "worker processes, >= 1 (default: all cores)"}),
        (("--scenarios",), {"default": None, "help": "comma-separated subset of the suite's scenarios"}),
        (("--planners",), {"default": None, "help": "comma-separated subset of planner entries (e.g. flb@0.3,him)"}),
        (("--seeds",), {"type": positive_int, "default": None, "metavar": "N",
                        "help": "use only the first N >= 1 seeds of each case (default: all)"}),
        (("--no-plot",), {"action": "store_true", "help": "skip the PNG plots"}),
        (("--quiet",), {"action": "store_true", "help": "no progress bar"}),
    ],
)
def _cmd_bench(ns: argparse.Namespace) -> int:
    from dataclasses import replace

    from .bench import SUITE, jobs_of, progress_bar, run_suite, workers, write_report

    suite = list(SUITE)
    for opt, value in (("--scenarios", ns.scenarios), ("--planners", ns.planners)):
        if value is not None and not [v for v in value.split(",") if v.strip()]:
            print(f"agnav bench: {opt} {value!r} names nothing; leave the option out to run the whole suite",
                  file=sys.stderr)
            return 2
    if ns.scenarios:
        want = [s.strip() for s in ns.scenarios.split(",") if s.strip()]
        unknown = [s for s in want if s not in {c.scenario for c in SUITE}]
        if unknown:
            print(f"agnav bench: unknown scenario(s) {', '.join(unknown)}; suite: {', '.join(c.scenario for c in SUITE)}", file=sys.stderr)
            return 2
        suite = [c for c in suite if c.scenario in want]
    if ns.planners:
        want_p = {p.strip() for p in ns.planners.split(",") if p.strip()}
        known_p = sorted({p for c in SUITE for p in c.planners})
        unknown_p = sorted(want_p - set(known_p))
        if unknown_p or not want_p:
            what = f"unknown planner entr{'y' if len(unknown_p) == 1 else 'ies'} {', '.join(unknown_p)}" if unknown_p \
                else "no planner entry given"
            print(f"agnav bench: {what}; known: {', '.join(known_p)}", file=sys.stderr)
            return 2
        if not any(p in want_p for c in suite for p in c.planners):
            print(f"agnav bench: the chosen scenarios run none of {', '.join(sorted(want_p))}; they run: "
                  f"{', '.join(sorted({p for c in suite for p in c.planners}))}", file=sys.stderr)
            return 2
        suite = [replace(c, planners=tuple(p for p in c.planners if p in want_p)) for c in suite]
        suite = [c for c in suite if c.planners]
    if ns.seeds is not None:
        suite = [replace(c, seeds=c.seeds[: ns.seeds]) for c in suite]
    if not suite:
        print("agnav bench: nothing to run", file=sys.stderr)
        return 2
    if ns.out is None and (ns.scenarios is not None or ns.planners is not None or ns.seeds is not None):
        print(f"agnav bench: a subset run (--scenarios, --planners or --seeds) needs --out: the default {DEFAULT_OUT} "
              "holds the whole suite's tables", file=sys.stderr)
        return 2
    out = DEFAULT_OUT if ns.out is None else ns.out
    bad_out = unusable_out_dir(out) or clear_earlier_outputs("bench", out, BENCH_OUTPUTS, ns.quiet)
    if bad_out:  # before the run, so that a long run is not lost to a typo
        print(f"agnav bench: --out {out}: {bad_out}", file=sys.stderr)
        return 1
    if not ns.quiet:  # the bar moves only when a run ends: say at once what is under way
        n_runs = len(jobs_of(suite))
        print(f"agnav bench: {n_runs} runs on {workers(ns.jobs, n_runs)} worker(s), results to {out}",
              file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    results = run_suite(suite, ns.jobs, None if ns.quiet else progress_bar)
    wall = time.perf_counter() - t0
    cmd = f"agnav bench planners --out {out}" + (f" --jobs {ns.jobs}" if ns.jobs else "") + \
        (f" --scenarios {ns.scenarios}" if ns.scenarios else "") + (f" --planners {ns.planners}" if ns.planners else "") + \
        (f" --seeds {ns.seeds}" if ns.seeds is not None else "")
    try:
        paths = write_report(results, out, cmd, wall, plots=not ns.no_plot)
    except OSError as e:  # disk full, folder removed or made read-only during the run
        from ..cli import _report_write_failure

        return _report_write_failure("bench", out, e)
    print(f"{len(results)} runs in {wall:.0f} s; wrote {len(paths)} files to {out}")
    return 0
