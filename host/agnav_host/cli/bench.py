"""``agnav bench SUITE``: the benchmark suites as sweeps (:mod:`agnav_host.sweep`), on local worker processes
(``--jobs N``, the default) or a Ray cluster (``--ray local|auto|ADDRESS``, ``pip install agnav[ray]``).

* ``yards``: every planner in random cluttered yards (``--yards N --first K --planners a,b --robot
  diff|ackermann --walkers N --timed --seeds N``); the tables on stdout.
* ``planners``: the reference experiments on every planner; tables and plots to ``--out`` (default
  ``bench/results/planners``, the committed tables: a subset run, ``--scenarios``, ``--planners`` or
  ``--seeds``, names its own ``--out``; the tables and plots an earlier run left there are removed first).
* ``timed``: the time-critical planner (ref 003), single robots, three robots, the firmware SIL; tables on
  stdout.
* ``perception``: row and proximity following, holes, ruts, latency; tables on stdout, figures to ``--plots``.

With ``--out DIR`` every run's row is appended to ``DIR/runs.jsonl`` as it ends and the tables are built from
the stored rows: the same command again (after a kill, or with more yards) reruns only the runs that are not
stored; ``--fresh`` starts over. Exit codes: 0 done, 1 a run failed or the output folder cannot be written, 2 a
bad option (an unknown planner or scenario is named with the known ones; ``--ray`` without Ray installed),
130 interrupted (the finished runs stay stored).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Callable

from .argtypes import nonneg_int, positive_int
from .outputs import clear_earlier_outputs, report_write_failure, unusable_out_dir
from .progress import ProgressLine, bar
from .registry import subcommand

__all__: list[str] = []

SUITES = ("yards", "planners", "timed", "perception")
PLANNERS_OUT = "bench/results/planners"
#: What a planners run writes into its folder (write_report): removed before a run when an earlier one left them.
BENCH_OUTPUTS = ("runs.csv", "summary.csv", "planners.md", "paths_*.png", "speed_*.png", "curvature_*.png")
EXIT_INTERRUPTED = 130

#: The options of one suite only (the others are for all): option -> suites
ONLY_FOR = {
    "--yards": ("yards",), "--first": ("yards",), "--robot": ("yards",), "--walkers": ("yards",),
    "--timed": ("yards",), "--mover-horizon": ("yards",),
    "--planners": ("yards", "planners"), "--seeds": ("yards", "planners", "timed"),
    "--scenarios": ("planners",), "--no-plot": ("planners", "perception"),
    "--quick": ("timed",), "--sil": ("timed",), "--multi": ("timed",), "--timing-repeats": ("timed",),
    "--goals": ("timed",), "--goals-only": ("timed",),
    "--only": ("perception",), "--methods": ("perception",), "--plots": ("perception",),
    "--row-jitter": ("perception",),
}


def _mover_horizon(text: str) -> float:
    from .argtypes import finite_float

    v = finite_float(text)
    if not 0.0 <= v <= 10.0:
        raise argparse.ArgumentTypeError(f"must be 0-10 s, got {text!r}")
    return v


def _row_jitter(text: str) -> float:
    from .argtypes import finite_float

    v = finite_float(text)
    if not 0.0 <= v <= 0.5:
        raise argparse.ArgumentTypeError(f"must be 0-0.5 m, got {text!r}")
    return v


@subcommand(
    "bench",
    help="run a benchmark suite as a sweep on local processes or Ray (yards, planners, timed, perception)",
    epilog="exit codes: 0 = done, 1 = a run failed or the output folder cannot be made or written, 2 = a bad "
           "option, 130 = interrupted (the finished runs stay in --out; the same command resumes)",
    args=[
        (("suite",), {"choices": list(SUITES), "help": "which benchmark"}),
        (("--out",), {"default": None, "metavar": "DIR",
                      "help": "store every run's row in DIR/runs.jsonl as it ends, build the tables from them and "
                              "resume from them (planners: tables and plots go there too, default "
                              f"{PLANNERS_OUT}, for the whole suite only; others: default none, nothing stored)"}),
        (("--jobs",), {"type": positive_int, "default": None, "metavar": "N",
                       "help": "local worker processes, >= 1 (default: yards 2, planners all cores, timed and "
                               "perception 1, so that their timing tables have the cores to themselves); with "
                               "--ray local: the cluster's CPUs"}),
        (("--ray",), {"default": None, "metavar": "local|auto|ADDRESS",
                      "help": "run on Ray (pip install agnav[ray]): local starts a cluster on 127.0.0.1 for the "
                              "run, auto joins this machine's cluster, or a cluster's address"}),
        (("--fresh",), {"action": "store_true", "help": "with --out: forget the stored runs and run everything"}),
        (("--quiet",), {"action": "store_true", "help": "no progress line"}),
        # yards
        (("--yards",), {"type": positive_int, "default": 100, "metavar": "N", "help": "yards: how many (default 100)"}),
        (("--first",), {"type": nonneg_int, "default": 0, "metavar": "K",
                        "help": "yards: number of the first yard (default 0; --first 100: a holdout set)"}),
        (("--robot",), {"choices": ["diff", "ackermann"], "default": "diff",
                        "help": "yards: diff, the 0.45 m differential drive (default); ackermann, the ref-003 RC car"}),
        (("--walkers",), {"type": nonneg_int, "default": 0, "metavar": "N",
                          "help": "yards: people pacing across each yard (default 0)"}),
        (("--timed",), {"action": "store_true", "help": "yards: give the goal an arrival time"}),
        (("--mover-horizon",), {"type": _mover_horizon, "default": 2.0, "metavar": "S",
                                "help": "yards, with --walkers: mover_horizon_s of the laser planners (default 2; "
                                        "0: they do not track people)"}),
        (("--planners",), {"default": None,
                           "help": "yards: comma-separated planners (entries such as flb@0.3 too; default every "
                                   "reactive planner, with --robot ackermann those that drive a car and timed); "
                                   "planners: a subset of the suite's entries"}),
        (("--seeds",), {"type": positive_int, "default": None, "metavar": "N",
                        "help": "yards: seeds 0..N-1 of every run (default 1); planners: the first N of each case "
                                "(default all); timed: seeds 0..N-1 (default 5)"}),
        # planners
        (("--scenarios",), {"default": None, "help": "planners: comma-separated subset of the suite's scenarios"}),
        (("--no-plot",), {"action": "store_true", "help": "planners, perception: skip the PNG plots"}),
        # timed
        (("--quick",), {"action": "store_true", "help": "timed: skip the 100 m ref-003 case"}),
        (("--sil",), {"action": "store_true", "help": "timed: only the firmware-in-the-loop sections"}),
        (("--multi",), {"action": "store_true", "help": "timed, with --sil: only the three-robot SIL fleet"}),
        (("--timing-repeats",), {"type": positive_int, "default": 3, "metavar": "N",
                                 "help": "timed: runs of the single and multi cases for the replanning times (default 3)"}),
        (("--goals",), {"type": nonneg_int, "default": 1000, "metavar": "N",
                        "help": "timed: random goal poses for the path-family check (default 1000; 0: none)"}),
        (("--goals-only",), {"action": "store_true", "help": "timed: only the random-goal check"}),
        # perception
        (("--only",), {"default": None, "metavar": "PARTS",
                       "help": "perception: comma-separated parts (default all: rows, proximity, proximity_sil, face, "
                               "oracle, holes, ruts, ruts_sil, hole_field, hole_field_sil, latency)"}),
        (("--methods",), {"default": None, "help": "perception: the row-detection methods (default all)"}),
        (("--plots",), {"default": "bench/results/perception", "metavar": "DIR",
                        "help": "perception: where the closed-loop figures go (default bench/results/perception)"}),
        (("--row-jitter",), {"type": _row_jitter, "default": None, "metavar": "M",
                             "help": "perception: the curvy row's planting jitter, m (default the scenario's 0.05)"}),
    ],
)
def _cmd_bench(ns: argparse.Namespace) -> int:
    used = _options_given(ns)
    wrong = [o for o in used if o in ONLY_FOR and ns.suite not in ONLY_FOR[o]]
    if wrong:
        o = wrong[0]
        return _bad(ns.suite, f"{o} is an option of {' and '.join(ONLY_FOR[o])}, not of {ns.suite}")
    if ns.fresh and ns.out is None and ns.suite != "planners":
        return _bad(ns.suite, "--fresh needs --out (without it nothing is stored)")
    handler = {"yards": _yards, "planners": _planners, "timed": _timed, "perception": _perception}[ns.suite]
    from ..sweep import RayUnreachable

    try:
        return handler(ns)
    except RayUnreachable as e:  # --ray auto or ADDRESS with no cluster there
        return _bad(ns.suite, str(e))


def _options_given(ns: argparse.Namespace) -> list[str]:
    """The options of ONLY_FOR that the command line set (a value other than the default)."""
    defaults = {"--yards": 100, "--first": 0, "--robot": "diff", "--walkers": 0, "--timed": False,
                "--mover-horizon": 2.0, "--planners": None, "--seeds": None, "--scenarios": None, "--no-plot": False,
                "--quick": False, "--sil": False, "--multi": False, "--timing-repeats": 3, "--goals": 1000,
                "--goals-only": False, "--only": None, "--methods": None, "--plots": "bench/results/perception",
                "--row-jitter": None}
    return [o for o, d in defaults.items() if getattr(ns, o[2:].replace("-", "_")) != d]


def _bad(suite: str, what: str) -> int:
    print(f"agnav bench {suite}: {what}", file=sys.stderr)
    return 2


def _backend(ns: argparse.Namespace, default_jobs: int | None) -> Any:
    """The back end of --jobs / --ray, or the exit code when Ray is asked for and missing."""
    from ..sweep import RayMissing, make_backend

    try:
        return make_backend(ns.jobs if ns.jobs is not None else (None if ns.ray else default_jobs), ns.ray)
    except RayMissing as e:
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 2


def _store(ns: argparse.Namespace, out: str | None) -> Any:
    """The run store in ``out`` (None: in memory), or the exit code when the folder is unusable."""
    from ..sweep import RunStore

    if out is None:
        return RunStore(None)
    why = unusable_out_dir(out)
    if why:
        print(f"agnav bench {ns.suite}: --out {out}: {why}", file=sys.stderr)
        return 1
    try:
        return RunStore(out, fresh=ns.fresh)
    except OSError as e:
        return report_write_failure(f"bench {ns.suite}", out, e)


def _label(row: dict[str, Any]) -> str:
    if "yard" in row:
        return f"yard {row['yard']} {row['planner']}: {row.get('end', '')}"
    if "scenario" in row and "planner" in row:
        return f"{row['scenario']}/{row['planner']}/s{row['seed']}: {row.get('end', '')}"
    return f"{row.get('case', row.get('part', row['task']))} s{row['seed']}"


def progress_line(show: bool) -> Callable[[Any], None] | None:
    """The sweep's progress on stderr: the bar, the rate, the time left and the run that ended (None when
    not shown)."""
    if not show:
        return None
    line = ProgressLine(every_s=0.1)

    def draw(p: Any) -> None:
        left = "" if p.left_s is None else f", about {_duration(p.left_s)} left"
        text = f"{bar(p.done, p.total)} runs, {p.rate_per_s:.2f} runs/s{left}; {_label(p.row):<40.40}"
        if p.done >= p.total:
            line.end(text)
        else:
            line.show(text)

    return draw


def _duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def _sweep(ns: argparse.Namespace, tasks: list[Any], backend: Any, store: Any, what: str,
           order: list[int] | None = None) -> list[dict[str, Any]] | int:
    """Run ``tasks`` as a sweep on ``backend`` (opened by the caller): says what is under way, shows the
    progress, turns the sweep's failures into an exit code (1 a run failed, 2 no Ray cluster at --ray, 130
    interrupted)."""
    from ..sweep import RayUnreachable, SweepFailed, run_sweep
    from ..sweep.tasks import code_digest, task_key

    try:
        if not ns.quiet:
            code = code_digest()
            n = len({task_key(t, code) for t in tasks})
            stored = sum(task_key(t, code) in store for t in tasks)
            again = f" ({stored} stored by an earlier run: resuming)" if stored else ""
            print(f"agnav bench: {n} runs on {backend.workers(max(1, n - stored))} worker(s){_where(backend)}{again}"
                  f"{what}", file=sys.stderr, flush=True)
        return run_sweep(tasks, backend, store, progress_line(not ns.quiet and sys.stderr.isatty()), order)
    except RayUnreachable as e:
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 2
    except SweepFailed as e:
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return _interrupted(ns, store)
    except OSError as e:
        return report_write_failure(f"bench {ns.suite}", str(store.out), e)


def _interrupted(ns: argparse.Namespace, store: Any) -> int:
    print(f"\nagnav bench {ns.suite}: interrupted; {len(store)} runs stored"
          + (f" in {store.out}: the same command resumes" if store.out is not None else ""), file=sys.stderr)
    return EXIT_INTERRUPTED


def _where(backend: Any) -> str:
    if backend.name != "ray":
        return ""
    return " of a local Ray cluster (127.0.0.1)" if backend.address == "local" else f" of the Ray cluster at {backend.address}"


def _planner_list(ns: argparse.Namespace, known: list[str]) -> list[str] | int:
    names = [p.strip() for p in ns.planners.split(",") if p.strip()]
    if not names:
        return _bad(ns.suite, f"--planners {ns.planners!r} names nothing; known: {', '.join(known)}")
    from ..planning.bench import _split

    unknown = []
    for p in names:
        try:
            base, _ = _split(p)
        except ValueError:
            base = p
        if base not in known or ("@" in p and base == p):
            unknown.append(p)
    if unknown:
        return _bad(ns.suite, f"unknown planner(s) {', '.join(unknown)}; known: {', '.join(known)}")
    return names


def _yards(ns: argparse.Namespace) -> int:
    import time

    from ..sim.runner import planner_names
    from ..sweep import yards

    planners = yards.default_planners(ns.robot) if ns.planners is None else _planner_list(ns, planner_names())
    if isinstance(planners, int):
        return planners
    backend = _backend(ns, 2)
    if isinstance(backend, int):
        return backend
    store = _store(ns, ns.out)
    if isinstance(store, int):
        return store
    t0 = time.time()
    ks = range(ns.first, ns.first + ns.yards)
    tasks = yards.tasks(ks, planners, ns.robot, ns.walkers, ns.timed, ns.mover_horizon, range(ns.seeds or 1))
    with backend:
        rows = _sweep(ns, tasks, backend, store, "" if ns.out is None else f", rows to {ns.out}/runs.jsonl")
    if isinstance(rows, int):
        return rows
    lines = yards.report(rows, planners, ns.first, ns.yards, ns.robot, ns.walkers, ns.timed, ns.mover_horizon)
    print("\n".join(lines))
    print(f"\nwall time {time.time() - t0:.0f} s")
    return 0


def _planners(ns: argparse.Namespace) -> int:
    from dataclasses import replace

    from ..planning.bench import SUITE, run_suite, write_report

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
            print(f"agnav bench: unknown scenario(s) {', '.join(unknown)}; suite: {', '.join(c.scenario for c in SUITE)}",
                  file=sys.stderr)
            return 2
        suite = [c for c in suite if c.scenario in want]
    if ns.planners:
        want_p = {p.strip() for p in ns.planners.split(",") if p.strip()}
        known_p = sorted({p for c in SUITE for p in c.planners})
        unknown_p = sorted(want_p - set(known_p))
        if unknown_p:
            what = f"unknown planner entr{'y' if len(unknown_p) == 1 else 'ies'} {', '.join(unknown_p)}"
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
        print(f"agnav bench: a subset run (--scenarios, --planners or --seeds) needs --out: the default {PLANNERS_OUT} "
              "holds the whole suite's tables", file=sys.stderr)
        return 2
    backend = _backend(ns, None)
    if isinstance(backend, int):
        return backend
    out = PLANNERS_OUT if ns.out is None else ns.out
    bad_out = unusable_out_dir(out) or clear_earlier_outputs("bench", out, BENCH_OUTPUTS, ns.quiet)
    if bad_out:  # before the run, so that a long run is not lost to a typo
        print(f"agnav bench: --out {out}: {bad_out}", file=sys.stderr)
        return 1
    store = _store(ns, out)
    if isinstance(store, int):
        return store
    import time

    from ..sweep.planners import tasks as planner_tasks

    t0 = time.perf_counter()
    n_runs = len(planner_tasks(suite))
    results: list[dict[str, Any]] | int
    try:
        with backend:
            if not ns.quiet:  # the bar moves only when a run ends: say at once what is under way
                print(f"agnav bench: {n_runs} runs on {backend.workers(n_runs)} worker(s){_where(backend)}, results to {out}",
                      file=sys.stderr, flush=True)
            results = run_suite(suite, ns.jobs, backend=backend, store=store, sweep_progress=progress_line(not ns.quiet))
    except KeyboardInterrupt:
        results = _interrupted(ns, store)
    except Exception as e:  # noqa: BLE001  (the sweep's failures, as for every suite)
        results = _sweep_failure(ns, e, store)
    if isinstance(results, int):
        return results
    wall = time.perf_counter() - t0
    cmd = f"agnav bench planners --out {out}" + (f" --jobs {ns.jobs}" if ns.jobs else "") + \
        (f" --ray {ns.ray}" if ns.ray else "") + (f" --scenarios {ns.scenarios}" if ns.scenarios else "") + \
        (f" --planners {ns.planners}" if ns.planners else "") + (f" --seeds {ns.seeds}" if ns.seeds is not None else "")
    try:
        paths = write_report(results, out, cmd, wall, plots=not ns.no_plot)
    except OSError as e:  # disk full, folder removed or made read-only during the run
        return report_write_failure("bench", out, e)
    print(f"{len(results)} runs in {wall:.0f} s; wrote {len(paths)} files to {out}")
    return 0


def _sweep_failure(ns: argparse.Namespace, e: BaseException, store: Any) -> int:
    from ..sweep import RayUnreachable, SweepFailed

    if isinstance(e, RayUnreachable):
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 2
    if isinstance(e, SweepFailed):
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 1
    if isinstance(e, OSError):
        return report_write_failure(f"bench {ns.suite}", str(store.out), e)
    raise e


def _timed(ns: argparse.Namespace) -> int:
    if ns.multi and not ns.sil:
        return _bad(ns.suite, "--multi goes with --sil")
    argv = ([] if ns.seeds is None else ["--seeds", str(ns.seeds)]) + (["--quick"] if ns.quick else []) + \
        (["--sil"] if ns.sil else []) + (["--multi"] if ns.multi else []) + \
        ["--timing-repeats", str(ns.timing_repeats), "--goals", str(ns.goals)] + (["--goals-only"] if ns.goals_only else [])
    return _script_suite(ns, argv)


def _perception(ns: argparse.Namespace) -> int:
    from ..perception import row_method_names

    parts_known = list(PERCEPTION_PARTS)
    parts = [p.strip() for p in (ns.only or ",".join(parts_known)).split(",") if p.strip()]
    unknown = [p for p in parts if p not in parts_known]
    if unknown or not parts:
        return _bad(ns.suite, f"--only: unknown part(s) {', '.join(unknown) or '(none given)'}; "
                              f"known: {', '.join(parts_known)}")
    methods = row_method_names() if ns.methods is None else [m.strip() for m in ns.methods.split(",") if m.strip()]
    bad_m = [m for m in methods if m not in row_method_names()]
    if bad_m or not methods:
        return _bad(ns.suite, f"--methods: unknown method(s) {', '.join(bad_m) or '(none given)'}; "
                              f"known: {', '.join(row_method_names())}")
    argv = ["--only", ",".join(parts), "--methods", ",".join(methods), "--plots", "" if ns.no_plot else ns.plots]
    if ns.row_jitter is not None:
        argv += ["--row-jitter", str(ns.row_jitter)]
    return _script_suite(ns, argv)


PERCEPTION_PARTS = ("rows", "proximity", "proximity_sil", "face", "oracle", "holes", "ruts", "ruts_sil", "hole_field",
                    "hole_field_sil", "latency")


def _script_suite(ns: argparse.Namespace, argv: list[str]) -> int:
    """A suite whose script prints the tables (bench/bench_timed.py, bench/bench_perception.py), its runs as
    sweeps: each call of a run function in turn, its seeds or methods spread over the workers."""
    from ..sweep import RayUnreachable, SweepFailed, run_sweep
    from ..sweep.scripts import SCRIPT_SUITES, NoCheckout, run_script, script

    try:
        script(SCRIPT_SUITES[ns.suite][0])
    except NoCheckout as e:
        return _bad(ns.suite, str(e))
    backend = _backend(ns, 1)
    if isinstance(backend, int):
        return backend
    store = _store(ns, ns.out)
    if isinstance(store, int):
        return store
    said: list[bool] = []

    def sweep(tasks: list[Any]) -> list[dict[str, Any]]:
        if not said and not ns.quiet:
            said.append(True)
            where = "" if ns.out is None else f", rows to {ns.out}/runs.jsonl"
            print(f"agnav bench: the runs of bench/{SCRIPT_SUITES[ns.suite][0]}.py on up to {backend.workers(1 << 30)} "
                  f"worker(s){_where(backend)}{where}", file=sys.stderr, flush=True)
        return run_sweep(tasks, backend, store, progress_line(not ns.quiet and sys.stderr.isatty()))

    try:
        with backend:
            return run_script(ns.suite, argv, sweep, store)
    except RayUnreachable as e:
        return _bad(ns.suite, str(e))
    except SweepFailed as e:
        print(f"agnav bench {ns.suite}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return _interrupted(ns, store)
    except Exception as e:  # noqa: BLE001  (a run of the script failed and the script did not catch it)
        print(f"agnav bench {ns.suite}: a run of bench/{SCRIPT_SUITES[ns.suite][0]}.py failed: "
              f"{type(e).__name__}: {e}", file=sys.stderr)
        return 1
