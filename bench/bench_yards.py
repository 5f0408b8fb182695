#!/usr/bin/env python3
"""Random cluttered yards: how often does each planner arrive, run out of time, or touch something?

Same as ``agnav bench yards`` (the yards, the robots and the table: agnav_host.sweep.yards); arguments are
passed through, e.g.::

    .venv/bin/python bench/bench_yards.py [--yards 100] [--first 0] [--planners subsumption,flb,vfh] [--jobs 2]
    .venv/bin/python bench/bench_yards.py --robot ackermann [--walkers 2] [--timed]
    .venv/bin/python bench/bench_yards.py --yards 10000 --planners flb --out out/yards --ray local

Every run is a sweep task; with ``--out DIR`` each run's row goes to DIR/runs.jsonl as it ends and the same
command resumes a killed sweep.
"""

import sys

from agnav_host.cli import main
from agnav_host.sweep.yards import ROBOTS, yard_toml  # noqa: F401  (yard_toml(k, ...) prints yard k's scenario)

if __name__ == "__main__":
    raise SystemExit(main(["bench", "yards", *sys.argv[1:]]))
