"""Matplotlib PNGs of a run (path coloured by speed, active behaviour layer over time) from a tlog summary."""

from __future__ import annotations

from pathlib import Path

from ..atomic import savefig_atomic
from ..link.replay import TlogSummary
from ..link.state import LAYER_NAMES

__all__ = ["plot_run"]


def plot_run(summary: TlogSummary, path: str | Path) -> Path:
    from ..calibration.plot import require_matplotlib

    plt = require_matplotlib()
    from .world_plot import draw_run, rows_from_poses

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2), dpi=110)
    if summary.poses:
        rows = rows_from_poses(summary.poses)
        art = draw_run(ax1, rows)
        cb = fig.colorbar(art.path, ax=ax1, shrink=0.85, pad=0.02)
        cb.set_label("speed, m/s (from the poses)")
        ax1.plot(rows[0, 1], rows[0, 2], "ko", ms=5, label="start")
        ax1.plot(rows[-1, 1], rows[-1, 2], "rs", ms=5, label="end")
        ax1.legend(fontsize=8)
        ax1.autoscale_view()
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("x, m (odometry frame)")
    ax1.set_ylabel("y, m (left)")
    ax1.set_title(f"path {summary.path_length_m:.2f} m")
    ax1.grid(alpha=0.3)
    if summary.layers:
        ts = [t for t, _ in summary.layers] + [summary.duration_s]
        ls = [lay for _, lay in summary.layers]
        ax2.step(ts, ls + [ls[-1]], where="post")
    ax2.set_yticks(list(LAYER_NAMES), list(LAYER_NAMES.values()), fontsize=7)
    ax2.set_xlabel("time, s")
    ax2.set_title("active firmware layer")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    savefig_atomic(fig, out)
    plt.close(fig)
    return out
