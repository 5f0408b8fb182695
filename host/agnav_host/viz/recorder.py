"""rerun recordings of runs (see the package docstring)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..link.state import LAYER_NAMES, REASON_NAMES, BehaviourState, PoseState, SonarState, flag_names

__all__ = ["Recorder", "VizUnavailable", "require_rerun", "record_tlog", "RERUN_PIN"]

RERUN_PIN = "rerun-sdk==0.41.0"
SONAR_HALF_CONE_RAD = math.radians(15.0)
PATH_PIECE = 64  # points per logged piece of the driven path
LAYER_COLOURS = {0: (128, 128, 128), 1: (220, 30, 30), 2: (240, 140, 0), 3: (160, 60, 200), 4: (40, 160, 220),
                 5: (40, 180, 80), 6: (30, 90, 220)}


class VizUnavailable(RuntimeError):
    """rerun-sdk is not installed (or too old)."""


def require_rerun() -> Any:
    try:
        import rerun as rr
    except ImportError:
        raise VizUnavailable(f"live view and .rrd recordings need rerun-sdk: .venv/bin/pip install {RERUN_PIN} "
                             "(pinned in requirements-lock.txt)") from None
    if not hasattr(rr, "RecordingStream") or not hasattr(rr, "Scalars"):
        raise VizUnavailable(f"rerun-sdk {getattr(rr, '__version__', '?')} is too old: install {RERUN_PIN}")
    return rr


def sonar_cone(x: float, y: float, yaw: float, bearing: float, r: float, n: int = 6) -> list[list[float]]:
    """Closed outline of one sonar cone (world frame)."""
    pts = [[x, y]]
    for a in np.linspace(-SONAR_HALF_CONE_RAD, SONAR_HALF_CONE_RAD, n):
        th = yaw + bearing + a
        pts.append([x + r * math.cos(th), y + r * math.sin(th)])
    pts.append([x, y])
    return pts


class Recorder:
    """Thin typed layer over one ``rerun.RecordingStream``."""

    def __init__(self, rec: Any, rr: Any, path: Path | None = None) -> None:
        self.rr = rr
        self.rec = rec
        self.path = path
        self._stream: Any = None  # rerun's in-memory stream, written to ``path`` by close() (to_file)
        self._path: list[list[float]] = []  # the driven path's current piece (PATH_PIECE points at most)
        self._piece = 0
        self._poses = 0

    @classmethod
    def to_file(cls, path: str | Path, app_id: str = "agnav") -> "Recorder":
        """A recording written to ``path`` by :meth:`close`. rerun encodes into memory and this recorder
        writes the bytes, so a failing disk is a plain OSError from ``close`` and no file is left: rerun's
        own file sink, on a full disk, logged its errors over ours, left a truncated file and once hung the
        process at exit. (rerun 0.41 offers no way to write the stream in pieces: the pieces of a binary
        stream concatenated do not verify.) The recording is held in memory until then: about 0.46 MB per
        minute of odometry, sonar and behaviour at 10 Hz each."""
        rr = require_rerun()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.open("wb").close()  # fail now, not at the end, when the folder cannot be written
        rec = rr.RecordingStream(app_id)
        r = cls(rec, rr, p)
        r._stream = rec.binary_stream()
        return r

    @classmethod
    def streaming_to(cls, path: str | Path, app_id: str = "agnav") -> "Recorder":
        """A recording streamed to ``path`` by rerun's file sink as it is logged (a robot run of hours is not
        held in memory). The folder is checked writable first; a disk that fills during the run ends the
        recording where it filled (rerun reports it on stderr), the run goes on."""
        rr = require_rerun()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.open("wb").close()  # fail now, not during the run, when the folder cannot be written
        rec = rr.RecordingStream(app_id)
        rec.save(str(p))
        return cls(rec, rr, None)

    @classmethod
    def spawn(cls, app_id: str = "agnav") -> "Recorder":
        """Live viewer (spawns ``rerun``); nothing is saved (use :meth:`to_file` for a recording)."""
        rr = require_rerun()
        rec = rr.RecordingStream(app_id)
        rec.spawn()
        return cls(rec, rr)

    def set_time(self, t_s: float) -> None:
        self.rec.set_time("time", duration=float(t_s))

    def log_pose(self, pose: PoseState) -> None:
        rr = self.rr
        x, y, yaw = pose.x_m, pose.y_m, pose.yaw_rad
        self.rec.log("world/robot", rr.Arrows2D(origins=[[x, y]], vectors=[[0.3 * math.cos(yaw), 0.3 * math.sin(yaw)]],
                                                colors=[(20, 20, 20)]))
        # The path goes out in pieces of PATH_PIECE points (world/path/<k>), the open piece again every
        # 4th pose and when full: a recording grows with the run's length, not with its square as when
        # the whole path was logged on every pose (65 MB for 10 minutes).
        self._path.append([x, y])
        self._poses += 1
        full = len(self._path) >= PATH_PIECE
        if len(self._path) >= 2 and (full or self._poses % 4 == 0):
            self.rec.log(f"world/path/{self._piece}", rr.LineStrips2D([self._path], colors=[(90, 90, 200)]))
        if full:
            self._piece += 1
            self._path = [self._path[-1]]
        self.rec.log("state/speed_m_s", rr.Scalars([pose.speed_m_s]))

    def log_goal(self, x_m: float, y_m: float) -> None:
        self.rec.log("world/goal", self.rr.Points2D([[x_m, y_m]], radii=[0.15], colors=[(0, 160, 0)], labels=["goal"]))

    def log_sonar(self, sonar: SonarState, pose: PoseState | None) -> None:
        if pose is None:
            return
        cones, colours = [], []
        for i, (r, st) in enumerate(zip(sonar.ranges_m, sonar.status)):
            if st in (2, 3) or r <= 0:  # fault / stale
                continue
            cones.append(sonar_cone(pose.x_m, pose.y_m, pose.yaw_rad, sonar.bearings_rad[i], r))
            colours.append((250, 160, 0) if st == 0 else (200, 200, 200))
        if cones:
            self.rec.log("world/sonar", self.rr.LineStrips2D(cones, colors=colours))

    def log_scan(self, points_world: np.ndarray) -> None:
        pts = np.asarray(points_world, dtype=float).reshape(-1, 2)
        self.rec.log("world/laser", self.rr.Points2D(pts, radii=[0.02], colors=[(200, 30, 30)]))

    def log_plan(self, path_xy: Iterable[Iterable[float]]) -> None:
        pts = [list(map(float, p)) for p in path_xy]
        if len(pts) >= 2:
            self.rec.log("world/plan", self.rr.LineStrips2D([pts], colors=[(0, 170, 90)]))

    def log_behaviour(self, b: BehaviourState) -> None:
        rr = self.rr
        self.rec.log("behaviour/layer", rr.Scalars([float(b.layer)]))
        self.rec.log("behaviour/reason", rr.Scalars([float(b.reason)]))
        self.rec.log("behaviour/flags", rr.Scalars([float(b.flags)]))
        self.rec.log("behaviour/command/steer_deg", rr.Scalars([math.degrees(b.steer_rad)]))
        self.rec.log("behaviour/command/speed_m_s", rr.Scalars([b.speed_m_s]))

    def log_layer_change(self, b: BehaviourState) -> None:
        names = ",".join(flag_names(b.flags)) or "-"
        self.log_text(f"layer {LAYER_NAMES.get(b.layer, b.layer)} reason {REASON_NAMES.get(b.reason, b.reason)} "
                      f"flags {names}", level="INFO")

    def log_text(self, text: str, level: str = "INFO") -> None:
        self.rec.log("log", self.rr.TextLog(text, level=level))

    def close(self) -> None:
        """Flush and finish the recording; for a file recording, write it: OSError when it cannot be
        written (no file is left then)."""
        try:
            self.rec.flush(timeout_sec=5.0)
        except TypeError:
            self.rec.flush()
        data = self._stream.read(flush=True, flush_timeout_sec=5.0) if self._stream is not None else None
        disc = getattr(self.rec, "disconnect", None)
        if disc is not None:
            disc()
        if self._stream is None or self.path is None:
            return
        data = (data or b"") + (self._stream.read(flush=False) or b"")  # the end of the stream, written by the disconnect
        self._stream = None
        try:
            with open(self.path, "wb") as f:
                f.write(data)
        except OSError:
            self.path.unlink(missing_ok=True)
            raise


def record_tlog(tlog: str | Path, rrd: str | Path) -> Path:
    """Turn a .tlog into an .rrd (pose, path, sonar, behaviour, status texts) for ``rerun``."""
    from ..link.state import RobotState
    from ..link.tlog import LogClock, host_systems, read_tlog

    hosts = host_systems(tlog)
    rec = Recorder.to_file(rrd)
    st = RobotState()
    clock = LogClock()
    last_layer: tuple[int, int] | None = None
    for t, m in read_tlog(tlog):
        rel = clock.tick(t)
        if m.get_srcSystem() in hosts:  # the ground station's own frames
            if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" and m.coordinate_frame == 1:
                rec.log_goal(m.x, -m.y)
            continue
        rec.set_time(rel)
        st.update(m, t)
        mt = m.get_type()
        if mt in ("AGNAV_ODOMETRY", "LOCAL_POSITION_NED") and st.pose is not None:
            rec.log_pose(st.pose)
        elif mt == "AGNAV_SONAR_RING" and st.sonar is not None:
            rec.log_sonar(st.sonar, st.pose)
        elif mt == "AGNAV_BEHAVIOUR_STATUS" and st.behaviour is not None:
            rec.log_behaviour(st.behaviour)
            key = (st.behaviour.layer, st.behaviour.reason)
            if key != last_layer:
                last_layer = key
                rec.log_layer_change(st.behaviour)
        elif mt == "STATUSTEXT":
            rec.log_text(st.statustexts[-1].text, level="WARN" if m.severity <= 4 else "INFO")
    rec.close()
    return Path(rrd)


def record_run(trajectory: np.ndarray, goals: Iterable[tuple[float, float]], rrd: str | Path,
               world_segments: np.ndarray | None = None, app_id: str = "agnav-sim") -> Path:
    """A simulator run as an .rrd: the true pose and path over time (``trajectory`` rows in
    ``sim.runner.TRAJECTORY_COLUMNS`` order), the goals and, when given, the world's wall segments
    ((n, 4) x0, y0, x1, y1 in m). Raises VizUnavailable when rerun-sdk is missing."""
    rec = Recorder.to_file(rrd, app_id=app_id)
    rr = rec.rr
    if world_segments is not None and len(world_segments):
        segs = [[[float(s[0]), float(s[1])], [float(s[2]), float(s[3])]] for s in np.asarray(world_segments)]
        rec.rec.log("world/walls", rr.LineStrips2D(segs, colors=[(60, 60, 60)]), static=True)
    for gx, gy in goals:
        rec.log_goal(gx, gy)
    for row in np.asarray(trajectory):
        rec.set_time(float(row[0]))
        rec.log_pose(PoseState(time_boot_s=float(row[0]), x_m=float(row[1]), y_m=float(row[2]), yaw_rad=float(row[3]),
                               speed_m_s=float(row[4]), yaw_rate_rad_s=float(row[5]), rx_time_s=float(row[0])))
    rec.close()
    return Path(rrd)
