"""``agnav faults``: run the fault-injection suite (:mod:`agnav_host.faults`) and print the table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .outputs import unwritable_file
from .progress import bar_line
from .registry import subcommand


@subcommand(
    "faults",
    help="inject every fault (radio, sensors, controller, bad commands, signing, host I/O) and print "
         "fault / expected / measured / pass",
    args=[
        (("--only",), {"action": "append", "default": [], "metavar": "TEXT",
                       "help": "run the cases whose area or name contains TEXT (repeatable)"}),
        (("--list",), {"action": "store_true", "help": "list the cases and exit"}),
        (("--markdown",), {"default": None, "metavar": "FILE",
                            "help": "also write the table as markdown (checked writable before the cases run)"}),
        (("--quiet",), {"action": "store_true", "help": "no progress bar"}),
    ],
)
def _cmd_faults(ns: argparse.Namespace) -> int:
    from ..faults import all_cases, format_table, run_cases

    cases = all_cases()
    if ns.only:
        keys = [k.lower() for k in ns.only]
        cases = [c for c in cases if any(k in c.name.lower() or k == c.area for k in keys)]
        if not cases:
            print(f"agnav faults: no case matches {', '.join(ns.only)} (see agnav faults --list)", file=sys.stderr)
            return 2
    if ns.list:
        for c in cases:
            print(f"{c.area:10s} {c.name}")
        return 0
    if ns.markdown:  # before the cases run (minutes for the whole suite), not after
        why = unwritable_file(Path(ns.markdown))
        if why:
            print(f"agnav faults: --markdown {ns.markdown}: cannot write there: {why}", file=sys.stderr)
            return 2
    rows = run_cases(cases, None if ns.quiet else bar_line(56))
    print(format_table(rows, markdown=False))
    if ns.markdown:
        try:
            Path(ns.markdown).parent.mkdir(parents=True, exist_ok=True)
            Path(ns.markdown).write_text(format_table(rows, markdown=True) + "\n", encoding="utf-8")
        except OSError as e:  # disk full, or the folder changed during the run: the table is printed above
            print(f"agnav faults: --markdown {ns.markdown}: could not write the table (printed above): "
                  f"{e.strerror or e}", file=sys.stderr)
            return 1
        print(f"wrote {ns.markdown}")
    return 0 if all(r.outcome.passed for r in rows) else 1
