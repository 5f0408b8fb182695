"""SICK TiM5xx / LMS1xx / LMS5xx emulator: the SIL's laser served as ``LMDscandata`` in CoLa-A and CoLa-B.

The telegram formats, framing and error codes are those of the codec in :mod:`agnav_host.lasers.sick` (whose
docstring names the SICK documents each fact comes from). What the emulator does:

- Ports: a TiM5xx serves both encodings on TCP 2112 and tells them apart by each telegram's first bytes; an LMS1xx /
  LMS5xx serves CoLa-A on 2111 and CoLa-B on 2112 (``ports=(cola_a, cola_b)``; 0 = any free port).
  :meth:`SickEmulator.start` returns ``tcp:HOST:PORT`` (TiM5xx) or ``tcp:HOST:A_PORT,tcp:HOST:B_PORT`` (LMS).
- Requests: ``sMN SetAccessMode`` (level 3 with the hash F4724744h, "authorised client", or level 2 with B21ACE26h,
  "maintenance", answers ``sAN SetAccessMode 1``, anything else 0), ``sRN DeviceIdent`` (name and version, e.g.
  ``TiM561``), ``sRN SerialNumber``, ``sRN FirmwareVersion``, ``sRN LMDscandata`` (``sRA`` with the newest published
  scan; the answer waits for the first one), ``sEN LMDscandata 1`` / ``0`` (``sEA``, then ``sSN LMDscandata`` for
  every published scan while subscribed), ``sMN LMCstartmeas`` / ``LMCstopmeas`` (``sAN ... 0``; ``sFA 1``,
  METHODIN_ACCESSDENIED, without the log-in), ``sMN Run`` (``sAN Run 1``, logs out).
- Anything else is answered ``sFA`` with a code of the SOPAS error table
  (:data:`~agnav_host.lasers.sick.SOPAS_ERRORS`): an unknown name B (UNKNOWN_CMD_FOR_NAMESERVER: the name server
  does not know it), an unknown command type C (UNKNOWN_COLA_COMMAND), missing or unreadable parameters 8
  (BUFFER_UNDERFLOW), a bad ``sEN`` value 4 (LOCALCONDITIONFAILED). A telegram of the other encoding on a
  single-encoding LMS port is answered in the port's own encoding (``sFA 11``, COLA_A_INVALID_CHARACTER, on the
  CoLa-A port; ``sFA C`` on the CoLa-B port): the documents do not say what a device does there, and an immediate
  answer lets the driver say what is wrong. Frames with a wrong checksum or bytes outside any telegram are dropped
  without an answer.

Telegram fields as the device fills them: telegram and scan counters count the published scans (uint_16, wrap),
``time since start-up`` is the first beam's time, ``time of transmission`` the end of the scan (both in us on a
32-bit counter that starts ``uptime_at_zero_s`` before simulated time 0 and wraps), where the published ``t_s``
is the time of the scan's *middle* beam (what a :class:`~agnav_host.types.LaserScan` stamp means) and the beam
interval is ``step / 360 deg / scan_hz``; the scanning frequency is ``scan_hz`` in 1/100 Hz, the measurement
frequency ``scan_hz x 360 deg / step`` in 100 Hz; one ``DIST1`` channel with the start angle and step of the
geometry in the device's convention (sensor angle + 90 deg, 1/10 000 deg) and the ranges in mm (scale factor 1;
2 when ``range_max_m`` exceeds 65.535 m, so 2 mm units), NaN / inf / outside ``range_min_m``-``range_max_m`` as 0
(no valid measurement). The TiM5xx adds an 8-bit ``RSSI1`` channel (a fixed 200 where there is an echo, 0
elsewhere), as a TiM5xx sends one.

:meth:`SickEmulator.drop_clients` is a test hook: it closes every client connection (the listeners stay), as a
pulled cable or a device restart would.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ...lasers.base import TelegramError
from ...lasers.sick import (
    CLIENT_LEVEL,
    CLIENT_PASSWORD_HASH,
    COLA_A,
    COLA_B,
    Command,
    Deframer,
    ScanChannel,
    ScanTelegram,
    encode_command,
    encode_scandata,
    frame,
    read_fields,
    sopas_error_payload,
    split_command,
)
from .base import PublishedScan, ScanBoard, ScanGeometry, Stream, Transport

__all__ = ["SickEmulator", "SICK_MODELS"]

#: kind -> (device ident name, firmware version, serial number, default (CoLa-A port, CoLa-B port))
SICK_MODELS: dict[str, tuple[str, str, int, tuple[int, int]]] = {
    "tim5xx": ("TiM561", "V3.01", 0x1A2B3C4, (2112, 2112)),
    "lms1xx": ("LMS111", "V1.80", 0x0C0FFEE, (2111, 2112)),
    "lms5xx": ("LMS511", "V2.20", 0x1511511, (2111, 2112)),
}

# sFA codes used here (numbering of the telegram listing's table, see agnav_host.lasers.sick.SOPAS_ERRORS)
_ACCESS_DENIED = 0x1
_LOCAL_CONDITION = 0x4
_UNDERFLOW = 0x8
_UNKNOWN_NAME = 0xB
_UNKNOWN_COMMAND = 0xC
_INVALID_CHARACTER = 0x11

_MAINTENANCE_HASH = 0xB21ACE26  # user level 2 [LMS500 family 8013796/UL20 tab. 22]
_U32 = 2**32


@dataclass(eq=False)  # identity hash: clients live in a set
class _Client:
    queue: deque[PublishedScan] = field(default_factory=lambda: deque(maxlen=256))
    stream_cola: str | None = None  # the encoding of its sEN LMDscandata 1, while subscribed
    access: int = 0
    polls: list[str] = field(default_factory=list)  # sRN LMDscandata waiting for the first scan (their encodings)


class SickEmulator:
    """A SICK scanner of ``kind`` ("tim5xx", "lms1xx", "lms5xx") scanning ``geometry`` (see the module docstring)."""

    def __init__(self, kind: str, geometry: ScanGeometry, host: str = "127.0.0.1",
                 ports: tuple[int, int] | None = None, *, uptime_at_zero_s: float = 10.0) -> None:
        if kind not in SICK_MODELS:
            raise ValueError(f"SICK emulator: kind must be one of {', '.join(SICK_MODELS)}, got {kind!r}")
        self.kind = kind
        self.geometry = geometry
        self.host = host
        self.model, self.version, self.serial, default_ports = SICK_MODELS[kind]
        self._want_ports = tuple(ports) if ports is not None else default_ports
        if len(self._want_ports) != 2:
            raise ValueError(f"SICK emulator: ports must be (CoLa-A port, CoLa-B port), got {ports!r}")
        self.uptime_at_zero_s = float(uptime_at_zero_s)
        step = round(math.degrees(geometry.angle_increment_rad) * 1e4)
        if not 1 <= step <= 0xFFFF:
            raise ValueError(f"SICK emulator: the angular step must be 0.0001 ... 6.5535 deg, got "
                             f"{math.degrees(geometry.angle_increment_rad):g} deg")
        if geometry.n_beams > 0xFFFF:
            raise ValueError(f"SICK emulator: at most 65535 beams, got {geometry.n_beams}")
        self.step_raw = step
        self.start_raw = round((math.degrees(geometry.angle_min_rad) + 90.0) * 1e4)
        self.scale = 1.0 if geometry.range_max_m <= 65.535 else 2.0
        self.board = ScanBoard()
        self._lock = threading.Lock()
        self._clients: set[_Client] = set()
        self._generation = 0
        self._transports: list[Transport] = []
        self._ports: tuple[int, int] = (0, 0)
        self._endpoints = ""
        self._cache: dict[tuple[int, str, str], bytes] = {}

    # ---- ScannerEmulator -----------------------------------------------------------------------------------
    def start(self) -> str:
        if self._endpoints:
            return self._endpoints
        pa, pb = self._want_ports
        if self.kind == "tim5xx":
            if pa == pb:
                port = self._listen(pb, frozenset((COLA_A, COLA_B)))
                self._ports = (port, port)
                self._endpoints = f"tcp:{self.host}:{port}"
                return self._endpoints
            both = frozenset((COLA_A, COLA_B))
            self._ports = (self._listen(pa, both), self._listen(pb, both))
        else:
            if pa == pb and pa != 0:
                raise ValueError(f"SICK emulator: an {self.kind} serves CoLa-A and CoLa-B on two ports, got {pa} twice")
            self._ports = (self._listen(pa, frozenset((COLA_A,))), self._listen(pb, frozenset((COLA_B,))))
        self._endpoints = ",".join(f"tcp:{self.host}:{p}" for p in self._ports)
        return self._endpoints

    @property
    def ports(self) -> tuple[int, int]:
        """The (CoLa-A, CoLa-B) ports served (the same port twice for a TiM5xx); (0, 0) before :meth:`start`."""
        return self._ports

    def publish(self, ranges_m: np.ndarray, t_s: float) -> None:
        r = np.asarray(ranges_m, dtype=float)
        if r.shape != (self.geometry.n_beams,):
            raise ValueError(f"SICK emulator: expected {self.geometry.n_beams} ranges, got shape {r.shape}")
        self.board.publish(r, t_s)
        scan = self.board.newest()
        assert scan is not None
        with self._lock:
            for c in self._clients:
                if c.stream_cola is not None or c.polls:
                    c.queue.append(scan)

    def drop_clients(self) -> None:
        """Close every client connection now (a test hook: the device went away); new connections are served."""
        with self._lock:
            self._generation += 1

    def close(self) -> None:
        self.board.close()
        for t in self._transports:
            t.stop.set()  # every listener and client winds down at once, then each is joined
        for t in self._transports:
            t.close()
        self._transports = []

    # ---- telegrams -----------------------------------------------------------------------------------------
    def telegram(self, scan: PublishedScan, kind: str = "sSN") -> ScanTelegram:
        """The ``LMDscandata`` telegram the device sends for a published scan."""
        g = self.geometry
        n = g.n_beams
        step_deg = self.step_raw / 1e4
        beam_dt = step_deg / 360.0 / g.scan_hz
        t_first = scan.t_s - 0.5 * (n - 1) * beam_dt + self.uptime_at_zero_s
        start_us = round(t_first * 1e6) % _U32
        tx_us = (start_us + round(n * beam_dt * 1e6)) % _U32
        r = scan.ranges_m
        with np.errstate(invalid="ignore"):
            valid = np.isfinite(r) & (r >= g.range_min_m) & (r <= g.range_max_m)
        raw = np.zeros(n, dtype=np.int64)
        raw[valid] = np.clip(np.rint(r[valid] * 1000.0 / self.scale), 1, 0xFFFF)
        dist = ScanChannel("DIST1", self.scale, 0.0, self.start_raw, self.step_raw, raw.astype(np.uint16))
        ch8: tuple[ScanChannel, ...] = ()
        if self.kind == "tim5xx":
            rssi = np.where(valid, 200, 0).astype(np.uint8)
            ch8 = (ScanChannel("RSSI1", 1.0, 0.0, self.start_raw, self.step_raw, rssi),)
        counter = (scan.seq + 1) & 0xFFFF
        return ScanTelegram(
            version=1, device_number=1, serial_number=self.serial, device_status=(0, 0),
            telegram_counter=counter, scan_counter=counter, time_since_startup_us=start_us,
            time_of_transmission_us=tx_us, inputs=(0, 0), outputs=(0, 0), layer_angle=0,
            scan_frequency=round(g.scan_hz * 100), measurement_frequency=round(g.scan_hz * 360.0 / step_deg / 100),
            channels16=(dist,), channels8=ch8, kind=kind)

    def _scan_payload(self, scan: PublishedScan, cola: str, kind: str) -> bytes:
        key = (scan.seq, cola, kind)
        with self._lock:
            hit = self._cache.get(key)
        if hit is not None:
            return hit
        payload = encode_scandata(self.telegram(scan, kind), cola)
        with self._lock:
            if len(self._cache) > 16:
                self._cache.clear()
            self._cache[key] = payload
        return payload

    # ---- serving -------------------------------------------------------------------------------------------
    def _listen(self, port: int, colas: frozenset[str]) -> int:
        t = Transport(lambda stream, stop: self._serve(stream, stop, colas))
        self._transports.append(t)
        return t.listen_tcp(self.host, port)

    def _serve(self, stream: Stream, stop: threading.Event, colas: frozenset[str]) -> None:
        client = _Client()
        with self._lock:
            gen = self._generation
            self._clients.add(client)
        deframer = Deframer()
        try:
            while not stop.is_set() and not stream.closed and gen == self._generation:
                self._flush(stream, client)
                data = stream.read(65536, timeout_s=0.005)
                if not data:
                    continue
                deframer.feed(data)
                while True:
                    try:
                        t = deframer.next()
                    except TelegramError:
                        continue  # a bad frame: dropped, as a device drops it
                    if t is None:
                        break
                    cola, payload = t
                    if cola not in colas:
                        own = next(iter(colas))
                        code = _INVALID_CHARACTER if own == COLA_A else _UNKNOWN_COMMAND
                        stream.write(frame(sopas_error_payload(own, code), own))
                        continue
                    for answer in self._answer(client, cola, payload):
                        stream.write(frame(answer, cola))
        finally:
            with self._lock:
                self._clients.discard(client)

    def _flush(self, stream: Stream, client: _Client) -> None:
        while True:
            with self._lock:
                if not client.queue:
                    return
                scan = client.queue.popleft()
                polls, client.polls = client.polls, []
                cola = client.stream_cola
            for pc in polls:
                stream.write(frame(self._scan_payload(scan, pc, "sRA"), pc))
            if cola is not None:
                stream.write(frame(self._scan_payload(scan, cola, "sSN"), cola))

    def _answer(self, client: _Client, cola: str, payload: bytes) -> list[bytes]:
        try:
            cmd = split_command(cola, payload)
        except TelegramError:
            return [sopas_error_payload(cola, _UNKNOWN_COMMAND)]
        try:
            return self._dispatch(client, cmd)
        except TelegramError:
            return [sopas_error_payload(cola, _UNDERFLOW)]

    def _dispatch(self, client: _Client, cmd: Command) -> list[bytes]:
        cola, kind, name = cmd.cola, cmd.kind, cmd.name
        if kind == "sRN":
            if name == "DeviceIdent":
                return [encode_command(cola, "sRA", name, ("str", self.model), ("str", self.version))]
            if name == "SerialNumber":
                return [encode_command(cola, "sRA", name, ("str", str(self.serial)))]
            if name == "FirmwareVersion":
                return [encode_command(cola, "sRA", name, ("str", self.version))]
            if name == "LMDscandata":
                read_fields(cmd).done()
                scan = self.board.newest()
                if scan is None:
                    with self._lock:
                        client.polls.append(cola)
                    return []
                return [self._scan_payload(scan, cola, "sRA")]
        elif kind == "sEN":
            if name == "LMDscandata":
                r = read_fields(cmd)
                on = r.uint("start/stop", 8)
                r.done()
                if on > 1:
                    return [sopas_error_payload(cola, _LOCAL_CONDITION)]
                with self._lock:
                    client.stream_cola = cola if on else None
                    if not on:
                        client.queue.clear()
                return [encode_command(cola, "sEA", name, ("u8", on))]
        elif kind == "sMN":
            if name == "SetAccessMode":
                r = read_fields(cmd)
                level, pw = r.uint("user level", 8), r.uint("password hash", 32)
                r.done()
                ok = (level, pw) in ((CLIENT_LEVEL, CLIENT_PASSWORD_HASH), (2, _MAINTENANCE_HASH))
                if ok:
                    client.access = level
                return [encode_command(cola, "sAN", name, ("u8", int(ok)))]
            if name in ("LMCstartmeas", "LMCstopmeas"):
                if client.access == 0:  # not logged in
                    return [sopas_error_payload(cola, _ACCESS_DENIED)]
                return [encode_command(cola, "sAN", name, ("u8", 0))]
            if name == "Run":
                client.access = 0
                return [encode_command(cola, "sAN", name, ("u8", 1))]
        elif kind not in ("sWN",):
            return [sopas_error_payload(cola, _UNKNOWN_COMMAND)]
        return [sopas_error_payload(cola, _UNKNOWN_NAME)]
