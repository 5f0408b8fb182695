"""A saved laser scan of four crop rows, shared by the `agnav rows` CLI tests."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from agnav_host.scanio import save_scan_csv
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import World, plants_along
from agnav_host.types import Pose2D


def four_rows_scan_csv(folder: Path) -> Path:
    """Rows 0.75 m apart; the robot 0.08 m left of the centre line, heading 0.1 rad clockwise (negative), the
    laser (TiM310) at the reference point. Written to ``folder/rows.csv``."""
    rng = np.random.default_rng(1)
    w = World()
    for y in (-1.125, -0.375, 0.375, 1.125):
        w.add_circles(plants_along(np.array([[-3.0, y], [8.0, y]]), 0.15, 0.05, rng, 3, 0.015))
    scan = Laser2D(laser_preset("tim310")).scan(w, Pose2D(0.0, 0.08, -0.1), 0.0, np.random.default_rng(0))
    return save_scan_csv(scan, folder / "rows.csv")
