"""``agnav field new``: a whole field generated as a scenario that ``agnav sim`` runs (sim.field_gen; docs/fields.md).

Exits 0 after writing the file, 1 when it cannot be written, 2 for a bad option (a field that does not fit the
robot, a pattern that leaves the field, an output that is not a .toml file).
"""

from __future__ import annotations

import argparse
import sys

from .argtypes import finite_float, int_in, nonneg_float, nonneg_int, positive_float
from .registry import subcommand

__all__: list[str] = []

_EPILOG = ("The rows bend as y = k * spacing + C * x * (L - x) (C = --curvature, 1/m; L = --length-m): C L^2 / 4 m "
           "at mid-length, ends at atan(C L) to the headland. The robot starts in the outermost lane on the right, "
           "facing along the rows; --pattern is in the Field Robot Event's notation (S-1L-2R-F), a random one from "
           "--seed by default. Exit codes: 0 written, 1 cannot write --out, 2 bad option.")


@subcommand(
    "field",
    help="whole fields: `agnav field new` writes a generated crop field as a scenario for `agnav sim`",
    args=[
        (("action",), {"choices": ["new"], "help": "new: generate a field"}),
        (("--rows",), {"type": int_in(2, 60), "default": 6, "help": "plant rows, 2-60 (lanes = rows - 1; default 6)"}),
        (("--spacing-m",), {"dest": "spacing_m", "type": positive_float, "default": 0.75,
                            "help": "distance between rows, m (default 0.75)"}),
        (("--length-m",), {"dest": "length_m", "type": positive_float, "default": 10.0,
                           "help": "row length, m (default 10)"}),
        (("--curvature",), {"type": finite_float, "default": 0.0,
                            "help": "C, 1/m: the rows' lateral bend C x (L - x) m (0 = straight; |C| L <= 0.3)"}),
        (("--gap-share",), {"dest": "gap_share", "type": nonneg_float, "default": 0.0,
                            "help": "share of each row without plants, in gaps of 0.3-1 m (0-0.3; default 0)"}),
        (("--jitter-m",), {"dest": "jitter_m", "type": nonneg_float, "default": 0.02,
                           "help": "planting jitter, m (1 sigma in x and y; default 0.02)"}),
        (("--seed",), {"type": nonneg_int, "default": 0, "help": "layout seed, a whole number >= 0 (default 0)"}),
        (("--out",), {"required": True, "metavar": "FIELD.toml", "help": "the scenario file to write"}),
        (("--plants",), {"choices": ["maize", "bush"], "default": "maize",
                         "help": "maize-like stems (default) or bushes"}),
        (("--robot",), {"choices": ["diff_drive", "ackermann"], "default": "diff_drive",
                        "help": "the robot: the 0.4 m differential drive (default) or the ref-003 RC car"}),
        (("--pattern",), {"default": None, "help": "turn pattern, e.g. S-1L-2R-1L-3R-F (default: random from --seed)"}),
        (("--missing-share",), {"dest": "missing_share", "type": nonneg_float, "default": 0.03,
                                "help": "share of single plants missing (0-0.3; default 0.03)"}),
        (("--weeds-per-m",), {"dest": "weeds_per_m", "type": nonneg_float, "default": 0.3,
                              "help": "weeds per metre of lane (0-5; default 0.3)"}),
        (("--ragged-m",), {"dest": "ragged_m", "type": nonneg_float, "default": 0.25,
                           "help": "row ends spread over +- this, m (0-1; default 0.25)"}),
        (("--headland-m",), {"dest": "headland_m", "type": positive_float, "default": 2.0,
                             "help": "from the furthest row end to the fence, m (2-10; default 2)"}),
        (("--time-limit-s",), {"dest": "time_limit_s", "type": nonneg_float, "default": 0.0,
                               "help": "the task's time, s (default: the event's 180 s, longer for a long pattern)"}),
        (("--name",), {"default": None, "help": "scenario name (default: from the size and seed)"}),
    ],
    epilog=_EPILOG,
)
def _cmd_field(ns: argparse.Namespace) -> int:
    from ..atomic import write_atomic
    from ..sim.field_gen import FieldSpec, FieldSpecError, generate_field
    from ..sim.scenario import ScenarioError, parse_scenario
    from .outputs import OutputError, check_output

    try:
        out = check_output("--out", ns.out, (".toml",))
    except ValueError as e:
        print(f"agnav field: {e}", file=sys.stderr)
        return 2
    except OutputError as e:
        print(f"agnav field: {e}", file=sys.stderr)
        return 1
    spec = FieldSpec(rows=ns.rows, spacing_m=ns.spacing_m, length_m=ns.length_m, curvature=ns.curvature,
                     gap_share=ns.gap_share, jitter_m=ns.jitter_m, seed=ns.seed, plants=ns.plants, robot=ns.robot,
                     pattern=ns.pattern or "", missing_share=ns.missing_share, weeds_per_m=ns.weeds_per_m,
                     ragged_m=ns.ragged_m, headland_m=ns.headland_m, time_limit_s=ns.time_limit_s, name=ns.name or "")
    try:
        text = generate_field(spec)
        sc = parse_scenario(text, str(out))  # what agnav sim will read
    except (FieldSpecError, ScenarioError) as e:
        print(f"agnav field: {e}", file=sys.stderr)
        return 2
    try:
        write_atomic(out, text)
    except OSError as e:
        print(f"agnav field: --out {ns.out}: cannot write: {e.strerror or e}", file=sys.stderr)
        return 1
    assert sc.field is not None
    print(f"{sc.name}: {spec.rows} rows, {len(sc.world.circles)} plant and weed circles, pattern {sc.field.pattern}, "
          f"task {sc.field.time_limit_s:g} s")
    print(f"  wrote {out}")
    print(f"  run it: agnav sim {out} --planner row-navigator --out OUT")
    return 0
