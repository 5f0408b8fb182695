"""rerun recordings of runs (see the package docstring)."""

from __future__ import annotations

import math
import os
import struct
import warnings
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from ..link.state import LAYER_NAMES, REASON_NAMES, BehaviourState, PoseState, SonarState, flag_names
from ..streamfile import StreamedFile, StreamFile

__all__ = ["Recorder", "VizUnavailable", "require_rerun", "record_tlog", "RERUN_PIN"]

RERUN_PIN = "rerun-sdk==0.41.0"
SONAR_HALF_CONE_RAD = math.radians(15.0)
PATH_PIECE = 64  # points per logged piece of the driven path
LAYER_COLOURS = {0: (128, 128, 128), 1: (220, 30, 30), 2: (240, 140, 0), 3: (160, 60, 200), 4: (40, 160, 220),
                 5: (40, 180, 80), 6: (30, 90, 220)}


# rerun's stream (rerun-sdk 0.41): every read of a binary stream is a whole RRD stream of its own, a 12-byte
# header ("RRF2", version, options), messages of a 16-byte header (kind, payload length: two uint64) and their
# payload, an End message (kind 0, rerun's index of that piece) and a 32-byte footer ending in "RRF2FOOT" and a
# uint32. The messages of one piece after another, behind one header, are one stream that rerun loads.
_RRD_FOURCC = b"RRF2"
_RRD_HEADER = 12
_RRD_MSG = struct.Struct("<QQ")
_RRD_FOOTER = 32
_RRD_FOOTER_TAG = b"RRF2FOOT"


def rrd_messages(piece: bytes) -> tuple[bytes, list[bytes]]:
    """Split one read of rerun's binary stream into its stream header and its messages, each whole (without
    the piece's End message and footer). ValueError when the bytes are not laid out so (another rerun)."""
    if len(piece) < _RRD_HEADER or piece[:4] != _RRD_FOURCC:
        raise ValueError(f"rerun's stream does not start with {_RRD_FOURCC!r}")
    at, end = _RRD_HEADER, len(piece)
    messages: list[bytes] = []
    while at < end:
        if at + _RRD_MSG.size > end:
            raise ValueError(f"rerun's stream ends inside a message header at byte {at}")
        kind, length = _RRD_MSG.unpack_from(piece, at)
        if at + _RRD_MSG.size + length > end:
            raise ValueError(f"rerun's message at byte {at} ({length} B) runs past the piece ({end} B)")
        if kind == 0:  # End: its index, then the footer close the piece
            tail = at + _RRD_MSG.size + length
            if end - tail != _RRD_FOOTER or piece[end - 12:end - 4] != _RRD_FOOTER_TAG:
                raise ValueError(f"rerun's stream has {end - tail} B after its End message, not its footer")
            return piece[:_RRD_HEADER], messages
        messages.append(piece[at:at + _RRD_MSG.size + length])
        at += _RRD_MSG.size + length
    return piece[:_RRD_HEADER], messages


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
        self._out: StreamFile | None = None  # streaming_to: the file the stream's messages go to as they come
        self._header = False  # streaming_to: the stream header is on its way to the file
        self.app_id = "agnav"
        self.result: StreamedFile | None = None  # streaming_to: what close() left on the disk
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
    def streaming_to(cls, path: str | Path, app_id: str = "agnav",
                     on_error: Callable[[str], None] | None = None) -> "Recorder":
        """A recording streamed to ``path`` as it is logged (a robot run of hours is not held in memory): rerun
        encodes into memory, and every :meth:`set_time` moves what it has encoded, whole messages, to the file
        (a :class:`~agnav_host.streamfile.StreamFile`). Opening the file raises OSError. A disk that fills
        during the run ends the recording on its last whole message, said once (a warning and ``on_error``),
        and the run goes on; :meth:`close` then leaves the cut file (``result.partial``), which rerun loads
        (``rerun.chunk.RrdReader(path).stream()``; it lacks rerun's index). A recording that ends whole is
        rewritten at close with rerun's index (``rerun rrd verify`` passes), through a temporary file renamed
        over it, when the disk has room for it (twice its size and 1 MiB); otherwise the streamed file stays."""
        rr = require_rerun()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        out = StreamFile(p, "recording", on_error=on_error)  # fails now, not during the run, on a folder it cannot write
        rec = rr.RecordingStream(app_id)
        r = cls(rec, rr, None)
        r.path = p
        r.app_id = app_id
        r._out = out
        r._stream = rec.binary_stream()
        return r

    @classmethod
    def spawn(cls, app_id: str = "agnav") -> "Recorder":
        """Live viewer (spawns ``rerun``); nothing is saved (use :meth:`to_file` for a recording)."""
        rr = require_rerun()
        rec = rr.RecordingStream(app_id)
        rec.spawn()
        return cls(rec, rr)

    def set_time(self, t_s: float) -> None:
        if self._out is not None:
            self._pump(self._stream.read(flush=False))
        self.rec.set_time("time", duration=float(t_s))

    def _pump(self, piece: bytes | None) -> None:
        """One read of rerun's stream to the streamed file: each message a whole record (the first of the file
        with the stream header)."""
        out = self._out
        if not piece or out is None or out.partial:
            return
        try:
            header, messages = rrd_messages(bytes(piece))
        except ValueError as e:
            out.fail(OSError(f"{e} (rerun-sdk {getattr(self.rr, '__version__', '?')}, this recorder reads "
                             f"{RERUN_PIN}'s)"))
            return
        if messages and not self._header:
            self._header = True
            messages[0] = header + messages[0]
        for m in messages:
            out.write(m)

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
        written (no file is left then). For a streamed one (:meth:`streaming_to`) ``result`` says what is on
        the disk; a write error was already said when it happened."""
        try:
            self.rec.flush(timeout_sec=5.0)
        except TypeError:
            self.rec.flush()
        data = self._stream.read(flush=True, flush_timeout_sec=5.0) if self._stream is not None else None
        disc = getattr(self.rec, "disconnect", None)
        if disc is not None:
            disc()
        if self._out is not None:
            self._close_stream(data)
            return
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


    def _close_stream(self, data: bytes | None) -> None:
        out = self._out
        assert out is not None
        self._pump(data)
        self._pump(self._stream.read(flush=False))  # the end of the stream, written by the disconnect
        self._stream = None
        self._out = None
        self.result = out.close()
        if self.result.kept and not self.result.partial:
            self._index(self.result.path)

    def _index(self, path: Path) -> None:
        """Rewrite a whole streamed recording with rerun's index, through a temporary file renamed over it; on
        any failure the streamed file stays as it is (rerun loads it without the index)."""
        import shutil

        tmp = path.with_name(f".{path.name}.part")
        try:
            # the rewrite may come out larger than the stream; short of room rerun's writer fails noisily on
            # stderr, so it is not tried
            if shutil.disk_usage(path.parent).free < 2 * path.stat().st_size + (1 << 20):
                return
            from rerun.chunk import RrdReader

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "no footer/manifest": the file is read whole, as streamed
                store = RrdReader(path).stream().collect()
            store.write_rrd(tmp, application_id=self.app_id, recording_id=str(self.rec.get_recording_id()))
            os.replace(tmp, path)
        except Exception:  # noqa: BLE001  (rerun's reader raises RuntimeError, the disk OSError: keep the stream)
            tmp.unlink(missing_ok=True)
            return
        self.result = StreamedFile(path, path.stat().st_size, self.result.records if self.result else 0)


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
