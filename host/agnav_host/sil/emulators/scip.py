"""A Hokuyo UST (TCP) or URG (pty) served from the SIL's simulated scans, answering SCIP 2.0 as the device does.

The protocol facts are those of :mod:`agnav_host.lasers.scip` (Hokuyo C-42-03320B *Communication Protocol
Specification For SCIP2.0 Standard*: sections 2, 5-9; C-42-04076 for the UST's TCP port 10940), whose codec
builds every reply:

- each command's reply is its echo, the status with its sum, the data lines, and the blank line (section 7);
  the echo repeats the command line as received, string characters included;
- VV / PP / II answer ``KEY:value;sum`` lines (sections 8.11-8.13); PP comes from the geometry (below);
- MD/MS/ME (``start end cluster interval scans``) acknowledge with ``00`` and then stream, to the client that
  asked, every published scan after the command (skipping ``interval`` scans between two sent), each with the
  remaining scans in the echo, status ``99``, the time stamp and 64-character data blocks (section 8.1);
  ``scans`` 00 streams until QT; at the end of a counted run the laser goes off;
- GD/GS/GE answer the newest scan with ``00`` when the laser is on (BM), ``10`` when it is off (section 8.2);
- BM (00, 02 already on), QT, RS, RT (00), TM0/TM1/TM2 with statuses 01-04 (section 8.6), ``SCIP2.0`` (echo,
  ``0``; section 2); parameter errors 01-07 for the scan commands, 0C for a wrong parameter length, 0G/0H for
  bad string characters and 0E for anything else (section 9).

Geometry to PP: ARES = 2 pi / ``angle_increment_rad`` (a whole number, else ValueError), the front step AFRT and
AMIN chosen so beam ``i`` is step ``AMIN + i`` at ``(step - AFRT) * 2 pi / ARES`` (``angle_min_rad`` must be a whole
number of steps from the front), AMAX = AMIN + n - 1, DMIN/DMAX = the range limits in mm, SCAN = ``scan_hz * 60``.

Values: a beam's range in mm; NaN, inf, <= 0 or beyond ``range_max_m`` is error code 1 ("no object in the
range", table 4), 1-19 mm is error code 4 ("out of range at the near end"); MS/GS values above 4095 mm (the
2-character limit) are 1 as well. ME/GE intensities are a fixed 1000 for a return and 0 for none.

Time: a published ``t_s`` is the device time of the scan's middle beam (the stamp :mod:`agnav_host.lasers.base`
gives a scan), so the time stamp, taken at step 0 (section 8.1), is ``t_s - mid_step * 60 / (SCAN * ARES)`` in
whole ms modulo 2**24. TM1 reads the device clock as the end of the newest scan plus the host time since it was
published (before any publish it waits up to 1 s for one, then counts from :meth:`ScipEmulator.start`): the
device clock runs at the host's rate, as the driver's clock mapping assumes.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from ...lasers.scip import (
    DEFAULT_PORT,
    ERROR_CODE_LIMIT_MM,
    MAX_TAG,
    TAG_CHARS,
    TIMESTAMP_WRAP_MS,
    ScipParams,
    data_lines,
    encode_array,
    format_reply,
    info_line,
    time_line,
)
from .base import PublishedScan, ScanBoard, ScanGeometry, Stream, Transport

__all__ = ["ScipEmulator", "params_from_geometry"]

_MODELS = {"ust": ("UST-10LX", "Ethernet 100 [Mbps]"), "urg": ("URG-04LX-UG01", "115200[bps]")}
_NO_OBJECT = 1  # table 4, UTM-30LX: "No object in the range"
_TOO_NEAR = 4  # table 4: "Object out of range (at the near end)"
_INTENSITY = 1000


def params_from_geometry(geometry: ScanGeometry, model: str = "UST-10LX") -> ScipParams:
    """The PP answer whose steps are exactly the geometry's beams (ValueError when no such steps exist)."""
    g = geometry
    turn = 2.0 * math.pi / g.angle_increment_rad
    ares = round(turn)
    if ares < 2 or abs(turn - ares) > 1e-6 * turn:
        raise ValueError(f"SCIP emulator: angle_increment_rad {g.angle_increment_rad!r} does not divide 2 pi into "
                         f"a whole number of steps (2 pi / step = {turn:.6f}); SCIP needs 2 pi / ARES")
    k_f = g.angle_min_rad / (2.0 * math.pi / ares)
    k = round(k_f)
    if abs(k_f - k) > 1e-6:
        raise ValueError(f"SCIP emulator: angle_min_rad {g.angle_min_rad!r} is {k_f:.6f} steps from the front, "
                         f"not a whole number of steps")
    afrt = max(-k, 0)
    amin = afrt + k
    amax = amin + g.n_beams - 1
    if amax >= ares or amax > 9999:
        raise ValueError(f"SCIP emulator: {g.n_beams} beams from step {amin} do not fit one turn of {ares} steps")
    rpm = round(g.scan_hz * 60.0)
    if rpm <= 0:
        raise ValueError(f"SCIP emulator: scan_hz {g.scan_hz!r} gives no whole rpm")
    return ScipParams(model=f"{model}(AgNav SIL emulator)", dmin_mm=round(g.range_min_m * 1000.0),
                      dmax_mm=round(g.range_max_m * 1000.0), ares=ares, amin=amin, amax=amax, afrt=afrt,
                      scan_rpm=rpm)


@dataclass
class _Run:
    """An MD/MS/ME run of one client."""

    code: str
    start: int
    end: int
    cluster: int
    interval: int
    scans: int  # 0: continuous
    tag: str
    last_seq: int
    remaining: int
    skip: int = 0


@dataclass
class _Session:
    laser_on: bool = False
    adjust: bool = False
    run: _Run | None = None


class ScipEmulator:
    """Hokuyo ``ust`` (TCP, default port 10940; ``port=0`` any free port) or ``urg`` (a pty) over SCIP 2.0."""

    def __init__(self, kind: str, geometry: ScanGeometry, host: str = "127.0.0.1", port: int | None = None) -> None:
        if kind not in _MODELS:
            raise ValueError(f"SCIP emulator: kind must be 'ust' (TCP) or 'urg' (pty), got {kind!r}")
        self.kind = kind
        self.geometry = geometry
        model, self._bps = _MODELS[kind]
        self.params = params_from_geometry(geometry, model)
        self.host = host
        self.port = DEFAULT_PORT if port is None else int(port)
        self.pty_path = ""
        self._board = ScanBoard()
        self._transport = Transport(self._serve)
        self._lock = threading.Lock()
        self._published: tuple[float, float] | None = None  # (t_s, host monotonic) of the newest publish
        self._t_start = time.monotonic()
        self._generation = 0
        p = self.params
        self._mid_step = 0.5 * (p.amin + p.amax)

    # ---- ScannerEmulator --------------------------------------------------------------------------------------
    def start(self) -> str:
        self._t_start = time.monotonic()
        if self.kind == "ust":
            self.port = self._transport.listen_tcp(self.host, self.port)
            return f"tcp:{self.host}:{self.port}"
        self.pty_path = self._transport.open_pty()
        return self.pty_path

    def publish(self, ranges_m: np.ndarray, t_s: float) -> None:
        r = np.asarray(ranges_m, dtype=float)
        if r.shape != (self.geometry.n_beams,):
            raise ValueError(f"SCIP emulator: expected {self.geometry.n_beams} ranges, got shape {r.shape}")
        with self._lock:
            self._published = (float(t_s), time.monotonic())
        self._board.publish(r, t_s)

    def close(self) -> None:
        self._board.close()
        self._transport.close()

    def drop_clients(self) -> None:
        """Test hook: close every TCP client's connection (a pty session is reset instead)."""
        with self._lock:
            self._generation += 1

    # ---- the device clock ---------------------------------------------------------------------------------------
    def _device_ms(self) -> int:
        if self._published is None:
            self._board.next_after(-1, 1.0)
        with self._lock:
            pub = self._published
        p = self.params
        if pub is None:
            t = time.monotonic() - self._t_start
        else:
            t = pub[0] + (p.amax - self._mid_step) * p.step_s + (time.monotonic() - pub[1])
        return math.floor(t * 1000.0) % TIMESTAMP_WRAP_MS

    def _stamp_ms(self, scan: PublishedScan) -> int:
        return math.floor((scan.t_s - self._mid_step * self.params.step_s) * 1000.0) % TIMESTAMP_WRAP_MS

    # ---- serving ------------------------------------------------------------------------------------------------
    def _serve(self, stream: Stream, stop: threading.Event) -> None:
        with self._lock:
            gen = self._generation
        session = _Session()
        buf = b""
        while not stop.is_set() and not stream.closed:
            with self._lock:
                dropped = gen != self._generation
                gen = self._generation
            if dropped:
                if self.kind == "ust":
                    return  # Transport closes the socket
                session, buf = _Session(), b""
            data = stream.read(4096, timeout_s=0.005 if session.run else 0.05)
            if data:
                buf += data
                while True:
                    cut = [i for i in (buf.find(b"\n"), buf.find(b"\r")) if i >= 0]
                    if not cut:
                        break
                    i = min(cut)
                    line, buf = buf[:i], buf[i + 1:]
                    if line:
                        stream.write(self._answer(session, line, stop))
                if len(buf) > 4096:  # no terminator in 4 kB: noise
                    buf = b""
            if session.run is not None:
                self._pump(session, stream)

    def _pump(self, s: _Session, stream: Stream) -> None:
        run = s.run
        assert run is not None
        scan = self._board.next_after(run.last_seq, 0.0)
        if scan is None:
            return
        run.last_seq = scan.seq
        if run.skip > 0:
            run.skip -= 1
            return
        run.skip = run.interval
        if run.scans:
            run.remaining -= 1
        echo = f"{run.code}{run.start:04d}{run.end:04d}{run.cluster:02d}{run.interval:01d}{run.remaining:02d}"
        if run.tag:
            echo += ";" + run.tag
        stream.write(self._scan_reply(echo, "99", run.code, run.start, run.end, run.cluster, scan))
        if run.scans and run.remaining <= 0:
            s.run = None
            s.laser_on = False

    def _scan_reply(self, echo: str, status: str, code: str, start: int, end: int, cluster: int,
                    scan: PublishedScan) -> bytes:
        mm, inten = self._values(code, start, end, cluster, scan.ranges_m)
        width = 2 if code[1] == "S" else 3
        if code[1] == "E":
            chars = encode_array(np.stack([mm, inten], axis=1).reshape(-1), width)
        else:
            chars = encode_array(mm, width)
        return format_reply(echo, status, [time_line(self._stamp_ms(scan)), *data_lines(chars)])

    def _values(self, code: str, start: int, end: int, cluster: int,
                ranges_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, g = self.params, self.geometry
        r = np.asarray(ranges_m, dtype=float)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(r) & (r > 0.0) & (r <= g.range_max_m)
            mm = np.where(ok, np.round(np.where(ok, r, 0.0) * 1000.0), _NO_OBJECT).astype(np.int64)
        mm = np.where(ok & (mm < ERROR_CODE_LIMIT_MM), _TOO_NEAR, mm)
        limit = (1 << 12) - 1 if code[1] == "S" else (1 << 18) - 1
        mm = np.where(mm > limit, _NO_OBJECT, mm)
        steps = np.arange(start, end + 1)
        beam = steps - p.amin
        inside = (beam >= 0) & (beam < g.n_beams)
        per_step = np.full(len(steps), _NO_OBJECT, dtype=np.int64)
        per_step[inside] = mm[beam[inside]]
        c = max(cluster, 1)
        n = -(-len(steps) // c)
        pad = np.full(n * c, _NO_OBJECT, dtype=np.int64)
        pad[:len(steps)] = per_step
        groups = pad.reshape(n, c)
        padded_valid = np.zeros(n * c, dtype=bool)
        padded_valid[:len(steps)] = per_step >= ERROR_CODE_LIMIT_MM
        valid = padded_valid.reshape(n, c)
        big = np.iinfo(np.int64).max
        best = np.where(valid, groups, big).min(axis=1)  # section 8.1: a cluster gives its least valid value
        out = np.where(valid.any(axis=1), best, groups[:, 0])
        inten = np.where(out >= ERROR_CODE_LIMIT_MM, _INTENSITY, 0).astype(np.int64)
        return out, inten

    # ---- commands -----------------------------------------------------------------------------------------------
    def _answer(self, s: _Session, raw: bytes, stop: threading.Event) -> bytes:
        try:
            line = raw.decode("ascii")
        except UnicodeDecodeError:
            return b""  # not a command at all: a real sensor has no echo to give
        if line == "SCIP2.0":
            return b"SCIP2.0\n0\n\n"  # section 2: the echo and status 0
        body, sep, tag = line.partition(";")
        if sep and len(tag) > MAX_TAG:
            return format_reply(line, "0G")
        if sep and not set(tag) <= TAG_CHARS:
            return format_reply(line, "0H")
        code, params = body[:2], body[2:]
        handler = {
            "VV": self._vv, "PP": self._pp, "II": self._ii, "BM": self._bm, "QT": self._qt, "RS": self._rs,
            "RT": self._rs, "TM": self._tm, "MD": self._md, "MS": self._md, "ME": self._md, "GD": self._gd,
            "GS": self._gd, "GE": self._gd,
        }.get(code)
        if handler is None or not code.isalpha() or not code.isupper():
            return format_reply(line, "0E")
        return handler(s, line, code, params, tag, stop)

    def _vv(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        model = _MODELS[self.kind][0]
        return format_reply(line, "00", [info_line("VEND", "Hokuyo Automatic Co.,Ltd."),
                                         info_line("PROD", f"SOKUIKI Sensor {model} (AgNav SIL emulator)"),
                                         info_line("FIRM", "AgNav-emulator"), info_line("PROT", "SCIP 2.0"),
                                         info_line("SERI", f"EMU-{self.kind.upper()}-0001")])

    def _pp(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        return format_reply(line, "00", self.params.info_lines())

    def _ii(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        mesm = "Measuring by Normal Mode" if s.laser_on else "IDLE"
        return format_reply(line, "00", [info_line("MODL", self.params.model),
                                         info_line("LASR", "ON" if s.laser_on else "OFF"),
                                         info_line("SCSP", f"Initial({self.params.scan_rpm}[rpm])"),
                                         info_line("MESM", mesm), info_line("SBPS", self._bps),
                                         info_line("TIME", f"{self._device_ms():06X}"),
                                         info_line("STAT", "Sensor works well.")])

    def _bm(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        if s.laser_on:
            return format_reply(line, "02")
        s.laser_on = True
        return format_reply(line, "00")

    def _qt(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        s.run, s.laser_on = None, False
        return format_reply(line, "00")

    def _rs(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params:
            return format_reply(line, "0C")
        s.run, s.laser_on, s.adjust = None, False, False
        return format_reply(line, "00")

    def _tm(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        if params not in ("0", "1", "2"):
            return format_reply(line, "01")
        if params == "0":
            if s.adjust:
                return format_reply(line, "02")
            s.adjust, s.laser_on, s.run = True, False, None
            return format_reply(line, "00")
        if params == "2":
            if not s.adjust:
                return format_reply(line, "03")
            s.adjust = False
            return format_reply(line, "00")
        if not s.adjust:
            return format_reply(line, "04")
        return format_reply(line, "00", [time_line(self._device_ms())])

    def _steps(self, line: str, params: str, with_run: bool) -> tuple[int, int, int, int, int] | bytes:
        need = 13 if with_run else 10
        if len(params) != need:
            return format_reply(line, "0C")
        fields: tuple[tuple[str, str], ...] = ((params[0:4], "01"), (params[4:8], "02"), (params[8:10], "03"))
        if with_run:
            fields += ((params[10:11], "06"), (params[11:13], "07"))
        for text, status in fields:
            if not text.isdigit():
                return format_reply(line, status)
        start, end, cluster = int(params[0:4]), int(params[4:8]), int(params[8:10])
        if end > self.params.amax:
            return format_reply(line, "04")
        if end < start:
            return format_reply(line, "05")
        interval, scans = (int(params[10:11]), int(params[11:13])) if with_run else (0, 0)
        return start, end, cluster, interval, scans

    def _md(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        parsed = self._steps(line, params, True)
        if isinstance(parsed, bytes):
            return parsed
        start, end, cluster, interval, scans = parsed
        newest = self._board.newest()
        s.run = _Run(code, start, end, cluster, interval, scans, tag, -1 if newest is None else newest.seq, scans)
        s.laser_on = True
        return format_reply(line, "00")

    def _gd(self, s: _Session, line: str, code: str, params: str, tag: str, stop: threading.Event) -> bytes:
        parsed = self._steps(line, params, False)
        if isinstance(parsed, bytes):
            return parsed
        start, end, cluster, _, _ = parsed
        if not s.laser_on:
            return format_reply(line, "10")
        scan = self._board.newest()
        deadline = time.monotonic() + 2.0
        while scan is None and not stop.is_set() and time.monotonic() < deadline:
            scan = self._board.next_after(-1, 0.1)
        if scan is None:
            return format_reply(line, "0A")
        return self._scan_reply(line, "00", code, start, end, cluster, scan)
