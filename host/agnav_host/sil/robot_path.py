"""The robot path end to end, as a field team runs it: ``agnav sil SCENARIO --laser KIND ...`` in one process serving
the firmware's MAVLink and the scenario's lasers over the devices' own protocols, and ``agnav run --config
host.toml --laser URL ... --planner NAME`` in another, over TCP on loopback, in real time.

:func:`run_robot_path` starts both, waits for the SIL's referee to end the run (or its duration), stops
``agnav run`` like Ctrl-C, and reads what both wrote: the referee's truth (``truth/``) and the robot side's own
outputs (``run/``: summary.json, run_info.json with the laser-to-command latencies, laser.alog, link.tlog).
:func:`timed_errors` and :func:`row_distance_of` turn the truth into the benchmarks' figures.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..sim.scenario import Scenario
from ..types import norm_angle_rad

__all__ = ["RobotPathRun", "run_robot_path", "timed_errors", "row_distance_of"]

_AGNAV = [sys.executable, "-c", "import sys; from agnav_host.cli import main; sys.exit(main())"]


@dataclass
class RobotPathRun:
    scenario: str
    planner: str
    out: Path
    truth: np.ndarray  # truth.csv: t_s (simulated, since boot), x_m, y_m, yaw_rad, speed, yaw rate, clearance, goal
    truth_info: dict[str, Any]
    truth_summary: dict[str, Any]
    run_info: dict[str, Any] | None
    run_summary: dict[str, Any] | None
    sil_rc: int | None
    run_rc: int | None
    sil_log: str = ""
    run_log: str = ""
    lasers: list[str] = field(default_factory=list)

    @property
    def end_reason(self) -> str:
        return str(self.truth_info.get("end_reason", "?"))

    @property
    def run_start_sim_s(self) -> float | None:
        """The simulated time at which ``agnav run`` started its loop (both processes share CLOCK_MONOTONIC)."""
        if not self.run_info or "t0_monotonic_s" not in self.run_info:
            return None
        return (float(self.run_info["t0_monotonic_s"]) - float(self.truth_info["monotonic_at_sim_zero_s"])) * \
            float(self.truth_info.get("speedup", 1.0))

    @property
    def latency(self) -> dict[str, Any]:
        return dict(self.run_info.get("laser_to_command", {})) if self.run_info else {}


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _goal_args(sc: Scenario) -> list[str]:
    args: list[str] = []
    for g in sc.goals:
        v = f"{g.x_m:g},{g.y_m:g}" + (f",{math.degrees(g.yaw_rad):.6g}" if g.yaw_rad is not None else "")
        args += [f"--goal={v}"]
    last = sc.goals[-1]
    if last.arrival_s is not None:
        args += ["--arrive-in", f"{last.arrival_s:g}"]
    return args + ["--goal-tolerance", f"{last.tolerance_m:g}"]


def run_robot_path(sc: Scenario, planner: str, out: str | Path, lasers: tuple[str, ...] = ("tim5xx",),
                   seed: int = 0, duration_s: float | None = None, run_args: tuple[str, ...] = (),
                   timeout_s: float | None = None) -> RobotPathRun:
    """Run ``sc`` with ``planner`` through the robot path (see the module docstring). ``lasers``: the emulated
    kind of the horizontal scanner and, for a scenario with a tilted laser, the tilted one's. RuntimeError with
    both logs when a process fails to start."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    dur = duration_s if duration_s is not None else sc.duration_s
    port = _free_port()
    hc = out / "host.toml"
    hc.unlink(missing_ok=True)
    def served(kind: str) -> str:  # TCP scanners on any free port; serial ones on a pty
        return kind if kind in ("urg", "rplidar") else f"{kind}:0"

    sil_cmd = _AGNAV + ["sil", sc.name, "--tcp", f"tcp:127.0.0.1:{port}",
                        "--laser", served(lasers[0]), "--host-config", str(hc), "--out", str(out / "truth"),
                        "--stop-at-end", "--movers-wait", "--duration", f"{dur + 5.0:g}", "--seed", str(seed)]
    if len(lasers) > 1:
        sil_cmd += ["--tilted-laser", served(lasers[1])]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    sil_log = open(out / "sil.log", "w")
    sil = subprocess.Popen(sil_cmd, stdout=sil_log, stderr=subprocess.STDOUT, env=env, stdin=subprocess.DEVNULL)
    run = None
    try:
        t_end = time.monotonic() + 60.0
        while not hc.exists() and sil.poll() is None and time.monotonic() < t_end:
            time.sleep(0.05)
        if not hc.exists():
            raise RuntimeError(f"agnav sil did not start: {(out / 'sil.log').read_text()}")
        run_cmd = _AGNAV + ["run", "--config", str(hc), "--planner", planner, "--out", str(out / "run"), "--no-plot",
                            "--duration", f"{dur + 3.0:g}", "--wait", "10", *_goal_args(sc), *run_args]
        run_log = open(out / "run.log", "w")
        run = subprocess.Popen(run_cmd, stdout=run_log, stderr=subprocess.STDOUT, env=env, stdin=subprocess.DEVNULL)
        limit = timeout_s if timeout_s is not None else dur + 60.0
        try:
            sil.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            sil.send_signal(signal.SIGINT)
            sil.wait(timeout=20)
        try:  # the robot side sees the arrival itself a moment later
            run.wait(timeout=8.0)
        except subprocess.TimeoutExpired:
            pass
        if run.poll() is None:
            run.send_signal(signal.SIGINT)
            try:
                run.wait(timeout=20)
            except subprocess.TimeoutExpired:
                run.kill()
                run.wait()
        run_log.close()
    finally:
        for p in (sil, run):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
        sil_log.close()
    truth_dir, run_dir = out / "truth", out / "run"

    def load(p: Path) -> dict[str, Any] | None:
        return json.loads(p.read_text()) if p.is_file() else None

    truth = np.loadtxt(truth_dir / "truth.csv", delimiter=",", skiprows=1, ndmin=2) if (truth_dir / "truth.csv").is_file() \
        else np.zeros((0, 8))
    return RobotPathRun(sc.name, planner, out, truth, load(truth_dir / "run_info.json") or {},
                        load(truth_dir / "summary.json") or {}, load(run_dir / "run_info.json"),
                        load(run_dir / "summary.json"), sil.returncode, run.returncode if run is not None else None,
                        (out / "sil.log").read_text(), (out / "run.log").read_text() if (out / "run.log").exists() else "",
                        list(lasers))


def timed_errors(r: RobotPathRun, sc: Scenario) -> dict[str, float | None]:
    """A timed run's figures from the truth: arrival-time error (s, since ``agnav run`` started, against the goal's
    ``arrival_s``), final position error (m) and heading error (deg) where the robot stopped."""
    g = sc.goals[-1]
    if not len(r.truth):
        return {"arrival_error_s": None, "final_error_m": None, "heading_error_deg": None}
    end = r.truth[-1]
    pos = math.hypot(end[1] - g.x_m, end[2] - g.y_m)
    hdg = None if g.yaw_rad is None else abs(math.degrees(norm_angle_rad(end[3] - g.yaw_rad)))
    arr = r.truth_info.get("arrival_sim_s")
    start = r.run_start_sim_s
    ate = None if arr is None or start is None or g.arrival_s is None else float(arr) - start - g.arrival_s
    return {"arrival_error_s": ate, "final_error_m": pos, "heading_error_deg": hdg}


def row_distance_of(r: RobotPathRun, sc: Scenario) -> Any:
    """The proximity run's distance from the row's design line (sim.metrics.row_distance on the truth)."""
    from ..sim.metrics import row_distance

    return row_distance(r.truth[:, 1], r.truth[:, 2], sc.world.row_lines, float(sc.meta.get("follow_offset_m", 1.0)))
