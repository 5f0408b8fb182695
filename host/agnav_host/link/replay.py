"""Summaries of .tlog files (``agnav replay``): duration, messages and bytes per type and direction,
telemetry rate against the budget, time per behaviour layer, e-stops, status texts, path length."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..units import cdeg_to_rad, milli_to_si

from .state import LAYER_NAMES, REASON_NAMES
from .tlog import MAV_TYPE_GCS, LogClock, read_tlog

__all__ = ["TlogSummary", "TlogError", "summarize_tlog"]


class TlogError(ValueError):
    """The log path is not a readable file (missing, a directory, no permission)."""


@dataclass
class TlogSummary:
    path: str
    duration_s: float = 0.0
    breaks: int = 0  # jumps in the log's stamps left out of the times (clock set, runs appended)
    rx_msgs: Counter[str] = field(default_factory=Counter)
    tx_msgs: Counter[str] = field(default_factory=Counter)
    rx_bytes: int = 0
    tx_bytes: int = 0
    layer_time_s: dict[str, float] = field(default_factory=dict)
    layer_changes: list[tuple[float, str, str]] = field(default_factory=list)
    statustexts: list[tuple[float, str]] = field(default_factory=list)
    path_length_m: float = 0.0
    final_pose: tuple[float, float, float] | None = None
    poses: list[tuple[float, float, float, float]] = field(default_factory=list)  # t, x, y, yaw
    layers: list[tuple[float, int]] = field(default_factory=list)  # t, layer
    file_bytes: int = 0  # size of the file
    undecoded_bytes: int = 0  # bytes that were not a frame with its 8-byte time stamp (skipped: corrupt, not a tlog)

    @property
    def undecoded_fraction(self) -> float:
        """Share of the file, 0..1, that was not MAVLink frames."""
        return self.undecoded_bytes / self.file_bytes if self.file_bytes else 0.0

    @property
    def rx_rate_bytes_s(self) -> float:
        return self.rx_bytes / self.duration_s if self.duration_s > 0 else 0.0

    def text(self, budget_bytes_s: float = 1500.0) -> str:
        out = [f"{self.path}: {self.duration_s:.1f} s, received {sum(self.rx_msgs.values())} frames / "
               f"{self.rx_bytes} B ({self.rx_rate_bytes_s:.0f} B/s, budget {budget_bytes_s:.0f} B/s"
               f"{', OVER' if self.rx_rate_bytes_s > budget_bytes_s else ''}), sent {sum(self.tx_msgs.values())} "
               f"frames / {self.tx_bytes} B"]
        if self.undecoded_bytes:
            out.append(f"{self.undecoded_bytes} B of {self.file_bytes} ({100 * self.undecoded_fraction:.1f} %) could not "
                       "be decoded as MAVLink frames and were skipped (a corrupt log, or not a telemetry log)")
        if self.breaks:
            out.append(f"({self.breaks} break(s) in the time stamps - the clock set, or runs appended to one file - "
                       "left out of the times)")
        out.append("received:")
        for k, n in self.rx_msgs.most_common():
            out.append(f"  {k:28s} {n:7d}  {n / self.duration_s if self.duration_s else 0:6.1f} Hz")
        if self.tx_msgs:
            out.append("sent:")
            for k, n in self.tx_msgs.most_common():
                out.append(f"  {k:28s} {n:7d}")
        if self.layer_time_s:
            out.append("time per behaviour layer:")
            for k, v in sorted(self.layer_time_s.items(), key=lambda kv: -kv[1]):
                out.append(f"  {k:16s} {v:7.1f} s")
        if self.layer_changes:
            out.append(f"layer changes: {len(self.layer_changes)} (first 10)")
            for t, layer, reason in self.layer_changes[:10]:
                out.append(f"  t={t:7.2f} s  {layer} ({reason})")
        for t, s in self.statustexts[:20]:
            out.append(f"statustext t={t:7.2f} s: {s}")
        if self.final_pose is not None:
            x, y, yaw = self.final_pose
            out.append(f"path {self.path_length_m:.2f} m, final pose x={x:.2f} m y={y:.2f} m yaw={math.degrees(yaw):.1f} deg")
        return "\n".join(out)


def _check_readable(path: str | Path) -> None:
    p = Path(path)
    if p.is_dir():
        raise TlogError(f"{p}: is a directory, not a .tlog file")
    if not p.exists():
        raise TlogError(f"{p}: no such file")
    try:
        with open(p, "rb"):
            pass
    except OSError as e:
        raise TlogError(f"{p}: cannot read: {e.strerror or e}") from None


def summarize_tlog(path: str | Path, host_sysid: int | None = None,
                   progress: Callable[[int, int], None] | None = None) -> TlogSummary:
    """Summary of one .tlog in one pass over it; :class:`TlogError` when ``path`` is not a readable file.
    The host's frames (``host_sysid``; by default the systems that sent ground-station heartbeats anywhere
    in the log) count as sent. Times run from the first frame, with any break in the stamps left out
    (:class:`~.tlog.LogClock`). ``progress(bytes read, file bytes)``: see :func:`~.tlog.read_tlog`."""
    _check_readable(path)
    s = TlogSummary(str(path), file_bytes=Path(path).stat().st_size)
    frame_bytes = 0  # every frame with its 8-byte time stamp: the rest of the file was skipped by the reader
    clock = LogClock()
    last_layer: tuple[int, int] | None = None
    last_layer_t = 0.0
    prev_xy: tuple[float, float] | None = None
    # who sent what is settled at the end (a ground station's heartbeat may come after its first frames)
    by_sender: dict[int, Counter[str]] = {}
    bytes_by_sender: Counter[int] = Counter()
    gcs: set[int] = set()
    texts: list[tuple[float, int, str]] = []
    for t, m in read_tlog(path, progress):
        rel = clock.tick(t)
        typ = m.get_type()
        n = len(m.get_msgbuf())
        frame_bytes += n + 8
        src = m.get_srcSystem()
        by_sender.setdefault(src, Counter())[typ] += 1
        bytes_by_sender[src] += n
        if typ == "HEARTBEAT" and m.type == MAV_TYPE_GCS:
            gcs.add(src)
        if src == host_sysid or src in gcs:
            continue
        if typ == "AGNAV_BEHAVIOUR_STATUS":
            key = (m.active_layer, m.reason)
            name = LAYER_NAMES.get(m.active_layer, str(m.active_layer))
            if last_layer is not None:
                prev = LAYER_NAMES.get(last_layer[0], str(last_layer[0]))
                s.layer_time_s[prev] = s.layer_time_s.get(prev, 0.0) + rel - last_layer_t
            last_layer_t = rel
            if key != last_layer:
                s.layer_changes.append((rel, name, REASON_NAMES.get(m.reason, str(m.reason))))
                s.layers.append((rel, m.active_layer))
            last_layer = key
        elif typ == "AGNAV_ODOMETRY":
            x, y, yaw = milli_to_si(m.x_mm), milli_to_si(m.y_mm), cdeg_to_rad(m.yaw_cdeg)
            if prev_xy is not None:
                s.path_length_m += math.hypot(x - prev_xy[0], y - prev_xy[1])
            prev_xy = (x, y)
            s.final_pose = (x, y, yaw)
            s.poses.append((rel, x, y, yaw))
        elif typ == "STATUSTEXT":
            txt = m.text if isinstance(m.text, str) else m.text.decode("ascii", "replace")
            texts.append((rel, src, txt.split("\x00", 1)[0]))
    hosts = {host_sysid} if host_sysid is not None else (gcs or {255})
    for src, counts in by_sender.items():
        if src in hosts:
            s.tx_msgs.update(counts)
            s.tx_bytes += bytes_by_sender[src]
        else:
            s.rx_msgs.update(counts)
            s.rx_bytes += bytes_by_sender[src]
    s.statustexts = [(rel, txt) for rel, src, txt in texts if src not in hosts]
    s.duration_s = clock.rel_s
    s.breaks = clock.breaks
    s.undecoded_bytes = max(0, s.file_bytes - frame_bytes)
    return s
