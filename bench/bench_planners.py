#!/usr/bin/env python3
"""Planner benchmark: the reference experiments on every host planner.

Same as ``agnav bench planners``; arguments are passed through, e.g.::

    .venv/bin/python bench/bench_planners.py --out bench/results/planners --jobs 2

Writes runs.csv, summary.csv, planners.md and plots (paths, speed, curvature) to --out.
"""

import sys

from agnav_host.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["bench", "planners", *sys.argv[1:]]))
