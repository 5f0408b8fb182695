"""The laser log (``.alog``): every scan of a run's lasers, streamed to disk, read back and replayed as a laser.

Format ``agnav-laserlog v1`` (all numbers little-endian)::

    # agnav-laserlog v1\\n                         the header line, 20 bytes of ASCII
    record, record, ...                            to the end of the file

    record   = tag (4 bytes of ASCII) | length (uint32: bytes of payload) | payload
    LASR     = UTF-8 JSON declaring one laser, written once before its first scan:
               {"id": int 0..65535, "url": str, "kind": str, "model": str,
                "mount": {"x_m", "y_m", "yaw_rad", "pitch_rad", "height_m"},
                "angle_min_rad": float, "angle_increment_rad": float, "n_beams": int >= 1,
                "range_max_m": float > 0 or null (no stated limit),
                "stamps": "device" | "arrival", "latency_s": float >= 0}
    SCAN     = laser id (uint16) | stamp_s (float64) | n (uint32)        struct "<HdI", 14 bytes
               | n ranges (uint16, millimetres; 0 = no return)
               | optional pose block: flag (uint8) and, if the flag is 1,
                 x_m, y_m, yaw_rad (3 x float64, struct "<ddd")

``stamp_s`` is the scan's stamp on the run's clock: seconds since the run started. The pose block gives the
robot's believed pose (the world / odometry frame) at the scan; the writer always writes the flag (0: no
pose), a reader also takes a SCAN that ends after its ranges. Ranges are rounded to the millimetre; NaN, inf,
0, a negative range and anything that rounds to 65535 mm or more (65.535 m) are written as 0, no return
(65535 itself is never written; a reader takes it for no return too). A SCAN's ``n`` must equal the
``n_beams`` of its laser's newest declaration: a laser whose geometry changes (a reconnect in another mode)
is declared again with the same id, and the scans after it use the new declaration. Readers ignore JSON keys
they do not know.

The writer (:class:`LaserLogWriter`) truncates an existing file, writes through a buffer and flushes at least
every 0.5 s (of scan time and of wall-clock time), so a crash loses at most the last half second. A full disk
(or any write error) does not end the run: the log is cut back to its last whole record, the error is said
once (:class:`~agnav_host.streamfile.StreamFile`) and later scans are dropped. A run killed mid-write leaves a
truncated last record: the readers ignore it and count it (``LaserLogReader.truncated_bytes``). Anything else that breaks the format (an unknown tag, bad JSON, ``n``
other than the declared ``n_beams``, a SCAN before its LASR, a length that fits no record) raises
:class:`LaserLogError` naming the file, the byte offset of the record and what is wrong; a file that is
not a laser log at all raises its subclass :class:`NotALaserLogError` saying what it looks like.

Reading: :func:`read_laser_log` streams :class:`LogScan` records (one scan in memory at a time);
:func:`laser_log_info` reads the declarations, scan counts and time spans (and so checks the whole file).

Replay: ``replay:FILE[?laser=ID&rate=R]`` opens :class:`LaserLogReplay`, a :class:`~.base.LaserSource`. It
delivers the scans of one laser (``laser=ID``; default: the first declared) stamped on ``time.monotonic()``:
scan k is due, and stamped, at ``start + (t_k - t_0) / rate`` (``rate=1``, the default, is the log's own
timing; ``rate=10`` ten times faster). ``rate=0`` replays as fast as the caller takes scans: every
:meth:`~LaserLogReplay.latest` returns the next scan, stamped with the time of the call. The mount passed
to the replay (from the URL's config) replaces the logged mount only when it is given explicitly, i.e. is
not the default ``LaserMount()``; otherwise the replay's ``mount`` is the newest logged one. Like a device,
replayed scans carry no pose (``LogScan.pose`` has it); :attr:`~LaserLogReplay.last_log_t_s` is the log time
of the scan returned last. At the end of the log ``latest()`` returns None for ever and
:attr:`~LaserLogReplay.finished` is True.
"""

from __future__ import annotations

import json
import math
import struct
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable

import numpy as np

from ..streamfile import StreamedFile, StreamFile
from ..types import LaserScan, Pose2D
from .base import LaserAddressError, LaserInfo, LaserMount, LaserStats, TelegramError, WrongDeviceError

__all__ = ["MAGIC", "SUFFIX", "LaserLogError", "NotALaserLogError", "LaserDecl", "LogScan", "LaserLogWriter",
           "LaserLogReader", "read_laser_log", "LaserLogInfo", "laser_log_info", "is_laser_log", "LaserLogReplay"]

MAGIC = b"# agnav-laserlog v1\n"
SUFFIX = ".alog"
_MAGIC_STEM = b"# agnav-laserlog v"
_REC = struct.Struct("<4sI")  # tag, payload length
_SCAN = struct.Struct("<HdI")  # laser id, stamp_s, n
_POSE = struct.Struct("<ddd")
_TAG_LASR = b"LASR"
_TAG_SCAN = b"SCAN"
_MAX_DECL_BYTES = 1 << 20  # a declaration is a few hundred bytes: a longer one is a broken length field
_NO_RETURN_MM = 65535  # ranges that round to this or more are written as 0 (no return)
_STAMPS = ("device", "arrival")
_MOUNT_KEYS = ("x_m", "y_m", "yaw_rad", "pitch_rad", "height_m")


class LaserLogError(ValueError):
    """A laser log breaks its format; the message names the file, the byte offset and what is wrong."""

    def __init__(self, path: str | Path, offset: int | None, what: str) -> None:
        self.path = str(path)
        self.offset = offset
        self.what = what
        super().__init__(f"{path}: byte {offset}: {what}" if offset is not None else f"{path}: {what}")


class NotALaserLogError(LaserLogError):
    """The file is not a laser log at all (another file, another version); the message says what it looks like."""


@dataclass(frozen=True)
class LaserDecl:
    """One laser as a LASR record declares it (``offset``: the record's byte offset in the file)."""

    id: int
    url: str
    kind: str
    model: str
    mount: LaserMount
    angle_min_rad: float
    angle_increment_rad: float
    n_beams: int
    range_max_m: float  # inf when the log states no limit
    stamps: str
    latency_s: float
    offset: int = 0


@dataclass(frozen=True)
class LogScan:
    """One logged scan. ``scan`` is in the sensor frame (NaN for no return, ``stamp_s = t_s``; its ``pose`` is
    the sensor's world pose, the robot pose composed with the planar mount, when ``pose`` is known); ``pose``
    is the robot's believed pose at the scan; ``laser`` the declaration in force."""

    laser_id: int
    t_s: float
    scan: LaserScan
    pose: Pose2D | None
    laser: LaserDecl


# ---- writing ------------------------------------------------------------------------------------------------


def _mm(ranges_m: Any) -> np.ndarray:
    r = np.asarray(ranges_m, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        mm = np.rint(r * 1000.0)
        ok = np.isfinite(mm) & (mm > 0) & (mm < _NO_RETURN_MM)
    return np.where(ok, mm, 0.0).astype("<u2")


def _range_max_json(v: float) -> float | None:
    return float(v) if math.isfinite(v) and v > 0 else None


class LaserLogWriter:
    """Writes a laser log to ``path`` (an existing file is truncated; missing folders are made).

    :meth:`declare` each laser once before its scans, then :meth:`write` every scan; :meth:`close` at the end
    (or use it as a context manager). A scan whose geometry (beam count, first angle, increment, range limit)
    differs from its laser's declaration re-declares the laser first, with the same url, kind, model, mount
    and stamps. The file is flushed at least every ``flush_s`` of scan time and of wall-clock time. Opening
    the file raises OSError; a write error later stops the log on its last whole record, said once (a
    warning, and ``on_error``), and the writer takes no more (``stopped``; :meth:`close` returns the
    :class:`~agnav_host.streamfile.StreamedFile`, ``partial`` then). A call with bad arguments (an undeclared
    laser, a non-finite time) raises ValueError. Safe to call from several threads.
    """

    def __init__(self, path: str | Path, flush_s: float = 0.5, on_error: Callable[[str], None] | None = None) -> None:
        self.path = Path(path)
        self.flush_s = flush_s
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # whole records only: a full disk cuts the log at a record boundary (the time rule below flushes it)
        self._f: StreamFile | None = StreamFile(self.path, "laser log", flush_s=None, on_error=on_error)
        self._lock = threading.Lock()
        self._decl: dict[int, dict[str, Any]] = {}
        self.scans_written = 0
        self._flushed_wall = time.monotonic()
        self._flushed_t: float | None = None
        self.result: StreamedFile | None = None  # set by close()
        self._f.write(MAGIC)

    def __enter__(self) -> "LaserLogWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def stopped(self) -> bool:
        """True once a write error ended the log (the file ends on its last whole record)."""
        return self._f is not None and self._f.partial

    def _file(self) -> StreamFile:
        if self._f is None:
            raise ValueError(f"{self.path}: the laser log is closed")
        return self._f

    def declare(self, laser_id: int, url: str, kind: str, model: str, mount: LaserMount, scan_template: LaserScan,
                stamps: str = "arrival", latency_s: float = 0.0) -> None:
        """Declare (or re-declare) laser ``laser_id``: its URL, kind, model, mount, and the geometry of
        ``scan_template`` (first angle, increment, beam count, range limit). Flushed at once."""
        if not (isinstance(laser_id, int) and 0 <= laser_id <= 0xFFFF):
            raise ValueError(f"laser id must be a whole number 0..65535, got {laser_id!r}")
        if stamps not in _STAMPS:
            raise ValueError(f"stamps must be one of {', '.join(_STAMPS)}, got {stamps!r}")
        if not (math.isfinite(latency_s) and latency_s >= 0):
            raise ValueError(f"latency_s must be a finite number >= 0, got {latency_s!r}")
        n = len(scan_template.ranges_m)
        if n < 1:
            raise ValueError(f"laser {laser_id}: the template scan has no beams")
        a0, inc = float(scan_template.angle_min_rad), float(scan_template.angle_increment_rad)
        if not (math.isfinite(a0) and math.isfinite(inc)):
            raise ValueError(f"laser {laser_id}: the template scan's angles must be finite, got {a0!r}, {inc!r}")
        d = {"id": laser_id, "url": str(url), "kind": str(kind), "model": str(model),
             "mount": {k: float(getattr(mount, k)) for k in _MOUNT_KEYS},
             "angle_min_rad": a0, "angle_increment_rad": inc, "n_beams": n,
             "range_max_m": _range_max_json(float(scan_template.range_max_m)), "stamps": stamps,
             "latency_s": float(latency_s)}
        with self._lock:
            self._declare_locked(d)

    def _declare_locked(self, d: dict[str, Any]) -> None:
        payload = json.dumps(d, ensure_ascii=False, allow_nan=False).encode("utf-8")
        f = self._file()
        f.write(_REC.pack(_TAG_LASR, len(payload)) + payload)
        f.flush()
        self._flushed_wall = time.monotonic()
        self._decl[d["id"]] = d

    def declare_source(self, laser_id: int, source: Any, info: LaserInfo, scan_template: LaserScan) -> None:
        """:meth:`declare` from a started :class:`~.base.LaserSource` and the :class:`LaserInfo` its start returned."""
        self.declare(laser_id, source.url, info.kind, info.model, source.mount, scan_template, info.stamps,
                     info.latency_s)

    def write(self, laser_id: int, scan: LaserScan, t_s: float, pose: Pose2D | None = None) -> None:
        """Append one scan of declared laser ``laser_id`` at run time ``t_s`` (s since the run started), with
        the robot's believed pose when known (a pose with a non-finite value is written as unknown)."""
        t = float(t_s)
        if not math.isfinite(t):
            raise ValueError(f"laser {laser_id}: the scan time must be finite, got {t_s!r}")
        ranges = _mm(scan.ranges_m)
        n = len(ranges)
        has_pose = pose is not None and all(math.isfinite(v) for v in (pose.x_m, pose.y_m, pose.yaw_rad))
        tail = b"\x01" + _POSE.pack(pose.x_m, pose.y_m, pose.yaw_rad) if has_pose and pose is not None else b"\x00"
        with self._lock:
            f = self._file()
            d = self._decl.get(laser_id)
            if d is None:
                raise ValueError(f"laser {laser_id} written before it was declared (declare() it first)")
            angle_min, angle_inc = float(scan.angle_min_rad), float(scan.angle_increment_rad)
            geometry = {"angle_min_rad": angle_min, "angle_increment_rad": angle_inc,
                        "n_beams": n, "range_max_m": _range_max_json(float(scan.range_max_m))}
            if any(d[k] != v for k, v in geometry.items()):  # a new mode: declare the new geometry first
                if n < 1 or not (math.isfinite(angle_min) and math.isfinite(angle_inc)):
                    raise ValueError(f"laser {laser_id}: a scan needs beams and finite angles, got {n} beams from "
                                     f"{scan.angle_min_rad!r} by {scan.angle_increment_rad!r}")
                self._declare_locked({**d, **geometry})
            f.write(_REC.pack(_TAG_SCAN, _SCAN.size + 2 * n + len(tail)) + _SCAN.pack(laser_id, t, n)
                    + ranges.tobytes() + tail)
            self.scans_written += 1
            now = time.monotonic()
            if self._flushed_t is None:
                self._flushed_t = t
            if now - self._flushed_wall >= self.flush_s or abs(t - self._flushed_t) >= self.flush_s:
                f.flush()
                self._flushed_wall, self._flushed_t = now, t

    def flush(self) -> None:
        with self._lock:
            self._file().flush()
            self._flushed_wall = time.monotonic()

    def close(self) -> StreamedFile:
        """Flush and close; idempotent. What is on the disk: its size, and ``partial`` when a write error
        stopped the log (a log that never got a whole record is removed, ``size_bytes`` 0)."""
        with self._lock:
            f, self._f = self._f, None
        if f is not None:
            self.result = f.close()
        assert self.result is not None
        return self.result


# ---- reading ------------------------------------------------------------------------------------------------


def _looks_like(head: bytes) -> str:
    """What a file that is not a laser log looks like, from its first bytes."""
    if not head:
        return "an empty file"
    if head.startswith(b"\xef\xbb\xbf"):
        head = head[3:]
    if head.startswith(b"# agnav-scan v1"):
        return "a one-scan CSV (agnav-scan v1)"
    if head.startswith(b"\x1f\x8b"):
        return "a gzip file (unpack it first)"
    if head.startswith(b"PK\x03\x04"):
        return "a zip file (unpack it first)"
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        text = ""
    if text and all(c.isprintable() or c in "\r\n\t" for c in text):
        line = text.splitlines()[0] if text.splitlines() else text
        return f"text starting {line[:40]!r}"
    return f"binary data starting {head[:8].hex(' ')}"


def _check_header(f: IO[bytes], path: Path) -> None:
    head = f.read(len(MAGIC))
    if head == MAGIC:
        return
    if head.startswith(_MAGIC_STEM):
        rest = head + f.read(16)
        if rest.startswith(MAGIC[:-1] + b"\r\n"):
            raise NotALaserLogError(path, None, "the header line ends in CR LF: the laser log was copied as text, "
                                                "which corrupts its binary records; copy it as binary")
        version = rest[len(_MAGIC_STEM):].split(b"\n", 1)[0].decode("ascii", "replace")
        raise NotALaserLogError(path, None, f"a laser log of version v{version}; this reader reads v1")
    if MAGIC.startswith(head) and head:
        raise NotALaserLogError(path, None, f"a laser log cut off in its header line ({len(head)} bytes): the run "
                                            "ended before its first scan")
    raise NotALaserLogError(path, None, f"{_looks_like(head + f.read(64))}, not a laser log "
                                        f"(which starts {MAGIC.decode().strip()!r})")


def is_laser_log(path: str | Path) -> bool:
    """True when the file starts like a laser log (any version); False for anything else, unreadable included."""
    try:
        with open(path, "rb") as f:
            return f.read(len(_MAGIC_STEM)) == _MAGIC_STEM
    except OSError:
        return False


def _num(d: dict[str, Any], key: str, where: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{where}{key} must be a finite number, got {v!r}")
    return float(v)


def _parse_decl(payload: bytes, offset: int) -> LaserDecl:
    """A LASR payload as a declaration; ValueError says what is wrong."""
    try:
        d = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"LASR declaration is not UTF-8 JSON ({e})") from None
    if not isinstance(d, dict):
        raise ValueError(f"LASR declaration must be a JSON object, got {type(d).__name__}")
    missing = [k for k in ("id", "url", "kind", "model", "mount", "angle_min_rad", "angle_increment_rad", "n_beams",
                           "range_max_m", "stamps", "latency_s") if k not in d]
    if missing:
        raise ValueError(f"LASR declaration lacks {', '.join(missing)}")
    lid = d["id"]
    if isinstance(lid, bool) or not isinstance(lid, int) or not 0 <= lid <= 0xFFFF:
        raise ValueError(f"LASR id must be a whole number 0..65535, got {lid!r}")
    for k in ("url", "kind", "model"):
        if not isinstance(d[k], str):
            raise ValueError(f"LASR {k} must be a string, got {d[k]!r}")
    m = d["mount"]
    if not isinstance(m, dict):
        raise ValueError(f"LASR mount must be an object with {', '.join(_MOUNT_KEYS)}, got {m!r}")
    mount = LaserMount(**{k: _num(m, k, "LASR mount.") for k in _MOUNT_KEYS})  # ValueError for a bad mount
    n = d["n_beams"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"LASR n_beams must be a whole number >= 1, got {n!r}")
    rmax = d["range_max_m"]
    if rmax is None:
        rmax_m = math.inf
    else:
        rmax_m = _num(d, "range_max_m", "LASR ")
        if rmax_m <= 0:
            raise ValueError(f"LASR range_max_m must be > 0 or null, got {rmax!r}")
    if d["stamps"] not in _STAMPS:
        raise ValueError(f"LASR stamps must be \"device\" or \"arrival\", got {d['stamps']!r}")
    lat = _num(d, "latency_s", "LASR ")
    if lat < 0:
        raise ValueError(f"LASR latency_s must be >= 0, got {lat!r}")
    return LaserDecl(lid, d["url"], d["kind"], d["model"], mount, _num(d, "angle_min_rad", "LASR "),
                     _num(d, "angle_increment_rad", "LASR "), n, rmax_m, d["stamps"], lat, offset)


class LaserLogReader:
    """Streams the scans of a laser log (see the module docstring); made by :func:`read_laser_log`.

    Iterate it for :class:`LogScan` records (only laser ``laser_id``'s when given). The file is opened and its
    header checked on construction (OSError, :class:`NotALaserLogError`); a broken record raises
    :class:`LaserLogError` when reached (``decode=False`` leaves the ranges empty: for counting and checking).
    ``truncated_bytes`` is the size of a cut-off last record that was ignored (0: none; ``truncated`` counts
    such records, 0 or 1); ``declarations`` lists the LASR records read so far. The file is closed at the end,
    on an error or by :meth:`close`.
    """

    def __init__(self, path: str | Path, laser_id: int | None = None, *, decode: bool = True) -> None:
        self.path = Path(path)
        self.laser_id = laser_id
        self.decode = decode
        self.declarations: list[LaserDecl] = []
        self.truncated = 0
        self.truncated_bytes = 0
        self.offset = 0  # where the next record starts
        self._decl: dict[int, LaserDecl] = {}
        self._f: IO[bytes] | None = open(self.path, "rb", buffering=1 << 16)  # noqa: SIM115 (closed in close())
        try:
            _check_header(self._f, self.path)
        except BaseException:
            self.close()
            raise
        self.offset = len(MAGIC)

    def __iter__(self) -> "LaserLogReader":
        return self

    def __enter__(self) -> "LaserLogReader":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        f, self._f = self._f, None
        if f is not None:
            f.close()

    def _error(self, offset: int, what: str) -> LaserLogError:
        self.close()
        return LaserLogError(self.path, offset, what)

    def _cut(self, have: int) -> None:
        """A record cut off by the end of the file (``have`` bytes of it there): the run was killed mid-write."""
        self.truncated += 1
        self.truncated_bytes = have
        self.close()

    def __next__(self) -> LogScan:
        rec = self._next_record()
        if rec is None:
            raise StopIteration
        return rec

    def _next_record(self) -> LogScan | None:
        f = self._f
        while f is not None:
            at = self.offset
            head = f.read(_REC.size)
            if not head:
                self.close()
                return None
            if len(head) < _REC.size:
                self._cut(len(head))
                return None
            tag, length = _REC.unpack(head)
            if tag == _TAG_LASR:
                if length > _MAX_DECL_BYTES:
                    raise self._error(at, f"LASR record of {length} bytes, more than {_MAX_DECL_BYTES} (a broken "
                                          "length field)")
                payload = f.read(length)
                if len(payload) < length:
                    self._cut(_REC.size + len(payload))
                    return None
                try:
                    decl = _parse_decl(payload, at)
                except ValueError as e:
                    raise self._error(at, str(e)) from None
                self._decl[decl.id] = decl
                self.declarations.append(decl)
                self.offset = at + _REC.size + length
                continue
            if tag != _TAG_SCAN:
                shown = tag.decode("ascii") if all(32 <= b < 127 for b in tag) else tag.hex(" ")
                raise self._error(at, f"unknown record tag {shown!r} (known: LASR, SCAN)")
            if length < _SCAN.size:
                raise self._error(at, f"SCAN record of {length} bytes, shorter than its {_SCAN.size}-byte header")
            payload = f.read(_SCAN.size)  # the fixed part first: the length is checked before the rest is read
            if len(payload) < _SCAN.size:
                self._cut(_REC.size + len(payload))
                return None
            lid, t, n = _SCAN.unpack(payload)
            if lid not in self._decl:
                raise self._error(at, f"SCAN of laser {lid} before its LASR declaration")
            decl = self._decl[lid]
            if n != decl.n_beams:
                raise self._error(at, f"SCAN of laser {lid} has {n} beams, its declaration (byte {decl.offset}) "
                                      f"says {decl.n_beams}")
            base = _SCAN.size + 2 * n
            if length not in (base, base + 1, base + 1 + _POSE.size):
                raise self._error(at, f"SCAN record of {length} bytes does not fit {n} beams (expected {base}, "
                                      f"{base + 1} or {base + 1 + _POSE.size})")
            payload += f.read(length - _SCAN.size)
            if len(payload) < length:
                self._cut(_REC.size + len(payload))
                return None
            if not math.isfinite(t):
                raise self._error(at, f"SCAN of laser {lid} has a non-finite stamp {t!r}")
            pose = None
            if length > base:
                flag = payload[base]
                if flag not in (0, 1) or (flag == 1) != (length == base + 1 + _POSE.size):
                    raise self._error(at, f"SCAN pose flag {flag} does not match a record of {length} bytes "
                                          f"(flag 0: {base + 1}, flag 1: {base + 1 + _POSE.size})")
                if flag == 1:
                    x, y, yaw = _POSE.unpack_from(payload, base + 1)
                    if not all(math.isfinite(v) for v in (x, y, yaw)):
                        raise self._error(at, f"SCAN pose is not finite: {x!r}, {y!r}, {yaw!r}")
                    pose = Pose2D(x, y, yaw)
            self.offset = at + _REC.size + length
            if self.laser_id is not None and lid != self.laser_id:
                continue
            if self.decode:
                mm = np.frombuffer(payload, dtype="<u2", count=n, offset=_SCAN.size).astype(float)
                ranges = np.where((mm > 0) & (mm < _NO_RETURN_MM), mm / 1000.0, np.nan)
            else:
                ranges = np.empty(0)
            sensor = pose.compose(decl.mount.pose) if pose is not None else None
            scan = LaserScan(decl.angle_min_rad, decl.angle_increment_rad, ranges, decl.range_max_m, t, sensor)
            return LogScan(lid, t, scan, pose, decl)
        return None


def read_laser_log(path: str | Path, laser_id: int | None = None) -> LaserLogReader:
    """Stream the scans of the laser log at ``path`` (all lasers, or only ``laser_id``'s) as :class:`LogScan`
    records; see :class:`LaserLogReader` for the errors and the truncated-tail count."""
    return LaserLogReader(path, laser_id)


@dataclass
class LaserLogInfo:
    """What :func:`laser_log_info` found: every declaration in file order, the first of each laser, scans
    and time span (s, run clock) per laser, the whole log's span, and a cut-off tail's size."""

    path: Path
    size_bytes: int
    declarations: list[LaserDecl] = field(default_factory=list)
    lasers: dict[int, LaserDecl] = field(default_factory=dict)  # first declaration of each, in order
    scans: dict[int, int] = field(default_factory=dict)
    span_s: dict[int, tuple[float, float]] = field(default_factory=dict)  # (first, last) scan time per laser
    t_first_s: float | None = None
    t_last_s: float | None = None
    truncated_bytes: int = 0

    @property
    def first_laser(self) -> int | None:
        """Id of the first declared laser (the replay's and ``agnav rows``'s default), None if none is."""
        return next(iter(self.lasers), None)

    @property
    def duration_s(self) -> float:
        return 0.0 if self.t_first_s is None or self.t_last_s is None else self.t_last_s - self.t_first_s


def laser_log_info(path: str | Path) -> LaserLogInfo:
    """Read the whole log (checking every record, without decoding ranges): declarations, scans per laser and
    time spans. Raises OSError, :class:`NotALaserLogError` or :class:`LaserLogError` like the reader."""
    p = Path(path)
    reader = LaserLogReader(p, decode=False)
    info = LaserLogInfo(p, p.stat().st_size)
    with reader:
        for rec in reader:
            lid, t = rec.laser_id, rec.t_s
            info.scans[lid] = info.scans.get(lid, 0) + 1
            lo, hi = info.span_s.get(lid, (t, t))
            info.span_s[lid] = (min(lo, t), max(hi, t))
            info.t_first_s = t if info.t_first_s is None else min(info.t_first_s, t)
            info.t_last_s = t if info.t_last_s is None else max(info.t_last_s, t)
    info.declarations = list(reader.declarations)
    for d in info.declarations:
        info.lasers.setdefault(d.id, d)
        info.scans.setdefault(d.id, 0)
    info.truncated_bytes = reader.truncated_bytes
    return info


# ---- replay -------------------------------------------------------------------------------------------------


class LaserLogReplay:
    """A laser log replayed as a :class:`~.base.LaserSource` (``replay:FILE?laser=ID&rate=R``; the module
    docstring gives the timing, the stamps and which mount applies). No thread: the file is read as
    :meth:`latest` takes scans. :meth:`start` checks the whole file first: a missing file raises
    LaserAddressError, a file that is no laser log WrongDeviceError, a corrupt one TelegramError; a laser the
    log does not declare LaserAddressError. A log that breaks later (changed under the replay) ends the
    replay, counted in ``stats.malformed``."""

    kind = "replay"

    def __init__(self, url: Any, mount: LaserMount | None = None) -> None:
        from . import LaserUrl, LaserUrlError, parse_laser_url

        u: LaserUrl = url if isinstance(url, LaserUrl) else parse_laser_url(str(url))
        self.url = u.text
        self.path = Path(u.path).expanduser()
        unknown = [k for k, _ in u.options if k not in ("laser", "rate")]
        if unknown:
            raise LaserUrlError(f"--laser {u.text!r}: unknown option {unknown[0]!r}; replay takes laser=ID and rate=R")
        self.laser_id: int | None = None
        lid = u.option("laser")
        if lid is not None:
            if not lid.isdigit() or int(lid) > 0xFFFF:
                raise LaserUrlError(f"--laser {u.text!r}: laser= takes a laser id, a whole number 0..65535, got {lid!r}")
            self.laser_id = int(lid)
        rate_text = u.option("rate", "1") or ""
        try:
            rate = float(rate_text)
        except ValueError:
            rate = math.nan
        if not (math.isfinite(rate) and rate >= 0):
            raise LaserUrlError(f"--laser {u.text!r}: rate= takes a number >= 0 (1 = the log's timing, 0 = as fast "
                                f"as scans are taken), got {rate_text!r}")
        self.rate = rate
        self._explicit_mount = mount is not None and mount != LaserMount()
        self.mount = mount or LaserMount()
        self.stats = LaserStats()
        self.info: LaserInfo | None = None
        self.log_info: LaserLogInfo | None = None
        self.declaration: LaserDecl | None = None
        self.last_log_t_s: float | None = None
        self.truncated_bytes = 0
        self._reader: LaserLogReader | None = None
        self._pending: LogScan | None = None
        self._t0_host = 0.0
        self._t0_log = 0.0
        self._finished = False
        self._started = False

    @property
    def finished(self) -> bool:
        """True once the log's last scan of the laser was delivered (or the replay was closed or broke)."""
        return self._finished

    def start(self, timeout_s: float = 5.0) -> LaserInfo:
        """Check the log, pick the laser, and start the replay's clock (a second call returns the same info;
        after :meth:`close` it starts over from the log's first scan)."""
        if self.info is not None and self._started:
            return self.info
        where = f"replay:{self.path}"
        try:
            li = laser_log_info(self.path)
        except NotALaserLogError as e:
            raise WrongDeviceError(f"{where}: {e.what}") from None
        except LaserLogError as e:
            raise TelegramError(f"{where}: corrupt laser log: {e}") from None
        except OSError as e:
            raise LaserAddressError(f"{where}: cannot open the laser log {str(self.path)!r}: {e.strerror or e}") from None
        if not li.lasers:
            raise LaserAddressError(f"{where}: the log declares no laser (the run ended before its first scan)")
        lid = li.first_laser if self.laser_id is None else self.laser_id
        if lid not in li.lasers:
            raise LaserAddressError(f"{where}: no laser {lid} in the log; it declares "
                                    f"{', '.join(str(k) for k in li.lasers)} (laser=ID)")
        assert lid is not None
        self.laser_id = lid
        self.log_info = li
        self.truncated_bytes = li.truncated_bytes
        if li.truncated_bytes:
            self.stats.last_error = f"{where}: ignored a cut-off last record ({li.truncated_bytes} bytes)"
        try:
            self._reader = read_laser_log(self.path, lid)
            self._pending = next(self._reader, None)
        except (OSError, LaserLogError) as e:
            self._close_reader()
            raise TelegramError(f"{where}: {e}") from None
        decl = self._pending.laser if self._pending is not None else li.lasers[lid]
        self._adopt(decl)
        self._finished = self._pending is None
        self._started = True
        self._t0_log = self._pending.t_s if self._pending is not None else 0.0
        self._t0_host = time.monotonic()
        n, span = li.scans.get(lid, 0), li.span_s.get(lid, (0.0, 0.0))
        hz = (n - 1) / (span[1] - span[0]) * self.rate if n > 1 and span[1] > span[0] and self.rate > 0 else 0.0
        self.info = LaserInfo(kind="replay", address=str(self.path), model=decl.model, serial="", stamps=decl.stamps,
                              latency_s=decl.latency_s, scan_hz=hz)
        return self.info

    def _adopt(self, decl: LaserDecl) -> None:
        self.declaration = decl
        if not self._explicit_mount:
            self.mount = decl.mount

    def _due(self, rec: LogScan) -> float:
        return self._t0_host + (rec.t_s - self._t0_log) / self.rate

    def _advance(self) -> None:
        try:
            self._pending = next(self._reader, None) if self._reader is not None else None
        except (OSError, LaserLogError) as e:
            self.stats.malformed += 1
            self.stats.last_error = f"replay:{self.path}: {e}"
            self._pending = None
        if self._pending is None:
            self._close_reader()

    def _deliver(self, rec: LogScan, stamp_s: float) -> LaserScan:
        if rec.laser is not self.declaration:
            self._adopt(rec.laser)
        self.last_log_t_s = rec.t_s
        s = rec.scan
        return LaserScan(s.angle_min_rad, s.angle_increment_rad, s.ranges_m, s.range_max_m, stamp_s, None)

    def latest(self) -> LaserScan | None:
        if not self._started:
            return None
        if self._pending is None:
            self._finished = True
            return None
        if self.rate == 0:
            rec = self._pending
            self._advance()
            self.stats.scans += 1
            self._finished = self._pending is None
            return self._deliver(rec, time.monotonic())
        now = time.monotonic()
        got: LogScan | None = None
        while self._pending is not None and self._due(self._pending) <= now:
            if got is not None:
                self.stats.dropped += 1
            got = self._pending
            self.stats.scans += 1
            self._advance()
        self._finished = self._pending is None
        return None if got is None else self._deliver(got, self._due(got))

    def wait(self, timeout_s: float) -> LaserScan | None:
        """The next scan, waiting up to ``timeout_s`` for it to fall due; None at once when the log has ended."""
        if self.rate == 0 or self._pending is None:
            return self.latest()
        end = time.monotonic() + max(0.0, timeout_s)
        while True:
            s = self.latest()
            if s is not None or self._pending is None:
                return s
            now = time.monotonic()
            if now >= end:
                return None
            time.sleep(max(0.0, min(self._due(self._pending), end) - now))

    def _close_reader(self) -> None:
        r, self._reader = self._reader, None
        if r is not None:
            r.close()

    def close(self) -> None:
        """Stop the replay and close the file; idempotent (``latest()`` then returns None)."""
        self._close_reader()
        self._pending = None
        self._finished = True
        self._started = False
