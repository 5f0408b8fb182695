"""``agnav planners``: the CLI wrapper around the planner registry (``agnav bench planners`` is in
:mod:`.bench`)."""

from __future__ import annotations

import argparse

from .registry import subcommand

__all__: list[str] = []


@subcommand("planners", help="list every controller (names for agnav sim / agnav run --planner) and the sensors each needs")
def _cmd_planners(ns: argparse.Namespace) -> int:
    from ..planning.registry import CONTROLLERS, WRAPPERS

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
