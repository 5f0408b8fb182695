"""Matplotlib PNG of a calibration fit: samples, fitted table, previous table, dead band."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np

from ..atomic import savefig_atomic
from ..link.calib_wire import TABLE_STEER, WireTable
from .fit import FitResult

__all__ = ["plot_fit", "require_matplotlib"]


def require_matplotlib() -> ModuleType:
    """Import matplotlib with the Agg backend, or raise RuntimeError saying how to install it."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("plots need matplotlib: .venv/bin/pip install matplotlib==3.11.2 "
                           "(pinned in requirements-lock.txt)") from None
    return plt


def plot_fit(fit: FitResult, path: str | Path, previous: WireTable | None = None, title: str = "") -> Path:
    plt = require_matplotlib()
    t = fit.table
    steer = t.table_id == TABLE_STEER
    scale, unit = (0.01, "steering angle, deg (positive left)") if steer else (0.001, "speed, m/s (forward)")
    lo = min(float(np.nanmin(fit.pwm)), min(p for p, _ in t.points())) - 2
    hi = max(float(np.nanmax(fit.pwm)), max(p for p, _ in t.points())) + 2
    grid = np.arange(int(lo), int(hi) + 1)
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    db_lo, db_hi = t.dead_band
    if db_hi > db_lo:
        ax.axvspan(db_lo, db_hi, color="0.9", label="dead band")
    ax.plot(fit.pwm, fit.value * scale, "o", ms=3, alpha=0.6, label="measured")
    ax.plot(grid, [t.value(int(g)) * scale for g in grid], "-", lw=2, label=f"fitted table (RMS {fit.rms * scale:.3g})")
    pts = t.points()
    ax.plot([p for p, _ in pts], [v * scale for _, v in pts], "s", ms=5, mfc="none", label="table points")
    if previous is not None:
        ax.plot(grid, [previous.value(int(g)) * scale for g in grid], "--", lw=1, label="previous table")
    ax.axvline(t.neutral_pwm, color="k", lw=0.5)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("PWM (table units)")
    ax.set_ylabel(unit)
    ax.set_title(title or ("Steering calibration" if steer else "Speed calibration"))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    savefig_atomic(fig, out)
    plt.close(fig)
    return out
