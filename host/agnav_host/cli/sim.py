"""``agnav scenarios`` and ``agnav sim``: the built-in scenarios, and a simulator run (ideal, or with the real
firmware in the loop) written to summary.json, trajectory.csv and the recordings.

``agnav sim`` exits 0 after a run, 1 when its results cannot all be written, 2 for a bad option or scenario
(checked before the run: an unknown planner, a sensor the planner needs and the scenario lacks, a run too
long, an output folder that cannot be one).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any, Callable

from .argtypes import nonneg_int, parse_goal, positive_float
from .outputs import clear_earlier_outputs, report_write_failure, unusable_out_dir
from .progress import ProgressLine
from .registry import subcommand

__all__ = ["SIM_OUTPUTS"]


@subcommand("scenarios", help="list the built-in simulator scenarios")
def _cmd_scenarios(ns: argparse.Namespace) -> int:
    from ..sim.scenario import DEFAULT_SCENARIO, builtin_descriptions

    for name, desc in builtin_descriptions().items():
        mark = " (default)" if name == DEFAULT_SCENARIO else ""
        print(f"{name:20s} {desc}{mark}")
    return 0


def _planner_names() -> list[str]:
    from ..sim.runner import planner_names

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
        (("--pattern",), {"default": None, "metavar": "S-1L-2R-F",
                          "help": "a whole field's turn pattern in the Field Robot Event's notation, instead of the "
                                  "scenario's [field] pattern: what the row navigator drives and the run is scored on"}),
        (("--quiet",), {"action": "store_true", "help": "no progress on stderr"}),
        (("--firmware",), {"choices": ["ideal", "sil", "avr"], "default": "ideal",
                           "help": "ideal: stand-in controller drives the model directly (default); sil: the real "
                                   "firmware (native SIL) between the host planner and the robot, with the radio link "
                                   "model; also writes link.tlog and firmware.csv; avr: the same with the real "
                                   "ATmega2560 ELF under simavr (slower: keep --duration short)"}),
        (("--localise",), {"choices": ["scan", "poles", "posts", "odometry"], "default": None,
                           "help": "the host plans on wheel odometry fused by: scan (scan matching against --map or a "
                                   "map built online), poles (poles and trunks learnt online), posts (the scenario's "
                                   "surveyed posts), odometry (none); "
                                   "default: the true pose (ideal), the posts when listed (sil)"}),
        (("--map",), {"default": None, "metavar": "FILE.yaml",
                      "help": "a saved map (map_server YAML + PGM, e.g. from agnav slam) for --localise scan"}),
    ],
)
def _cmd_sim(ns: argparse.Namespace) -> int:
    from ..sim.metrics import ROW_SETTLE_M, row_distance
    from ..sim.runner import run_scenario, write_outputs, write_row_distance
    from ..sim.scenario import ScenarioError, load_scenario, run_length_problem
    from ..types import Goal

    from ..sim.field_controllers import is_field_controller

    names = _planner_names()
    if ns.planner not in names and ns.planner.replace("_", "-") not in names and not is_field_controller(ns.planner):
        print(f"agnav sim: unknown planner {ns.planner!r}; known: {', '.join(names)}", file=sys.stderr)
        return 2
    try:
        sc = load_scenario(ns.scenario)
    except ScenarioError as e:
        print(f"agnav sim: {e}", file=sys.stderr)
        return 2
    if getattr(ns, "pattern", None) is not None:
        from ..sim.field_gen import with_pattern

        try:
            sc = with_pattern(sc, ns.pattern)
        except ValueError as e:
            hint = " (`agnav field new` writes a field)" if sc.field is None else ""
            print(f"agnav sim: --pattern {ns.pattern}: {e}{hint}", file=sys.stderr)
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
        from ..sim.runner import _make_controller

        try:  # a name the scenario cannot run (no tilted laser, a bad meta entry...) fails here, not mid-run
            _make_controller(sc, ns.planner)
        except ValueError as e:
            print(f"agnav sim: {e}", file=sys.stderr)
            return 2
    if ns.map is not None and ns.localise != "scan":
        print("agnav sim: --map is for --localise scan", file=sys.stderr)
        return 2
    if ns.localise is not None:
        from ..sim.runner import make_localiser

        try:  # an impossible localiser or an unreadable map fails here, not mid-run
            make_localiser(sc, ns.localise, ns.map)
        except ValueError as e:
            print(f"agnav sim: --localise {ns.localise}: {e}", file=sys.stderr)
            return 2
    bad_out = unusable_out_dir(ns.out) or clear_earlier_outputs("sim", ns.out, SIM_OUTPUTS, ns.quiet)
    if bad_out:
        print(f"agnav sim: --out {ns.out}: {bad_out}", file=sys.stderr)
        return 2
    goal = None
    if ns.goal is not None:
        x, y, hdg = ns.goal
        goal = Goal(x, y, None if hdg is None else math.radians(hdg))
    line = ProgressLine()
    last = [-1]

    def progress(t: float, total: float) -> None:
        pct = int(100 * t / total) // 10 * 10
        if pct != last[0]:  # every 10 %
            last[0] = pct
            line.show(f"[{sc.name}] t={t:6.1f}/{total:.0f} s  {pct:3d}%")

    write: Callable[[], list[Path]]  # the run's output files, written once the run is over
    if getattr(ns, "firmware", "ideal") in ("sil", "avr"):
        from ..sil.build import SilBuildError
        from ..sil.session import SilConfig, run_sil_scenario, write_sil_outputs

        cfg = SilConfig(firmware="avr" if ns.firmware == "avr" else "native")
        try:
            sil = run_sil_scenario(sc, ns.planner, ns.seed, ns.duration, goal, config=cfg,
                                   progress=None if ns.quiet else progress, localise=ns.localise, map_yaml=ns.map)
        except SilBuildError as e:  # no compiler, no simavr, a firmware that does not build
            line.end()
            print(f"agnav sim: --firmware {ns.firmware}: {e}", file=sys.stderr)
            return 1
        result = sil.run
        line.end()
        write = lambda: write_sil_outputs(sil, ns.out, plot=not ns.no_plot)  # noqa: E731
    else:
        result = run_scenario(sc, ns.planner, ns.seed, ns.duration, goal, None if ns.quiet else progress,
                              localise=ns.localise, map_yaml=ns.map)
        line.end()
        write = lambda: write_outputs(result, ns.out, plot=not ns.no_plot)  # noqa: E731
    # the proximity follower on plant rows: how far the run kept from the nearest row's design line (the set
    # distance meta.follow_offset_m, default 1 m)
    row_run = ns.planner == "proximity" and bool(sc.world.row_lines)
    rows = (row_distance(result.trajectory[:, 1], result.trajectory[:, 2], sc.world.row_lines,
                         float(sc.meta.get("follow_offset_m", 1.0)), plants=sc.world.row_plants) if row_run else None)
    field = result.metrics.field_detail
    try:
        paths = write()
        if rows is not None:
            paths += write_row_distance(rows, ns.out, plot=not ns.no_plot)
        if field is not None:
            paths += _field_outputs(sc, result, field, ns.out, plot=not ns.no_plot)
        if not getattr(ns, "no_rrd", False):
            paths += _sim_recordings(sc, result, ns.out, with_link=ns.firmware in ("sil", "avr"))
    except (OSError, RuntimeError) as e:  # disk full, output folder not writable, recorder died
        return report_write_failure("sim", ns.out, e)
    m = result.metrics
    print(f"{sc.name}: {result.end_reason}, success={m.success}, time={m.time_s:.2f} s, path={m.path_length_m:.2f} m")
    if result.believed is not None:
        b, p = result.believed
        print(f"  localisation ({ns.localise or sc.meta.get('localise') or 'posts'}): the host's pose "
              f"{math.hypot(b.x_m - p.x_m, b.y_m - p.y_m):.3f} m and "
              f"{math.degrees(abs(math.remainder(b.yaw_rad - p.yaw_rad, 2 * math.pi))):.2f} deg off the true pose at the end")
    for t_ev, text in result.events:
        if text.startswith("localisation"):
            print(f"  t={t_ev:.1f} s: {text}")
    if rows is not None:
        pl = rows.planted()
        if pl is not None:
            print(f"  distance from the row as planted (each plant's centre, averaged over {pl['window_m']:g} m of row; past "
                  f"the first {rows.settle_m:g} m of travel): mean {pl['mean_m']:.3f} m, sd {pl['sd_m']:.3f}, "
                  f"{pl['min_m']:.3f}-{pl['max_m']:.3f} m, {100 * pl['within_band']:.1f} % within {rows.set_m:g} +- "
                  f"{rows.band_m:g} m")
        print(f"  distance from the row (design line, past the first {rows.settle_m:g} m of travel): mean {rows.mean_m:.3f} m, "
              f"sd {rows.sd_m:.3f}, {rows.min_m:.3f}-{rows.max_m:.3f} m, {100 * rows.within:.1f} % within "
              f"{rows.set_m:g} +- {rows.band_m:g} m")
    elif row_run:
        print(f"  distance from the row: not measured (the robot drove less than the first {ROW_SETTLE_M:g} m; "
              "no row_distance.json)")
    if field is not None and sc.field is not None:
        print(f"  field ({sc.field.pattern}): {field.rows_completed}/{len(field.expected)} lanes in the pattern's order, "
              f"pattern {'completed' if field.pattern_completed else 'not completed'}, {field.plants_touched} plants "
              f"touched; Field Robot Event: distance in rows {field.distance_m:.1f} m, time {field.time_s:.1f} s, "
              f"score {field.score_m:.1f} m")
    for p in paths:
        print(f"  wrote {p}")
    return 0


def _field_outputs(sc: Any, result: Any, field: Any, out: str, plot: bool) -> list[Path]:
    """field.json (the run scored on its field: every lane driven in order with its time, the turns between) and,
    with matplotlib and ``plot``, field.png (the route on the field, the pattern's lanes numbered)."""
    import json

    from ..atomic import write_atomic

    js = Path(out) / "field.json"
    write_atomic(js, json.dumps({"pattern": sc.field.pattern, **field.to_dict()}, indent=2) + "\n")
    written = [js]
    if plot:
        try:
            from ..viz.field_plot import plot_field_run

            written.append(plot_field_run(Path(out) / "field.png", result.trajectory, sc, field,
                                          planner=result.planner, end_reason=result.end_reason))
        except ImportError:
            pass
    return written


#: Every file `agnav sim` may write into its --out folder (ideal and firmware-in-the-loop runs, plots and
#: recordings): those of an earlier run are removed before a run, so that a folder never mixes two runs.
SIM_OUTPUTS = ("summary.json", "run_info.json", "trajectory.csv", "trajectory.png", "recording.rrd",
               "link.tlog", "firmware.csv", "link.rrd", "row_distance.json", "row_distance.png", "field.json",
               "field.png")



def _missing_sensor(sc: Any, planner: str) -> str | None:
    """Why the host planner in ``planner`` (``NAME`` or ``NAME+ground-guard``) cannot run on scenario ``sc``: a
    sensor it needs at every step that the scenario does not have; None when nothing is missing (or the name
    is not a registry planner: the field controllers check their own sensors)."""
    from ..planning.base import UnknownPlanner
    from ..planning.registry import canonical_name, planner_names, sensors_needed

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



def _sim_recordings(sc: Any, result: Any, out: str, with_link: bool) -> list[Path]:
    """recording.rrd (true pose and path, goals, walls) and, for firmware-in-the-loop runs (``with_link``:
    this run wrote link.tlog), link.rrd (what the robot reported over the radio: odometry, sonar, behaviour
    layer) for `rerun`."""

    from ..viz.recorder import VizUnavailable, record_run, record_tlog

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


