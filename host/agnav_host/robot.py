"""A robot run: the host loop (:mod:`agnav_host.hostloop`) on the wall clock, against the robot's link and its
laser scanners. ``agnav run`` is a thin command over :class:`RobotRun`.

Sources: the firmware's odometry (AGNAV_ODOMETRY over the link, composed with the start pose), its sonar ring,
the horizontal laser and the tilted one (:mod:`agnav_host.lasers`: real scanners, the SIL's emulators, replayed
logs). With a horizontal laser the loop steps on each of its scans, at once (the scan's latency to the command
is measured); without one, or while it is silent, it steps at ``control_hz`` so that the watchdog sees the gap
and the firmware keeps getting setpoints. The command goes out as the firmware's setpoint
(:func:`~agnav_host.hostloop.firmware_setpoint`), or to a stock ArduPilot Rover.

Clock: every time in a run is seconds since :meth:`RobotRun.run` started (``t0_monotonic_s`` on
``time.monotonic()``); laser stamps are moved onto it.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .atomic import write_atomic
from .hostloop import Decision, HostLoop, OdometryReport, SensorFrame, firmware_setpoint
from .lasers import DeviceClock, LaserInfo, LaserMount, LaserSource
from .link.state import PoseState
from .planning.base import RobotSpec
from .streamfile import StreamedFile, StreamFile
from .types import DriveCommand, Goal, LaserScan, Pose2D, SonarFrame
from .units import milli_to_si

__all__ = ["RobotRun", "RunSettings", "RobotOutcome", "LaserFeed", "RunOutputs", "POSE_STALE_S", "TRAJECTORY_COLUMNS",
           "latency_summary"]

_log = logging.getLogger(__name__)

#: A host controller steers on the robot's odometry (AGNAV_ODOMETRY, 10 Hz): older than this (5 frames
#: missed) and it would drive blind, so the robot is held stopped instead.
POSE_STALE_S = 0.5
LASER_WAIT_S = 0.25  # with a laser: the longest wait for its next scan before a step without one, s
TRAJECTORY_COLUMNS = ("t_s", "x_m", "y_m", "yaw_rad", "speed_m_s", "yaw_rate_rad_s", "clearance_m", "goal_index")


@dataclass
class LaserFeed:
    """A started laser source in a run: its role (``laser`` or ``tilted_laser``), mounting pose and device info."""

    source: LaserSource
    mount: LaserMount
    info: LaserInfo
    role: str = "laser"


@dataclass(frozen=True)
class RunSettings:
    """What a robot run needs besides its link and lasers (SI units, times in s since the run started)."""

    goals: tuple[Goal, ...]
    spec: RobotSpec
    start: Pose2D = Pose2D()
    control_hz: float = 10.0
    duration_s: float | None = None
    firmware_max_steer_rad: float = math.radians(45.0)
    status_hz: float = 2.0
    # what the run knows of its surroundings (a sim.world.World, e.g. the surveyed posts), drawn under the path in
    # trajectory.png; None: the picture holds the path, the robot's outline and the goals
    world: Any = None


@dataclass
class RobotOutcome:
    """How a run ended (``arrived``, ``duration``, ``interrupted``, ``planning_error``) and what it measured."""

    reason: str
    t_s: float
    message: str = ""
    latency_s: list[float] = field(default_factory=list)  # per scan: command sent - scan stamp
    wait_s: list[float] = field(default_factory=list)  # per scan: the loop took it - scan stamp
    step_s: list[float] = field(default_factory=list)  # per scan: the controller's step
    steps: int = 0
    scans: int = 0
    holds: int = 0


def latency_summary(latency_s: list[float]) -> dict[str, float | int | None]:
    """Median, 99th percentile and maximum of the laser-to-command latencies, ms."""
    if not latency_s:
        return {"scans": 0, "median_ms": None, "p99_ms": None, "max_ms": None}
    a = np.asarray(latency_s) * 1e3
    return {"scans": int(len(a)), "median_ms": round(float(np.median(a)), 3),
            "p99_ms": round(float(np.percentile(a, 99)), 3), "max_ms": round(float(a.max()), 3)}


class RunOutputs:
    """The ``--out`` folder of a robot run, written as the run goes: ``trajectory.csv`` (the planned pose,
    appended every step), ``laser.alog`` (every scan of every laser, :mod:`agnav_host.lasers.log`),
    ``recording.rrd`` (rerun, streamed to disk), ``localisation.csv`` (with a localiser: its state and pose sigma
    every step) and, at the end, ``summary.json`` (the keys of ``agnav sim``), ``run_info.json`` and
    ``trajectory.png``.

    The streamed files go through :class:`~agnav_host.streamfile.StreamFile`: a full disk (any write error) never
    ends the run; the file stops on its last whole record (a CSV line, a laser-log record, a rerun message) and
    is said once, as a WARNING of the library's logger, a WARN text in the recording while it still records,
    and in ``run_info.json`` (``output_errors``). A file that never got a whole record is removed.
    :meth:`finish` lists the files on the disk, each a :class:`~agnav_host.streamfile.StreamedFile`, whose
    :meth:`~agnav_host.streamfile.StreamedFile.listing` says ``partial (N B)`` for one that stopped early."""

    def __init__(self, out: str | Path | None, rrd: str | Path | None = None) -> None:
        from .lasers.log import LaserLogWriter

        self.dir = Path(out) if out is not None else None
        self.rows: list[tuple[float, ...]] = []
        self.errors: list[str] = []  # each streamed file's write error, as said
        self.unwritten: list[str] = []  # finish(): the files written whole at the end that could not be
        self._traj: StreamFile | None = None
        self.log: Any = None
        self.rec: Any = None
        if self.dir is not None:
            self.dir.mkdir(parents=True, exist_ok=True)
            self._traj = StreamFile(self.dir / "trajectory.csv", "trajectory", on_error=self._file_error)
            self._traj.write_text(",".join(TRAJECTORY_COLUMNS) + "\n")
            self.log = LaserLogWriter(self.dir / "laser.alog", on_error=self._file_error)
        self._loc: StreamFile | None = None  # localisation.csv, opened on the first step with a localiser
        self._loc_failed = False
        self._declared: set[int] = set()
        self.rrd = Path(rrd) if rrd is not None else None
        if self.rrd is not None:
            from .viz.recorder import Recorder

            self.rec = Recorder.streaming_to(self.rrd, on_error=self._file_error)

    def _file_error(self, message: str) -> None:
        """A streamed file stopped (already logged by its StreamFile): kept for run_info.json and put in the
        recording's log."""
        self.errors.append(message)
        if self.rec is not None:
            try:
                self.rec.log_text(message, "WARN")
            except Exception:  # noqa: BLE001  (the recording is secondary: the run goes on)
                pass

    def scan(self, laser_id: int, feed: LaserFeed, scan: LaserScan, t_s: float, pose: Pose2D | None) -> None:
        if self.log is not None and laser_id not in self._declared:
            self.log.declare(laser_id, feed.source.url, feed.info.kind, feed.info.model, feed.mount, scan,
                             feed.info.stamps, feed.info.latency_s)
            self._declared.add(laser_id)
        if self.log is not None:
            self.log.write(laser_id, scan, t_s, pose)
        if self.rec is not None and laser_id == 0 and scan.pose is not None:
            self.rec.set_time(t_s)
            self.rec.log_scan(_world_points(scan))

    def step(self, t_s: float, pose: Pose2D, speed: float, yaw_rate: float, clearance: float, goal_index: int,
             state: Any) -> None:
        row = (t_s, pose.x_m, pose.y_m, pose.yaw_rad, speed, yaw_rate, clearance, float(goal_index))
        self.rows.append(row)
        if self._traj is not None:
            self._traj.write_text(f"{row[0]:.3f},{row[1]:.6f},{row[2]:.6f},{row[3]:.6f},{row[4]:.6f},{row[5]:.6f},"
                                  f"{row[6]:.6f},{goal_index}\n")
        if self.rec is not None:
            self.rec.set_time(t_s)
            self.rec.log_pose(PoseState(t_s, pose.x_m, pose.y_m, pose.yaw_rad, speed, yaw_rate, t_s))
            if state is not None and state.sonar is not None and state.pose is not None:
                self.rec.log_sonar(state.sonar, state.pose)
            if state is not None and state.behaviour is not None:
                self.rec.log_behaviour(state.behaviour)

    def localisation(self, t_s: float, state: str, sigma: tuple[float, float, float]) -> None:
        """A row of ``localisation.csv``: the localiser's state and its pose sigma (x m, y m, yaw rad)."""
        if self.dir is None or self._loc_failed:
            return
        if self._loc is None:
            path = self.dir / "localisation.csv"
            try:
                self._loc = StreamFile(path, "localisation", on_error=self._file_error)
            except OSError as e:
                self._loc_failed = True
                msg = f"localisation {path}: {e.strerror or e}: not written, the run goes on"
                _log.warning("%s", msg)
                self._file_error(msg)
                return
            self._loc.write_text("t_s,state,sigma_x_m,sigma_y_m,sigma_yaw_rad\n")
        self._loc.write_text(f"{t_s:.3f},{state or '-'},{sigma[0]:.5f},{sigma[1]:.5f},{sigma[2]:.6f}\n")

    def text(self, t_s: float, text: str, level: str = "INFO") -> None:
        if self.rec is not None:
            self.rec.set_time(t_s)
            self.rec.log_text(text, level)

    def finish(self, settings: RunSettings, outcome: RobotOutcome, info: dict[str, Any],
               plot: bool = True) -> list[StreamedFile]:
        """Close the streamed files, write summary.json, run_info.json (with ``output_errors``) and the plot
        (each whole or not at all); the files on the disk, in that order (a removed empty file is not listed).
        Those that could not be written are in ``unwritten`` ("name: reason")."""
        from .sim.metrics import RunMetrics

        written: list[StreamedFile] = []
        if self.rec is not None:
            self.rec.close()
            if self.rec.result is not None:
                written.append(self.rec.result)
        if self.dir is None:
            return [f for f in written if f.kept]
        assert self._traj is not None and self.log is not None
        written += [self._traj.close(), self.log.close()]
        if self._loc is not None:
            written.append(self._loc.close())
        written = [f for f in written if f.kept]
        rows = np.array(self.rows, dtype=float) if self.rows else np.zeros((1, len(TRAJECTORY_COLUMNS)))
        last = settings.goals[-1]
        arrived = outcome.reason == "arrived"
        m = RunMetrics.compute(rows[:, 0], rows[:, 1:3], rows[:, 3], rows[:, 4], rows[:, 5], rows[:, 6],
                               (last.x_m, last.y_m), last.yaw_rad, last.arrival_s, arrived,
                               outcome.t_s if arrived else None)
        info = {**info, "output_errors": list(self.errors)}
        for name, text in (("summary.json", json.dumps(m.to_dict(), indent=2) + "\n"),
                           ("run_info.json", json.dumps(info, indent=2) + "\n")):
            try:
                p = write_atomic(self.dir / name, text)
            except OSError as e:  # whole or not at all: listed as not written, the others still tried
                self.unwritten.append(f"{name}: {e.strerror or e}")
                continue
            written.append(StreamedFile(p, len(text.encode("utf-8")), 1))
        if plot and len(self.rows) > 1:
            try:
                png = _plot_run(rows, settings, self.dir / "trajectory.png", outcome.reason)
            except OSError as e:
                self.unwritten.append(f"trajectory.png: {e.strerror or e}")
                png = None
            if png is not None:
                written.append(StreamedFile(png, png.stat().st_size, 1))
        return written

    def abandon(self) -> None:
        """Close what is open after a failure (the files keep what was written)."""
        for c in (self._traj, self._loc, self.log):
            try:
                if c is not None:
                    c.close()
            except Exception:
                pass
        if self.rec is not None:
            try:
                self.rec.close()
            except Exception:
                pass


def _world_points(scan: LaserScan) -> np.ndarray:
    assert scan.pose is not None
    xy = scan.xy()
    c, s = math.cos(scan.pose.yaw_rad), math.sin(scan.pose.yaw_rad)
    return np.column_stack((scan.pose.x_m + c * xy[:, 0] - s * xy[:, 1], scan.pose.y_m + s * xy[:, 0] + c * xy[:, 1]))


def _plot_run(rows: np.ndarray, settings: RunSettings, path: Path, reason: str) -> Path | None:
    """trajectory.png: the planned pose's path coloured by speed, the robot's outline (from its RobotSpec) every
    2 s and at the end, the start and the goals, over ``settings.world`` when the run has one; None without
    matplotlib."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return None
    from .viz.world_plot import Footprint, plot_run

    return plot_run(path, rows, world=settings.world, goals=list(settings.goals), start=settings.start,
                    footprint=Footprint.of_spec(settings.spec), title="agnav run (odometry / localiser pose)",
                    end_reason=reason)


def _sonar_frame(state: Any, t_s: float) -> SonarFrame | None:
    if state.sonar is None:
        return None
    s = state.sonar
    st = np.array(s.status)
    r = np.array(s.ranges_m, dtype=float)
    r[st != 0] = np.nan  # no echo, fault and stale carry no obstacle range
    return SonarFrame(stamp_s=t_s, fired=st != 3, echo_us=2.0 * r / 343.0 * 1e6, ranges_m=r)


def _on_run_clock(scan: LaserScan, t0: float) -> LaserScan:
    return LaserScan(scan.angle_min_rad, scan.angle_increment_rad, scan.ranges_m, scan.range_max_m, scan.stamp_s - t0)


class RobotRun:
    """The host loop against a robot (see the module docstring).

    ``robot``: an :class:`~agnav_host.link.robot.AgnavRobot` (its ``state`` is the endpoint's telemetry) or an
    ArduPilot Rover adapter (``ardupilot=True``: DriveCommands instead of firmware setpoints); ``say``: where
    messages for the operator go (a laser fault, odometry lost and back); ``status``: called at ``status_hz``
    with the run time."""

    def __init__(self, robot: Any, loop: HostLoop, settings: RunSettings, lasers: list[LaserFeed] | None = None,
                 outputs: RunOutputs | None = None, ardupilot: bool = False,
                 say: Callable[[str], None] = lambda m: None, status: Callable[[float], None] | None = None,
                 clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep) -> None:
        self.robot = robot
        self.loop = loop
        self.settings = settings
        feeds = lasers or []
        self.laser = next((f for f in feeds if f.role == "laser"), None)
        self.tilted = next((f for f in feeds if f.role == "tilted_laser"), None)
        self.outputs = outputs
        self.ardupilot = ardupilot
        self.say = say
        self.status = status
        self.clock = clock
        self.sleep = sleep
        self.t0 = clock()
        self._odo_stamp: float | None = None
        self._odo_clock = DeviceClock(wrap_s=milli_to_si(2.0 ** 32))  # time_boot_ms is a 32-bit count of ms
        self._blind = False
        self._hold = ""

    # ---- sources ---------------------------------------------------------------------------------------
    def _pose(self, st: Any, now: float) -> tuple[Pose2D | None, OdometryReport | None]:
        p = st.pose
        if p is None or now - p.rx_time_s > POSE_STALE_S:
            return None, None
        report = None
        if p.time_boot_s != self._odo_stamp:
            self._odo_stamp = p.time_boot_s
            # the firmware's clock onto the run's: the localiser extrapolates odometry to the loop's times
            stamp = self._odo_clock.to_host(p.time_boot_s, p.rx_time_s) - self.t0
            report = OdometryReport(p.x_m, p.y_m, p.yaw_rad, stamp, p.speed_m_s, p.yaw_rate_rad_s)
        return self.settings.start.compose(Pose2D(p.x_m, p.y_m, p.yaw_rad)), report

    def _wait_scan(self, period: float) -> LaserScan | None:
        if self.laser is None:
            self.sleep(period)
            return None
        # the loop steps on each scan; a wait longer than a scan period (but well inside the watchdog's 0.5 s
        # and the firmware's link timeout) only returns empty when the laser is late
        return self.laser.source.wait(max(period, LASER_WAIT_S))

    # ---- the command -------------------------------------------------------------------------------------
    def _send(self, cmd: DriveCommand) -> None:
        sp = self.settings.spec
        if self.ardupilot:
            v = max(-sp.max_speed_m_s, min(sp.max_speed_m_s, cmd.speed_m_s))
            self.robot.drive_command(DriveCommand(v, cmd.yaw_rate_rad_s, cmd.steer_rad))
            return
        steer, v = firmware_setpoint(cmd, sp.kinematics, sp.track_m, sp.wheelbase_m, self.settings.firmware_max_steer_rad,
                                     sp.max_speed_m_s)
        self.robot.drive(steer, v)

    def _clearance(self, scan: LaserScan | None) -> float:
        if scan is None:
            return math.nan
        xy = scan.xy()
        if not len(xy):
            return math.nan
        m = self.laser.mount if self.laser is not None else LaserMount()
        c, s = math.cos(m.yaw_rad), math.sin(m.yaw_rad)  # the returns in the robot frame: nearest to its centre
        x = m.x_m + c * xy[:, 0] - s * xy[:, 1]
        y = m.y_m + s * xy[:, 0] + c * xy[:, 1]
        return float(np.min(np.hypot(x, y))) - self.settings.spec.radius_m

    # ---- the run -----------------------------------------------------------------------------------------------
    def run(self) -> RobotOutcome:
        """Drive until the last goal is reached, ``duration_s`` is up, a planning error, or Ctrl-C (reason
        ``interrupted``: the robot is told to stop at once; the caller e-stops it)."""
        try:
            return self._run()
        except KeyboardInterrupt:
            self.robot.stop()
            out = self._outcome
            out.reason, out.t_s = "interrupted", self.clock() - self.t0
            return out

    def _run(self) -> RobotOutcome:
        from .planning.base import PlanningError

        s = self.settings
        period = 1.0 / s.control_hz
        self.t0 = self.clock()
        out = self._outcome = RobotOutcome("duration", 0.0)
        next_status = 0.0
        last_scan: LaserScan | None = None
        while True:
            raw = self._wait_scan(period)
            now = self.clock()
            t = now - self.t0
            if s.duration_s is not None and t >= s.duration_s:
                out.reason, out.t_s = "duration", t
                break
            st = self.robot.state
            pose, report = self._pose(st, now)
            scan = _on_run_clock(raw, self.t0) if raw is not None else None
            tilted_raw = self.tilted.source.latest() if self.tilted is not None else None
            tilted = _on_run_clock(tilted_raw, self.t0) if tilted_raw is not None else None
            frame = SensorFrame(t, pose, st.pose.speed_m_s if pose is not None else 0.0,
                                st.pose.yaw_rate_rad_s if pose is not None else 0.0, odometry=report, scan=scan,
                                tilted_scan=tilted, sonar=_sonar_frame(st, t))
            try:
                d = self.loop.step(frame)
            except PlanningError as e:
                self.robot.stop()
                out.reason, out.t_s, out.message = "planning_error", t, str(e)
                break
            out.steps += 1
            self._act(d, t)
            if scan is not None:
                out.scans += 1
                if d.command is not None and not d.hold and not d.arrived:
                    out.latency_s.append(self.clock() - self.t0 - scan.stamp_s)
                    out.wait_s.append(t - scan.stamp_s)
                    out.step_s.append(d.step_s)
                last_scan = d.observation.scan if d.observation is not None and d.observation.scan is not None else last_scan
            if d.hold:
                out.holds += 1
            self._record(d, t, st, scan, tilted, last_scan)
            if d.arrived:
                out.reason, out.t_s, out.message = "arrived", t, d.event
                break
            if self.status is not None and t >= next_status:
                next_status = t + 1.0 / s.status_hz
                self.status(t)
        for _ in range(3):
            self.robot.stop()
            self.sleep(0.05)
        return out

    def _act(self, d: Decision, t: float) -> None:
        if d.event:
            self.say(d.event)
            if self.outputs is not None:
                self.outputs.text(t, d.event, "WARN" if d.hold else "INFO")
        if d.command is None and d.idle == "no new scan":  # the last setpoint stands until the next scan
            return
        if d.command is None:  # no odometry: hold the robot (stop setpoints also keep the firmware's link alive)
            if not self._blind:
                self._blind = True
                self.say(f"no odometry for > {POSE_STALE_S:.1f} s: holding the robot stopped until telemetry returns")
            self.robot.stop()
            return
        if self._blind:
            self._blind = False
            self.say(f"odometry back at t={t:.1f} s: planning again")
        if d.hold or d.arrived:
            if d.hold and d.hold != self._hold and not d.event:
                self.say(f"holding the robot: {d.hold}")
            self._hold = d.hold
            self.robot.stop()
            return
        if self._hold:
            self.say(f"t={t:.1f} s: {self._hold.split(':')[0]} cleared, driving again")
            self._hold = ""
        self._send(d.command)

    def _record(self, d: Decision, t: float, st: Any, scan: LaserScan | None, tilted: LaserScan | None,
                last_scan: LaserScan | None) -> None:
        o = self.outputs
        if o is None:
            return
        pose = d.pose
        if scan is not None and self.laser is not None:
            placed = d.observation.scan if d.observation is not None and d.observation.scan is not None else scan
            o.scan(0, self.laser, placed, scan.stamp_s, pose)
        if tilted is not None and self.tilted is not None:
            o.scan(1, self.tilted, tilted, tilted.stamp_s, pose)
        if pose is not None:
            speed = st.pose.speed_m_s if st.pose is not None else 0.0
            yr = st.pose.yaw_rate_rad_s if st.pose is not None else 0.0
            o.step(t, pose, speed, yr, self._clearance(last_scan), self.loop.goal_index, st)
            if d.pose_sigma is not None:
                o.localisation(t, d.localisation, d.pose_sigma)
