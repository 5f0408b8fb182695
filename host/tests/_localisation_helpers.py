"""Helpers of the localisation tests: ``agnav run`` against the fake robot on a replayed laser log."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from agnav_host.types import LaserScan


def run_on_replayed_scans(tmp_path: Path, scan_at: Callable[[float], LaserScan], model: str, mount_x_m: float,
                          localise: str) -> tuple[int, list[str]]:
    """Write 3 s of ``scan_at(t)`` at 15 Hz as a laser log (laser ``model`` ``mount_x_m`` ahead of the axle),
    run ``agnav run --localise LOCALISE`` on it for 2 s towards (1, 0) with the HIM planner against the fake
    robot; returns the exit code and the lines of ``localisation.csv`` (none when the run failed)."""
    from agnav_host import cli
    from agnav_host.lasers import LaserMount
    from agnav_host.lasers.log import LaserLogWriter
    from agnav_host.link.fake import FakeRobot

    log = tmp_path / "scans.alog"
    with LaserLogWriter(log) as w:
        w.declare(0, "tim5xx://test", "tim5xx", model, LaserMount(mount_x_m), scan_at(0.0), "device", 0.0)
        for k in range(45):
            w.write(0, scan_at(k / 15.0), k / 15.0, None)
    out = tmp_path / "run"
    laser = f"replay:{log}" + (f"?x={mount_x_m}" if mount_x_m else "")
    with FakeRobot() as fr:
        rc = cli.main(["run", "--device", fr.device, "--laser", laser, "--planner", "him", "--goal", "1,0",
                       "--duration", "2", "--out", str(out), "--no-plot", "--localise", localise])
    rows = (out / "localisation.csv").read_text().splitlines() if rc == 0 else []
    return rc, rows
