"""The MIT Killian Court log, the real data ``agnav slam`` is scored on.

The log: PyPI's ``rtb-data`` (the Robotics Toolbox's data files, MIT licence) ships
``rtbdata/data/killian.g2o.zip``, a g2o pose graph of the Killian Court run (MIT, 2002) that carries the run's
3,873 SICK scans as ROBOTLASER1 lines (180 beams, 1 deg apart, ipc timestamps). :mod:`.carmen` reads it; its
odometry is the chain of the graph's sequential edges (the vertices are the graph builder's estimate).

The ground truth: the relations of Kuemmerle et al. 2009 for this run, ``mit-killian.relations``
(``t1 t2 dx dy dz roll pitch yaw`` a line), kept in the project's shared data folder beside the checkout
(``../shared/data``) or wherever ``$AGNAV_KILLIAN_RELATIONS`` points. 658 of its 4,677 relations have both
times among the log's scans (the log is a subsampled copy of the run); :func:`~.relations.score_relations`
scores those.
"""

from __future__ import annotations

import os
from pathlib import Path

from .._paths import CHECKOUT_ROOT

__all__ = ["KillianDataError", "killian_log_path", "killian_relations_path", "PUBLISHED_TRANS_M"]

#: The published translational errors on this run (Kuemmerle et al. 2009, table of absolute errors), m:
#: method -> (mean, standard deviation)
PUBLISHED_TRANS_M = {"scan matching": (1.651, 4.138), "RBPF (50 particles)": (0.122, 0.386),
                     "graph mapping": (0.050, 0.056)}


class KillianDataError(LookupError):
    """The Killian log or its relations are not where they are looked for; the message says how to get them."""


def killian_log_path() -> Path:
    """The path of ``killian.g2o.zip`` in the installed ``rtb-data`` package."""
    try:
        from importlib.resources import files

        p = Path(str(files("rtbdata") / "data" / "killian.g2o.zip"))
    except ModuleNotFoundError:
        raise KillianDataError("the Killian log comes with PyPI's rtb-data package: pip install rtb-data") from None
    if not p.is_file():
        raise KillianDataError(f"rtb-data is installed but holds no {p.name} (looked at {p})")
    return p


def killian_relations_path() -> Path:
    """The path of ``mit-killian.relations``: ``$AGNAV_KILLIAN_RELATIONS``, else the shared data folder beside
    the checkout."""
    env = os.environ.get("AGNAV_KILLIAN_RELATIONS")
    tried = []
    if env:
        tried.append(Path(env))
    if CHECKOUT_ROOT is not None:
        tried.append(CHECKOUT_ROOT.parent / "shared" / "data" / "mit-killian.relations")
    for p in tried:
        if p.is_file():
            return p
    where = ", ".join(str(p) for p in tried) or "nowhere (no checkout and no $AGNAV_KILLIAN_RELATIONS)"
    raise KillianDataError(f"mit-killian.relations not found (looked at {where}); set $AGNAV_KILLIAN_RELATIONS")
