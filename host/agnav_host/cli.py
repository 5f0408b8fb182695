"""``agnav`` command line: a registry of subcommands, each a thin wrapper around library calls.

Add a subcommand with the :func:`subcommand` decorator::

    @subcommand("name", help="one line", args=[(("--flag",), {"type": int})])
    def _cmd_name(ns: argparse.Namespace) -> int: ...

Any option that takes a value may be given a negative number after a space (``--goal -3,5,90``,
``--start-speed -1e-3``): :func:`main` joins such an option with a value that reads as a number or a
comma-separated list of numbers (``--goal=-3,5,90``) before argparse sees it, since argparse would
otherwise take the value for an option. The options that take a value are read from the parser, so a
subcommand declares nothing for this. Beyond that, the parsers (:class:`_Parser`) take any word that starts
like a negative number for a value, never an option: after an abbreviated option (``--start-steer -1e-3``),
as a positional (``param set NAME -1e3``) and when the list is malformed (``--goal -3,abc,90`` gets the
option's own message), and they take a subcommand's options between its positionals
(``param get --device X NAME``).

Number options use the checked types below (:func:`finite_float`, :func:`positive_float`, ...) so that
``nan``, ``inf`` or a negative count is refused by argparse with the option's name, not deep in a run. Every
option or positional that takes text (a path, a name, a device) and declares no type of its own refuses an
empty value (``--out ""``, ``--device "$PORT"`` with ``PORT`` unset), which would otherwise mean ``.`` or the
option's default (:func:`nonempty_text`, added by :func:`build_parser`).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

__all__ = ["main", "subcommand", "SUBCOMMANDS", "parse_goal", "build_parser", "finite_float", "positive_float",
           "positive_float_at_most", "DAY_S", "up_to_a_day", "nonneg_float", "positive_int", "nonneg_int", "int_in", "nonempty_text",
           "unusable_out_dir", "unwritable_file"]

Handler = Callable[[argparse.Namespace], int]


@dataclass(frozen=True)
class _Sub:
    name: str
    help: str
    handler: Handler
    args: tuple[tuple[tuple[str, ...], dict[str, Any]], ...]
    epilog: str = ""


SUBCOMMANDS: dict[str, _Sub] = {}
_UNSIGNED = r"((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan)"
# a negative number, or a comma-separated list of numbers starting with one: "-3,5,90", "-1e-3", "-inf"
_NUMLIST = re.compile(rf"^-{_UNSIGNED}(,[-+]?{_UNSIGNED})*$", re.IGNORECASE)


# A word that starts like a negative number ("-3,5,90", "-1e-3", "-inf", a malformed "-3,abc,90"): a value for
# argparse, never an option (no option of agnav starts with "-" and a digit, ".", "inf" or "nan").
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


class _Parser(argparse.ArgumentParser):
    """argparse's parser with two rules for people typing commands: a word that starts like a negative number
    is a value (:data:`_NEGATIVE_VALUE`), and a subcommand's options may stand between its positionals
    (``param get --device X NAME``: argparse's intermixed parsing, for every parser without subcommands)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_VALUE
        self._in_intermixed = False

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        if self._in_intermixed or any(a.nargs in (argparse.PARSER, argparse.REMAINDER)
                                      for a in self._get_positional_actions()):
            return super().parse_known_args(args, namespace)
        self._in_intermixed = True  # parse_known_intermixed_args calls parse_known_args: plain ones from here
        try:
            return self.parse_known_intermixed_args(args, namespace)
        finally:
            self._in_intermixed = False


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def finite_float(text: str) -> float:
    """argparse type: a finite number (``nan`` and ``inf`` refused)."""
    v = _number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return v


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def positive_float_at_most(hi: float, what: str = "") -> Callable[[str], float]:
    """argparse type: a finite number > 0 and <= ``hi`` (``what`` says what ``hi`` is: "a day")."""

    def parse(text: str) -> float:
        v = positive_float(text)
        if v > hi:
            raise argparse.ArgumentTypeError(f"must be <= {hi:g}{f' ({what})' if what else ''}, got {text!r}")
        return v

    parse.__name__ = "float"
    return parse


#: The longest time an option takes, s (a wait, a timeout, an arrival time): longer waits overflow the
#: threading timeouts they end in, and no field robot's task is timed further out
DAY_S = 86400.0
up_to_a_day = positive_float_at_most(DAY_S, "a day")


def nonneg_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


def int_in(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """argparse type: a whole number in [lo, hi] (either end open when None)."""

    def parse(text: str) -> int:
        try:  # decimal first, leading zeros and all ("010" is ten), then 0x10, 0o17, 0b101
            v = int(text, 10)
        except ValueError:
            try:
                v = int(text, 0)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}{_digits_hint(text)}") from None
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            span = f"{lo}..{hi}" if lo is not None and hi is not None else (f">= {lo}" if lo is not None else f"<= {hi}")
            raise argparse.ArgumentTypeError(f"must be {span}, got {text!r}")
        return v

    parse.__name__ = "int"
    return parse


positive_int = int_in(1)
nonneg_int = int_in(0)


def _digits_hint(text: str) -> str:
    """For a whole number written as a float (``1e3``, ``10.0``): the digits to write instead."""
    try:
        f = float(text)
    except ValueError:
        return ""
    return f" (write it in digits: {int(f)})" if f.is_integer() and abs(f) < 2**53 else ""


def nonempty_text(text: str) -> str:
    """argparse type of the text options and positionals (paths, names, devices): anything but the empty string.
    An empty value (``--out ""``, or ``--device "$PORT"`` with PORT not set) would otherwise be taken for the
    current folder or silently for the option's default."""
    if text == "":
        raise argparse.ArgumentTypeError("empty value (a shell variable that is not set?)")
    return text


def _refusing_empty(kw: dict[str, Any]) -> dict[str, Any]:
    """``kw`` of an argument with :func:`nonempty_text` as its type when it takes text: it stores a value and has
    neither a type nor a list of choices of its own."""
    if "type" in kw or "choices" in kw or kw.get("action", "store") not in ("store", "append", "extend"):
        return kw
    return {**kw, "type": nonempty_text}


def subcommand(name: str, help: str, args: Sequence[tuple[tuple[str, ...], dict[str, Any]]] = (),
               epilog: str = "") -> Callable[[Handler], Handler]:
    """Register ``fn`` as ``agnav <name>``; ``epilog`` ends ``agnav <name> --help`` (exit codes, units)."""

    def deco(fn: Handler) -> Handler:
        if name in SUBCOMMANDS:
            raise ValueError(f"subcommand {name!r} registered twice")
        SUBCOMMANDS[name] = _Sub(name, help, fn, tuple(args), epilog)
        return fn

    return deco


def parse_goal(text: str) -> tuple[float, float, float | None]:
    """``X,Y`` or ``X,Y,HEADING_DEG`` -> (x_m, y_m, heading_deg or None). Negative numbers are fine."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"goal must be X,Y or X,Y,HEADING_DEG, got {text!r}")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"goal must contain numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"goal values must be finite, got {text!r}")
    return vals[0], vals[1], vals[2] if len(vals) == 3 else None


def _value_options(parser: argparse.ArgumentParser) -> dict[str, set[str]]:
    """For each subcommand, its options that take a value (not flags)."""
    out: dict[str, set[str]] = {}
    for act in parser._actions:
        if isinstance(act, argparse._SubParsersAction):
            for name, sp in act.choices.items():
                out[name] = {o for a in sp._actions if a.option_strings and a.nargs != 0 for o in a.option_strings}
    return out


def _subparser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    """The parser of subcommand ``name``."""
    act = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return act.choices[name]  # type: ignore[no-any-return]


def _join_negative_values(argv: list[str], value_options: dict[str, set[str]]) -> list[str]:
    """Join an option that takes a value (``value_options``: :func:`_value_options`) with a following
    negative number (list): ``--x -1`` -> ``--x=-1``."""
    sub = next((a for a in argv if not a.startswith("-")), None)
    takes_value = value_options.get(sub or "", set())
    out: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in takes_value and i + 1 < len(argv) and _NUMLIST.match(argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


# Modules that register more subcommands with @subcommand when imported (one per area, so
# each area keeps its CLI next to its code). Listed here so `agnav --help` shows them all.
COMMAND_MODULES: tuple[str, ...] = (
    "agnav_host.perception.commands",
    "agnav_host.planning.commands",
    "agnav_host.planning.timed_commands",
    "agnav_host.link.commands",
    "agnav_host.link.run_command",
    "agnav_host.sil.commands",
    "agnav_host.faults.commands",
)


def _load_command_modules() -> None:
    import importlib
    import importlib.util

    for name in COMMAND_MODULES:
        if importlib.util.find_spec(name.rsplit(".", 1)[0]) is None:
            continue  # that area is not in this build
        try:
            spec = importlib.util.find_spec(name)
        except ModuleNotFoundError:
            spec = None
        if spec is not None:
            importlib.import_module(name)


def build_parser() -> argparse.ArgumentParser:
    _load_command_modules()
    parser = _Parser(prog="agnav", description="AgNav host companion")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for s in SUBCOMMANDS.values():
        sp = sub.add_parser(s.name, help=s.help, description=s.help, epilog=s.epilog or None)
        for flags, kw in s.args:
            sp.add_argument(*flags, **_refusing_empty(kw))
        sp.set_defaults(_handler=s.handler)
    return parser


#: Exit code when the reader of our output went away (``agnav planners | head -1``): what a process killed by
#: SIGPIPE reports to the shell, 128 + 13.
EXIT_BROKEN_PIPE = 141


def _quiet_broken_pipe() -> int:
    """The reader of stdout (or stderr) is gone: point both at /dev/null so that nothing more, not even
    Python's flush at exit, fails on them, and exit quietly as standard tools do."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        for stream in (sys.stdout, sys.stderr):
            os.dup2(devnull, stream.fileno())
    except (OSError, ValueError, AttributeError):  # a stream without a file descriptor (a test's capture)
        pass
    return EXIT_BROKEN_PIPE


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agnav`` console script; returns the exit code."""
    parser = build_parser()  # first: every subcommand's options must be known to the joiner
    args = _join_negative_values(list(sys.argv[1:] if argv is None else argv), _value_options(parser))
    ns, extras = parser.parse_known_args(args)
    if extras:  # with the subcommand's usage, not agnav's
        _subparser(parser, ns.command).error(f"unrecognized arguments: {' '.join(extras)}")
    handler: Handler = ns._handler
    try:
        rc = handler(ns)
        sys.stdout.flush()  # here, not at exit, so that a closed pipe is caught below
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return rc


# ---- subcommands -------------------------------------------------------------------------------


@subcommand("scenarios", help="list the built-in simulator scenarios")
def _cmd_scenarios(ns: argparse.Namespace) -> int:
    from .sim.scenario import DEFAULT_SCENARIO, builtin_descriptions

    for name, desc in builtin_descriptions().items():
        mark = " (default)" if name == DEFAULT_SCENARIO else ""
        print(f"{name:20s} {desc}{mark}")
    return 0


def _planner_names() -> list[str]:
    from .sim.runner import planner_names

    return planner_names()


@subcommand(
    "sim",
    help="run a simulator scenario and write summary.json and trajectory.csv",
    args=[
        (("scenario",), {"nargs": "?", "default": None, "help": "built-in name or .toml path (default: the default scenario)"}),
        (("--planner",), {"default": "him", "help": "planner by name (default him; see agnav planners; goal_seek = the stand-in)"}),
        (("--seed",), {"type": nonneg_int, "default": 0, "help": "random seed, a whole number >= 0 (default 0)"}),
        (("--duration",), {"type": positive_float, "default": None,
                           "help": "simulated seconds, > 0 (default: the scenario's duration_s)"}),
        (("--goal",), {"type": parse_goal, "default": None, "metavar": "X,Y[,HDG_DEG]",
                       "help": "replace the scenario's goals by one goal (m, m, deg); negatives allowed"}),
        (("--out",), {"required": True, "help": "output directory"}),
        (("--no-plot",), {"action": "store_true", "help": "skip the PNG even if matplotlib is present"}),
        (("--no-rrd",), {"action": "store_true", "help": "skip the rerun recordings (recording.rrd, link.rrd)"}),
        (("--quiet",), {"action": "store_true", "help": "no progress on stderr"}),
        (("--firmware",), {"choices": ["ideal", "sil", "avr"], "default": "ideal",
                           "help": "ideal: stand-in controller drives the model directly (default); sil: the real "
                                   "firmware (native SIL) between the host planner and the robot, with the radio link "
                                   "model; also writes link.tlog and firmware.csv; avr: the same with the real "
                                   "ATmega2560 ELF under simavr (slower: keep --duration short)"}),
    ],
)
def _cmd_sim(ns: argparse.Namespace) -> int:
    from .sim.metrics import ROW_SETTLE_M, row_distance
    from .sim.runner import run_scenario, write_outputs, write_row_distance
    from .sim.scenario import ScenarioError, load_scenario, run_length_problem
    from .types import Goal

    from .sim.field_controllers import is_field_controller

    names = _planner_names()
    if ns.planner not in names and ns.planner.replace("_", "-") not in names and not is_field_controller(ns.planner):
        print(f"agnav sim: unknown planner {ns.planner!r}; known: {', '.join(names)}", file=sys.stderr)
        return 2
    try:
        sc = load_scenario(ns.scenario)
    except ScenarioError as e:
        print(f"agnav sim: {e}", file=sys.stderr)
        return 2
    too_long = None if ns.duration is None else run_length_problem(ns.duration, sc.dt_s, "--duration")
    if too_long:
        print(f"agnav sim: --duration {ns.duration:g}: {too_long}", file=sys.stderr)
        return 2
    missing = _missing_sensor(sc, ns.planner)
    if missing:
        print(f"agnav sim: {missing}", file=sys.stderr)
        return 2
    if ns.planner != "goal_seek":
        from .sim.runner import _make_controller

        try:  # a name the scenario cannot run (no tilted laser, a bad meta entry...) fails here, not mid-run
            _make_controller(sc, ns.planner)
        except ValueError as e:
            print(f"agnav sim: {e}", file=sys.stderr)
            return 2
    bad_out = unusable_out_dir(ns.out) or clear_earlier_outputs("sim", ns.out, SIM_OUTPUTS, ns.quiet)
    if bad_out:
        print(f"agnav sim: --out {ns.out}: {bad_out}", file=sys.stderr)
        return 2
    goal = None
    if ns.goal is not None:
        x, y, hdg = ns.goal
        goal = Goal(x, y, None if hdg is None else math.radians(hdg))
    last = [-1]

    def progress(t: float, total: float) -> None:
        pct = int(100 * t / total) // 10 * 10
        if pct != last[0]:
            last[0] = pct
            print(f"\r[{sc.name}] t={t:6.1f}/{total:.0f} s  {pct:3d}%", end="", file=sys.stderr, flush=True)

    if getattr(ns, "firmware", "ideal") in ("sil", "avr"):
        from .sil.session import SilConfig, run_sil_scenario, write_sil_outputs

        cfg = SilConfig(firmware="avr" if ns.firmware == "avr" else "native")
        sil = run_sil_scenario(sc, ns.planner, ns.seed, ns.duration, goal, config=cfg,
                               progress=None if ns.quiet else progress)
        result = sil.run
        if not ns.quiet:
            print(file=sys.stderr)
        write = lambda: write_sil_outputs(sil, ns.out, plot=not ns.no_plot)  # noqa: E731
    else:
        result = run_scenario(sc, ns.planner, ns.seed, ns.duration, goal, None if ns.quiet else progress)
        if not ns.quiet:
            print(file=sys.stderr)
        write = lambda: write_outputs(result, ns.out, plot=not ns.no_plot)  # noqa: E731
    # the proximity follower on plant rows: how far the run kept from the nearest row's design line (the set
    # distance meta.follow_offset_m, default 1 m)
    row_run = ns.planner == "proximity" and bool(sc.world.row_lines)
    rows = (row_distance(result.trajectory[:, 1], result.trajectory[:, 2], sc.world.row_lines,
                         float(sc.meta.get("follow_offset_m", 1.0))) if row_run else None)
    try:
        paths = write()
        if rows is not None:
            paths += write_row_distance(rows, ns.out, plot=not ns.no_plot)
        if not getattr(ns, "no_rrd", False):
            paths += _sim_recordings(sc, result, ns.out, with_link=ns.firmware in ("sil", "avr"))
    except (OSError, RuntimeError) as e:  # disk full, output folder not writable, recorder died
        return _report_write_failure("sim", ns.out, e)
    m = result.metrics
    print(f"{sc.name}: {result.end_reason}, success={m.success}, time={m.time_s:.2f} s, path={m.path_length_m:.2f} m")
    if rows is not None:
        print(f"  distance from the row (design line, past the first {rows.settle_m:g} m of travel): mean {rows.mean_m:.3f} m, "
              f"sd {rows.sd_m:.3f}, {rows.min_m:.3f}-{rows.max_m:.3f} m, {100 * rows.within:.1f} % within "
              f"{rows.set_m:g} +- {rows.band_m:g} m")
    elif row_run:
        print(f"  distance from the row: not measured (the robot drove less than the first {ROW_SETTLE_M:g} m; "
              "no row_distance.json)")
    for p in paths:
        print(f"  wrote {p}")
    return 0


#: Every file `agnav sim` may write into its --out folder (ideal and firmware-in-the-loop runs, plots and
#: recordings): those of an earlier run are removed before a run, so that a folder never mixes two runs.
SIM_OUTPUTS = ("summary.json", "run_info.json", "trajectory.csv", "trajectory.png", "recording.rrd",
               "link.tlog", "firmware.csv", "link.rrd", "row_distance.json", "row_distance.png")


def clear_earlier_outputs(command: str, out: str, patterns: tuple[str, ...], quiet: bool) -> str | None:
    """Remove the files matching ``patterns`` (globs: the files ``command`` writes) that an earlier run left
    in ``out``; other files are left alone. Why that failed, or None. Said on stderr unless ``quiet``: the
    names, or their count when there are more than eight."""
    old: list[Path] = []  # in the order of ``patterns``, then by name
    for pat in patterns:
        old += [p for p in sorted(Path(out).glob(pat)) if (p.is_file() or p.is_symlink()) and p not in old]
    for p in old:
        try:
            p.unlink()
        except OSError as e:
            return f"cannot remove {p.name} of an earlier run: {e.strerror or e}"
    if old and not quiet:
        what = ", ".join(p.name for p in old) if len(old) <= 8 else f"{len(old)} files"
        print(f"agnav {command}: --out {out}: removed the earlier run's {what}", file=sys.stderr)
    return None


def _missing_sensor(sc: Any, planner: str) -> str | None:
    """Why the host planner in ``planner`` (``NAME`` or ``NAME+ground-guard``) cannot run on scenario ``sc``: a
    sensor it needs at every step that the scenario does not have; None when nothing is missing (or the name
    is not a registry planner: the field controllers check their own sensors)."""
    from .planning.base import UnknownPlanner
    from .planning.registry import canonical_name, planner_names, sensors_needed

    base = planner.split("+", 1)[0]
    try:
        needs = sensors_needed(canonical_name(base))
    except UnknownPlanner:
        return None
    have = {"laser": getattr(sc, "laser", None) is not None, "sonar": getattr(sc, "sonar", None) is not None}
    lacking = [s for s in needs if not have.get(s, True)]
    if not lacking:
        return None
    what = " and a ".join(f"[{s}]" for s in lacking)
    extra = " (a [tilted_laser] looks at the ground, not ahead)" if "laser" in lacking and getattr(sc, "tilted_laser", None) else ""
    usable = [n for n in planner_names() if all(have.get(s, True) for s in sensors_needed(n))]
    return (f"planner {planner!r} needs a {what} in the scenario; {sc.name!r} has none{extra}; planners that run "
            f"on it: {', '.join(usable + ['goal_seek'])}")


def unusable_out_dir(out: str) -> str | None:
    """Why ``out`` cannot be the output folder (a file, a folder that cannot be made, or one that takes no new
    files), or None; made and tried here, before a long run, so that the run is not lost to a typo or to a
    read-only folder."""
    import tempfile

    p = Path(out)
    if p.exists() and not p.is_dir():
        return "is a file, not a folder"
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return f"cannot create the folder: {e.strerror or e}"
    try:
        with tempfile.NamedTemporaryFile(dir=p, prefix=".agnav-write-check-"):
            pass
    except OSError as e:
        return f"cannot write in the folder: {e.strerror or e}"
    return None


def unwritable_file(p: Path) -> str | None:
    """Why the file ``p`` cannot be written (without leaving anything behind; missing folders count as made),
    or None if it can: checked before a long job, like :func:`unusable_out_dir` for a folder."""
    import tempfile

    if p.is_dir():
        return "it is a directory"
    parent = p.parent
    anc = parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        return f"{anc} is not a directory"
    try:
        if anc == parent:
            existed = p.exists()
            with open(p, "ab"):
                pass
            if not existed:
                p.unlink()
        else:  # the missing folders will be made: this must be allowed where they start
            tempfile.TemporaryDirectory(dir=anc).cleanup()
    except OSError as e:
        if isinstance(e, FileNotFoundError) and parent.is_dir():
            return f"{parent} does not take new files ({e.strerror})"
        return e.strerror or str(e)
    return None


def _report_write_failure(cmd: str, out: str, err: BaseException) -> int:
    """A run whose results could not all be written (disk full, read-only folder...): say so
    plainly and list what was kept, instead of a traceback."""

    why = getattr(err, "strerror", None) or str(err)
    where = getattr(err, "filename", None)
    print(f"agnav {cmd}: could not write the results{f' ({where})' if where else ''}: {why}", file=sys.stderr)
    try:
        import shutil

        free = shutil.disk_usage(out).free
        if free < 1 << 20:
            print(f"agnav {cmd}: the disk holding {out} is full ({free} B free)", file=sys.stderr)
    except OSError:
        pass
    kept = sorted(p for p in Path(out).glob("*") if p.is_file() and p.stat().st_size > 0) if Path(out).is_dir() else []
    if kept:
        print(f"agnav {cmd}: kept {len(kept)} file(s): " + ", ".join(f"{p.name} ({p.stat().st_size} B)" for p in kept),
              file=sys.stderr)
    else:
        print(f"agnav {cmd}: nothing was written", file=sys.stderr)
    return 1


def _sim_recordings(sc: Any, result: Any, out: str, with_link: bool) -> list:
    """recording.rrd (true pose and path, goals, walls) and, for firmware-in-the-loop runs (``with_link``:
    this run wrote link.tlog), link.rrd (what the robot reported over the radio: odometry, sonar, behaviour
    layer) for `rerun`."""

    from .viz.recorder import VizUnavailable, record_run, record_tlog

    out_dir = Path(out)
    try:
        goals = [(g.x_m, g.y_m) for g in getattr(sc, "goals", [])]
        segs = getattr(getattr(sc, "world", None), "segments", None)
        written = [record_run(result.trajectory, goals, out_dir / "recording.rrd", world_segments=segs)]
        if with_link:
            written.append(record_tlog(out_dir / "link.tlog", out_dir / "link.rrd"))
        return written
    except VizUnavailable as e:
        print(f"agnav sim: no recording ({e})", file=sys.stderr)
        return []


if __name__ == "__main__":  # pragma: no cover
    # `python -m agnav_host.cli`: the command modules register with agnav_host.cli, not with this
    # __main__ copy of it, so run the package's own main.
    from agnav_host.cli import main as _main

    raise SystemExit(_main())
