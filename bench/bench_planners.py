#!/usr/bin/env python3
"""Planner benchmark: the reference experiments on every host planner.

Same as ``agnav bench planners`` (a sweep on local processes or Ray); arguments are passed through, e.g.::

    .venv/bin/python bench/bench_planners.py --out bench/results/planners --jobs 2
    .venv/bin/python bench/bench_planners.py --out out/planners --ray local

Writes runs.jsonl (each run as it ends: a killed run resumes), runs.csv, summary.csv, planners.md and plots
(paths, speed, curvature) to --out.
"""

import sys

from agnav_host.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["bench", "planners", *sys.argv[1:]]))
