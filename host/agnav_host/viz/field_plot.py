"""field.png: a run on a whole field, as :func:`~agnav_host.viz.world_plot.run_figure` draws it (the field's plants,
weeds, fence and row lines, the route coloured by speed, the robot's outline), with the pattern's lanes numbered in
the order they are to be driven (green: driven in order; grey: not reached) and the Field Robot Event's score in
the title."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..atomic import savefig_atomic
from .world_plot import _pyplot, run_figure

if TYPE_CHECKING:
    from ..sim.field_gen import FieldScore
    from ..sim.scenario import Scenario

__all__ = ["plot_field_run"]


def plot_field_run(path: str | Path, rows: Any, scenario: "Scenario", score: "FieldScore", *, planner: str = "",
                   end_reason: str | None = None, dpi: int = 100) -> Path:
    """Write field.png (module docstring) for the trajectory ``rows`` (the runner's columns) on ``scenario``."""
    from ..sim.field_gen import FieldLayout

    plt = _pyplot()
    assert scenario.field is not None
    title = (f"{scenario.name} ({planner}) {scenario.field.pattern}: {score.rows_completed}/{len(score.expected)} "
             f"lanes, {score.plants_touched} plants touched, score {score.score_m:.1f} m")
    fig, ax = run_figure(rows, scenario, title=title, end_reason=end_reason, dpi=dpi)
    try:
        layout = FieldLayout.of(scenario)
        for k, lane in enumerate(score.expected):
            c = layout.lanes[lane].centre
            mid = c[len(c) // 2]
            done = k < score.rows_completed
            ax.annotate(str(k + 1), xy=(float(mid[0]), float(mid[1])), ha="center", va="center", fontsize=9,
                        color="white", gid="lane_order",
                        bbox=dict(boxstyle="circle,pad=0.2", fc="#2e8b57" if done else "0.55", ec="none"))
        ends = np.array([c for ln in layout.lanes for c in (ln.centre[0], ln.centre[-1])])
        ax.plot(ends[:, 0], ends[:, 1], ls="none")  # keep the lanes' ends in view
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        savefig_atomic(fig, out, dpi=dpi, bbox_inches="tight")
    finally:
        plt.close(fig)
    return out
