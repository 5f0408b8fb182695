"""Reader of CARMEN laser logs, the text format of the public 2D laser SLAM benchmark datasets.

One message a line, fields separated by white space, ``#`` starts a comment. The lines read:

``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp hostname logger_timestamp``
    a front laser scan (``RLASER``: the rear one, turned by pi) with the laser's pose and the robot's
    odometry pose at the scan. The old format states no beam geometry: the beams span pi from -pi/2,
    ``pi / n`` apart (``pi / (n - 1)`` for 181, 361 and 721 beams, which include both ends).
``ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n m v_1 .. v_m
laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety side_safety turn_axis
ipc_timestamp hostname logger_timestamp``
    a scan with its geometry, the laser's and the robot's odometry pose (``ROBOTLASER2``: a second laser).
``RAWLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n m v_1 .. v_m
ipc_timestamp hostname logger_timestamp``
    a scan without a pose (``RAWLASER2`` .. ``RAWLASER4``: other lasers); its odometry is interpolated
    in time between the ``ODOM`` lines around it.
``ODOM x y theta tv rv accel ipc_timestamp hostname logger_timestamp``
    an odometry pose.

Distances are metres, angles radians, timestamps seconds. A scan's time is its ``ipc_timestamp``, kept as
the text of the log (:attr:`CarmenScan.t_text`) as well as a number. A range of 0, a negative one, or one at
or beyond the laser's maximum (``max_range``; FLASER and RLASER state none, and the SICK scanners of those
logs write about 81.9 m for no return, so 80 m is taken) is no return (NaN).

A g2o pose graph that carries its scans as ROBOTLASER1 lines (``VERTEX_SE2 id x y theta`` before each scan,
``EDGE_SE2 i j dx dy dtheta`` + 6 information entries; the benchmark's ``killian.g2o`` is one) is read as a
log too. Its vertices and the scans' pose fields are the graph's estimate, not measurements, so they are not
taken for odometry: the odometry of such a log is the chain of its sequential edges (j = i + 1) composed
from the first vertex (:attr:`CarmenLog.odometry_source` says which was used). Its other edges (loop
closures of whoever built the graph) are not used.

Lines of other messages (``PARAM``, ``SYNC``, ``TRUEPOS``, the graph's vertices and edges, ...) are counted
per message and otherwise ignored. A line of a
read message that breaks its format (too few or too many fields, a field that is not a number, a beam count
out of range) is skipped and counted with its line number and the reason (:class:`CarmenLog`); so is a last
line cut off by a truncated file. A scan whose odometry is not finite, or a RAWLASER scan outside the
time span of the ODOM lines, has no odometry (``odom`` None). Only a file with no scan at all, or one that
is not text, is an error (:class:`CarmenLogError`).
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Iterable

import numpy as np

from ..types import FloatArray, Pose2D

__all__ = ["CarmenLogError", "CarmenScan", "SkippedLine", "CarmenLog", "read_carmen_log", "parse_carmen_lines",
           "looks_like_carmen", "FLASER_RANGE_MAX_M"]

#: The no-return limit taken for FLASER / RLASER lines, which state none, m
FLASER_RANGE_MAX_M = 80.0
_MAX_BEAMS = 100_000
_MAX_SKIP_EXAMPLES = 20
_SCAN_TAGS = ("FLASER", "RLASER", "ROBOTLASER1", "ROBOTLASER2", "RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")
_KNOWN_TAGS = (*_SCAN_TAGS, "ODOM")


class CarmenLogError(ValueError):
    """The file cannot be read as a CARMEN log at all (not text, no scan in it); the message says why."""


@dataclass(frozen=True)
class CarmenScan:
    """One laser scan of a CARMEN log.

    ``angle_min_rad`` / ``angle_increment_rad``: beam i points at ``angle_min + i * increment`` in the
    laser's frame; ``ranges_m``: shape (n,), NaN for no return; ``laser_pose``: the laser in the odometry
    frame, ``odom``: the robot in the odometry frame (None when the log gives no usable odometry for it);
    ``mount``: the laser in the robot's frame; ``t_s`` / ``t_text``: the ipc timestamp, s, as a number and
    as written; ``line``: the line number (from 1); ``tag``: the message."""

    t_s: float
    t_text: str
    angle_min_rad: float
    angle_increment_rad: float
    ranges_m: FloatArray
    range_max_m: float
    odom: Pose2D | None
    mount: Pose2D
    line: int
    tag: str


@dataclass(frozen=True)
class SkippedLine:
    """A line that was not read: its number (from 1), message and why."""

    line: int
    tag: str
    why: str


@dataclass
class CarmenLog:
    """What :func:`read_carmen_log` read: the scans in file order, how many lines of each other message were
    ignored, the skipped lines (``skipped``: the count; ``skip_examples``: the first 20 with their reason),
    and how many scans have no odometry."""

    path: str
    scans: list[CarmenScan] = field(default_factory=list)
    odom_lines: int = 0
    ignored: dict[str, int] = field(default_factory=dict)
    skipped: int = 0
    skip_examples: list[SkippedLine] = field(default_factory=list)
    odometry_source: str = "the scans' odometry fields"

    @property
    def without_odometry(self) -> int:
        return sum(1 for s in self.scans if s.odom is None)

    def skip(self, line: int, tag: str, why: str) -> None:
        self.skipped += 1
        if len(self.skip_examples) < _MAX_SKIP_EXAMPLES:
            self.skip_examples.append(SkippedLine(line, tag, why))

    def summary(self) -> str:
        """One paragraph for people: scans read, lines skipped (with the first reasons), lines ignored."""
        parts = [f"{len(self.scans)} scans"]
        if self.odom_lines:
            parts.append(f"{self.odom_lines} ODOM lines")
        if self.without_odometry:
            parts.append(f"{self.without_odometry} scans without odometry")
        text = ", ".join(parts) + f"; odometry from {self.odometry_source}"
        if self.ignored:
            text += "; ignored " + ", ".join(f"{n} {tag}" for tag, n in sorted(self.ignored.items()))
        if self.skipped:
            first = "; ".join(f"line {s.line}: {s.why}" for s in self.skip_examples[:3])
            text += f"; skipped {self.skipped} bad line{'s' if self.skipped != 1 else ''} ({first}"
            text += ", ...)" if self.skipped > 3 else ")"
        return text


class _Bad(Exception):
    pass


def _f(tok: str) -> float:
    try:
        return float(tok)
    except ValueError:
        raise _Bad(f"{tok[:20]!r} is not a number") from None


def _count(tok: str, what: str) -> int:
    try:
        n = int(tok)
    except ValueError:
        raise _Bad(f"{what} {tok[:20]!r} is not a whole number") from None
    if not 0 <= n <= _MAX_BEAMS:
        raise _Bad(f"{what} {n} is out of range")
    return n


def _ranges(toks: list[str], range_max_m: float) -> FloatArray:
    try:
        r = np.array(toks, dtype=float)
    except ValueError:
        raise _Bad("a range is not a number") from None
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(r) | (r <= 0.0) | (r >= range_max_m)
    r[bad] = np.nan
    return r


def _pose(toks: list[str]) -> Pose2D | None:
    x, y, th = (_f(t) for t in toks)
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(th)):
        return None
    return Pose2D(x, y, th)


def _relative(a: Pose2D, b: Pose2D) -> Pose2D:
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    dx, dy = b.x_m - a.x_m, b.y_m - a.y_m
    return Pose2D(c * dx + s * dy, -s * dx + c * dy, math.remainder(b.yaw_rad - a.yaw_rad, 2.0 * math.pi))


def _stamp(toks: list[str], i: int) -> tuple[float, str]:
    t = _f(toks[i])
    if not math.isfinite(t):
        raise _Bad(f"timestamp {toks[i][:20]!r} is not finite")
    return t, toks[i]


def _flaser(tag: str, toks: list[str], line: int) -> CarmenScan:
    n = _count(toks[1], "beam count")
    if len(toks) != n + 11:
        raise _Bad(f"{n} beams need {n + 11} fields, the line has {len(toks)}")
    inc = math.pi / (n - 1) if n in (181, 361, 721) else math.pi / max(n, 1)
    ranges = _ranges(toks[2:2 + n], FLASER_RANGE_MAX_M)
    laser = _pose(toks[2 + n:5 + n])
    odom = _pose(toks[5 + n:8 + n])
    t, t_text = _stamp(toks, 8 + n)
    mount = Pose2D(0.0, 0.0, math.pi if tag == "RLASER" else 0.0)
    if laser is not None and odom is not None:
        mount = _relative(odom, laser)
    return CarmenScan(t, t_text, -math.pi / 2.0, inc, ranges, FLASER_RANGE_MAX_M, odom, mount, line, tag)


def _geometry(toks: list[str]) -> tuple[float, float, float, int]:
    start, _fov, res, rmax = (_f(t) for t in toks[2:6])
    if not (math.isfinite(start) and math.isfinite(res) and res != 0.0):
        raise _Bad("the beam geometry is not finite")
    if not (math.isfinite(rmax) and rmax > 0.0):
        rmax = math.inf
    return start, res, rmax, _count(toks[8], "beam count")


def _beams(tag: str, toks: list[str], tail: int) -> tuple[float, float, float, FloatArray, int]:
    """The beam geometry, the ranges and the index after the remissions of a ROBOTLASER or RAWLASER line, whose
    remissions are followed by ``tail`` fields."""
    if len(toks) < 10:
        raise _Bad(f"the line has {len(toks)} fields, too few for a {tag[:-1]} message")
    start, res, rmax, n = _geometry(toks)
    if len(toks) < 10 + n:
        raise _Bad(f"{n} beams need at least {n + 10 + tail} fields, the line has {len(toks)}")
    m = _count(toks[9 + n], "remission count")
    i = 10 + n + m
    if len(toks) != i + tail:
        raise _Bad(f"{n} beams and {m} remissions need {i + tail} fields, the line has {len(toks)}")
    return start, res, rmax, _ranges(toks[9:9 + n], rmax), i


def _robotlaser(tag: str, toks: list[str], line: int) -> CarmenScan:
    start, res, rmax, ranges, i = _beams(tag, toks, 14)
    laser = _pose(toks[i:i + 3])
    odom = _pose(toks[i + 3:i + 6])
    t, t_text = _stamp(toks, i + 11)
    mount = _relative(odom, laser) if laser is not None and odom is not None else Pose2D()
    return CarmenScan(t, t_text, start, res, ranges, rmax, odom, mount, line, tag)


def _rawlaser(tag: str, toks: list[str], line: int) -> CarmenScan:
    start, res, rmax, ranges, i = _beams(tag, toks, 3)
    t, t_text = _stamp(toks, i)
    return CarmenScan(t, t_text, start, res, ranges, rmax, None, Pose2D(), line, tag)


def _odom(toks: list[str]) -> tuple[float, Pose2D | None]:
    if len(toks) != 10:
        raise _Bad(f"ODOM needs 10 fields, the line has {len(toks)}")
    return _stamp(toks, 7)[0], _pose(toks[1:4])


def _interpolate_odometry(scans: list[CarmenScan], odom: list[tuple[float, Pose2D | None]]) -> list[CarmenScan]:
    """The RAWLASER scans with their odometry interpolated in time between the ODOM poses around them."""
    good = sorted((t, p) for t, p in odom if p is not None)
    if not good:
        return scans
    ts = np.array([t for t, _ in good])
    xs = np.array([p.x_m for _, p in good])
    ys = np.array([p.y_m for _, p in good])
    th = np.unwrap(np.array([p.yaw_rad for _, p in good]))
    out = []
    for s in scans:
        if s.tag.startswith("RAWLASER") and ts[0] <= s.t_s <= ts[-1]:
            pose = Pose2D(float(np.interp(s.t_s, ts, xs)), float(np.interp(s.t_s, ts, ys)),
                          math.remainder(float(np.interp(s.t_s, ts, th)), 2.0 * math.pi))
            s = CarmenScan(s.t_s, s.t_text, s.angle_min_rad, s.angle_increment_rad, s.ranges_m, s.range_max_m,
                           pose, s.mount, s.line, s.tag)
        out.append(s)
    return out


def _graph_odometry(log: CarmenLog, vertex_of_scan: list[int | None], edges: dict[int, Pose2D],
                    first: dict[int, Pose2D]) -> None:
    """Give the scans of a g2o graph the odometry of its sequential edges (when they reach every scan)."""
    if not edges or any(v is None for v in vertex_of_scan) or not vertex_of_scan:
        return
    v0 = vertex_of_scan[0]
    assert v0 is not None
    pose = first.get(v0, Pose2D())
    chain = {v0: pose}
    v = v0
    last = max(v for v in vertex_of_scan if v is not None)
    while v < last:
        if v not in edges:
            return
        pose = pose.compose(edges[v])
        v += 1
        chain[v] = pose
    log.scans = [CarmenScan(s.t_s, s.t_text, s.angle_min_rad, s.angle_increment_rad, s.ranges_m, s.range_max_m,
                            chain.get(vi) if vi is not None else None, s.mount, s.line, s.tag)
                 for s, vi in zip(log.scans, vertex_of_scan)]
    log.odometry_source = f"the g2o graph's {len(edges)} sequential EDGE_SE2 edges"


def parse_carmen_lines(lines: Iterable[str], path: str = "<lines>", complete: bool = True) -> CarmenLog:
    """Read the lines of a CARMEN log (see the module's text for what is read, ignored and skipped).
    ``complete`` False: the text did not end with a newline, so a bad last line is a cut-off one."""
    log = CarmenLog(path)
    odom: list[tuple[float, Pose2D | None]] = []
    last_bad: tuple[int, str] | None = None
    vertex: int | None = None
    vertex_of_scan: list[int | None] = []
    vertex_pose: dict[int, Pose2D] = {}
    seq_edges: dict[int, Pose2D] = {}
    number = 0
    for number, text in enumerate(lines, start=1):
        toks = text.split("#", 1)[0].split()
        if not toks:
            continue
        tag = toks[0]
        if tag in ("VERTEX_SE2", "EDGE_SE2"):
            log.ignored[tag] = log.ignored.get(tag, 0) + 1
            try:
                if tag == "VERTEX_SE2" and len(toks) == 5:
                    vertex = int(toks[1])
                    vp = _pose(toks[2:5])
                    if vp is not None:
                        vertex_pose[vertex] = vp
                elif tag == "EDGE_SE2" and len(toks) == 12 and int(toks[2]) == int(toks[1]) + 1:
                    ep = _pose(toks[3:6])
                    if ep is not None:
                        seq_edges[int(toks[1])] = ep
            except (ValueError, _Bad):
                pass
            continue
        if tag not in _KNOWN_TAGS:
            if tag.isidentifier() and tag.upper() == tag and text.isprintable():
                log.ignored[tag] = log.ignored.get(tag, 0) + 1
            else:
                log.skip(number, tag[:20], "not a CARMEN message")
                last_bad = (number, tag[:20])
            continue
        try:
            if tag == "ODOM":
                odom.append(_odom(toks))
                log.odom_lines += 1
            elif tag in ("FLASER", "RLASER"):
                log.scans.append(_flaser(tag, toks, number))
                vertex_of_scan.append(vertex)
            elif tag.startswith("ROBOTLASER"):
                log.scans.append(_robotlaser(tag, toks, number))
                vertex_of_scan.append(vertex)
            else:
                log.scans.append(_rawlaser(tag, toks, number))
        except _Bad as e:
            log.skip(number, tag, f"{tag}: {e}")
            last_bad = (number, tag)
    if not complete and last_bad is not None and last_bad[0] == number and log.skip_examples:
        ex = log.skip_examples
        if ex[-1].line == number:
            ex[-1] = SkippedLine(number, ex[-1].tag, f"{ex[-1].tag}: the file ends inside this line (truncated)")
    if odom:
        log.scans = _interpolate_odometry(log.scans, odom)
    if seq_edges and len(vertex_of_scan) == len(log.scans):
        _graph_odometry(log, vertex_of_scan, seq_edges, vertex_pose)
    return log


def looks_like_carmen(head: bytes) -> bool:
    """True when the first bytes of a file are text whose first message is a CARMEN one."""
    try:
        text = head.decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        text = head[: max(0, len(head) - 4)].decode("utf-8", errors="replace")
    for line in text.splitlines():
        toks = line.split("#", 1)[0].split()
        if toks:
            return toks[0] in _KNOWN_TAGS or toks[0] in ("PARAM", "SYNC", "TRUEPOS", "VERTEX_SE2", "EDGE_SE2")
    return False


def _open_text(p: Path) -> tuple[IO[bytes], str]:
    if zipfile.is_zipfile(p):
        zf = zipfile.ZipFile(p)
        names = [n for n in zf.namelist() if not n.endswith("/") and "__MACOSX" not in n]
        if len(names) != 1:
            raise CarmenLogError(f"{p}: a zip archive must hold one log, this one holds {len(names)} files")
        return zf.open(names[0]), f"{p}!{names[0]}"
    return open(p, "rb"), str(p)  # noqa: SIM115 (closed by the caller)


def read_carmen_log(path: str | Path) -> CarmenLog:
    """Read the CARMEN log at ``path`` (a text file, or a zip archive holding one). Raises OSError when the
    file cannot be read and :class:`CarmenLogError` when it is not text or holds no scan."""
    p = Path(path)
    f, name = _open_text(p)
    with f:
        data = f.read()
    if b"\0" in data[:65536]:
        raise CarmenLogError(f"{name}: not a CARMEN log (binary data, not text)")
    text = data.decode("utf-8", errors="replace")
    log = parse_carmen_lines(text.splitlines(), name, complete=text.endswith("\n") or not text)
    if not log.scans:
        what = f" ({log.summary()})" if log.skipped or log.ignored else ""
        raise CarmenLogError(f"{name}: no laser scan in the file (no FLASER, ROBOTLASER or RAWLASER line){what}")
    return log
