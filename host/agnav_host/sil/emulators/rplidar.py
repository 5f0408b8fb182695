"""An emulated Slamtec RPLIDAR A1 on a pseudo-terminal, speaking the device's serial protocol.

It follows the document the driver follows (:mod:`agnav_host.lasers.rplidar`: Slamtec's *RPLIDAR Interface
Protocol and Application Notes* for the A1 & A2) and answers as the device does:

- STOP 0x25: leaves the scanning state, no answer.
- RESET 0x40: leaves the scanning state and, like a rebooting A1, prints its boot text (``RP LIDAR
  System.`` / ``Firmware Ver 1.29 - rc1, HW Ver 7`` / ``Model: 18``, the form an A1 is reported to print; the
  rc number is arbitrary here).
- GET_INFO 0x50: model 0x18 (an A1M8's), firmware 1.29, hardware 7 and a fixed 16-byte serial number.
- GET_HEALTH 0x52: status good, error code 0 (:attr:`RplidarEmulator.health` sets another answer).
- GET_SAMPLERATE 0x59: the time of one sample, 1 / (scan_hz x beams in a full circle), for both modes.
- SCAN 0x20 / FORCE_SCAN 0x21: the descriptor ``A5 5A 05 00 00 40 81``, then every published scan as one
  revolution of 5-byte samples: the newest scan first, then each one published after it. The first sample of
  each revolution has S = 1. A sensor-frame beam at angle ``a`` (counter-clockwise) is sent at the device
  heading ``-a`` (clockwise), in the order the device turns (heading 0 upwards), angle_q6 rounded to 1/64
  degree; distance_q2 is the range in quarter millimetres, 0 for no return (NaN, inf, or outside the
  geometry's range_min-range_max), quality 47 for a return (what an A1M8 reports for every valid sample) and
  0 for none. Only the geometry's beams are sent: a 270-degree geometry gives a 270-degree revolution.
  Samples are written at the device's pace, one sample time apart (in chunks of about 5 ms), unless
  ``pace=False``; a scan published while one is still being sent waits, and only the newest waits.
- any other request (EXPRESS_SCAN, SET_MOTOR_PWM, ...) is ignored, as the device ignores what it does not
  know, and a scan goes on; each request above ends a scan first (the device "will leave the Scanning state
  once it receives a new request"). A request with a payload (command bit 7 set) whose checksum is wrong is
  dropped.

A pty has no modem lines, so the motor (DTR) is not emulated: the emulator always "spins".
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from ...lasers.rplidar import (
    CMD_FORCE_SCAN,
    CMD_GET_HEALTH,
    CMD_GET_INFO,
    CMD_GET_SAMPLERATE,
    CMD_RESET,
    CMD_SCAN,
    CMD_STOP,
    DESCRIPTOR_HEALTH,
    DESCRIPTOR_INFO,
    DESCRIPTOR_SAMPLERATE,
    DESCRIPTOR_SCAN,
    ANGLE_Q6_FULL,
    DeviceInfo,
    Health,
    SampleRate,
    encode_descriptor,
    encode_health,
    encode_info,
    encode_samplerate,
    encode_samples,
    split_requests,
)
from .base import PublishedScan, ScanBoard, ScanGeometry, Stream, Transport

__all__ = ["RplidarEmulator", "A1M8_INFO"]

A1M8_INFO = DeviceInfo(model=0x18, firmware_major=1, firmware_minor=29, hardware=7,
                       serial=bytes.fromhex("A1B2C3D4E5F60718293A4B5C6D7E8F90"))
QUALITY_VALID = 47
_KNOWN = (CMD_STOP, CMD_RESET, CMD_GET_INFO, CMD_GET_HEALTH, CMD_GET_SAMPLERATE, CMD_SCAN, CMD_FORCE_SCAN)


class RplidarEmulator:
    """Serves one pty as an RPLIDAR A1 scanning ``geometry`` (module docstring for what it answers)."""

    def __init__(self, kind: str, geometry: ScanGeometry, *, info: DeviceInfo = A1M8_INFO, pace: bool = True) -> None:
        if kind != "rplidar":
            raise ValueError(f"RplidarEmulator emulates kind 'rplidar', not {kind!r}")
        self.kind = kind
        self.geometry = geometry
        self.info = info
        self.pace = pace
        self.health = Health(0, 0)
        self.board = ScanBoard()
        self.transport = Transport(self._serve)
        n_full = max(1, round(2.0 * math.pi / geometry.angle_increment_rad))
        self.sample_time_s = 1.0 / (geometry.scan_hz * n_full)
        self.requests: list[int] = []  # commands received, in order (for tests)
        self._inject = bytearray()
        self._lock = threading.Lock()
        # the beams in the device's order: heading (clockwise) ascending from 0
        a = geometry.angle_min_rad + geometry.angle_increment_rad * np.arange(geometry.n_beams)
        heading_deg = np.mod(-np.degrees(a), 360.0)
        q6 = np.rint(heading_deg * 64.0).astype(np.int64) % ANGLE_Q6_FULL
        self._order = np.argsort(q6, kind="stable")
        self._angle_q6 = q6[self._order]

    @property
    def boot_text(self) -> bytes:
        i = self.info
        return (f"RP LIDAR System.\r\nFirmware Ver {i.firmware_major}.{i.firmware_minor:02d} - rc1, "
                f"HW Ver {i.hardware}\r\nModel: {i.model:02X}\r\n").encode("ascii")

    # ---- ScannerEmulator ----------------------------------------------------------------------------------
    def start(self) -> str:
        return self.transport.open_pty()

    def publish(self, ranges_m: np.ndarray, t_s: float) -> None:
        r = np.asarray(ranges_m, dtype=float)
        if r.shape != (self.geometry.n_beams,):
            raise ValueError(f"rplidar emulator: expected {self.geometry.n_beams} ranges, got shape {r.shape}")
        self.board.publish(r, t_s)

    def close(self) -> None:
        self.board.close()
        self.transport.close()

    def inject(self, data: bytes) -> None:
        """Write ``data`` into the stream before the next samples (garbage on the line, for tests)."""
        with self._lock:
            self._inject += data

    # ---- the device ---------------------------------------------------------------------------------------
    def revolution_bytes(self, ranges_m: np.ndarray) -> bytes:
        """One revolution of samples for a scan of the geometry (the first with S = 1)."""
        g = self.geometry
        r = np.asarray(ranges_m, dtype=float)[self._order]
        ok = np.isfinite(r) & (r >= g.range_min_m) & (r <= g.range_max_m)
        q2 = np.where(ok, np.rint(np.where(ok, r, 0.0) * 4000.0), 0).astype(np.int64)
        ok &= (q2 > 0) & (q2 <= 0xFFFF)
        q2 = np.where(ok, q2, 0)
        start = np.zeros(len(r), dtype=bool)
        start[0] = True
        return encode_samples(start, np.where(ok, QUALITY_VALID, 0), self._angle_q6, q2)

    def _serve(self, stream: Stream, stop: threading.Event) -> None:
        buf = bytearray()
        scanning = False
        seq = -1  # the last scan sent
        rev = b""  # the revolution being sent
        sent = 0  # bytes of it sent
        t0 = 0.0
        while not stop.is_set():
            data = stream.read(4096, 0.005 if scanning else 0.05)
            if data:
                buf += data
                for cmd, _payload in split_requests(buf):
                    self.requests.append(cmd)
                    if cmd not in _KNOWN:
                        continue  # ignored, and a scan goes on
                    scanning, rev, sent = False, b"", 0  # any request it knows ends a scan
                    if cmd == CMD_STOP:
                        pass
                    elif cmd == CMD_RESET:
                        if stop.wait(0.005):
                            return
                        stream.write(self.boot_text)
                    elif cmd == CMD_GET_INFO:
                        stream.write(encode_descriptor(DESCRIPTOR_INFO) + encode_info(self.info))
                    elif cmd == CMD_GET_HEALTH:
                        stream.write(encode_descriptor(DESCRIPTOR_HEALTH) + encode_health(self.health))
                    elif cmd == CMD_GET_SAMPLERATE:
                        us = max(1, min(0xFFFF, round(self.sample_time_s * 1e6)))
                        stream.write(encode_descriptor(DESCRIPTOR_SAMPLERATE) + encode_samplerate(SampleRate(us, us)))
                    elif cmd in (CMD_SCAN, CMD_FORCE_SCAN):
                        if self.health.status == 2:
                            continue  # ignored in the protection stop state
                        stream.write(encode_descriptor(DESCRIPTOR_SCAN))
                        scanning, seq = True, -1
            if not scanning:
                continue
            with self._lock:
                junk, self._inject = bytes(self._inject), bytearray()
            if junk:
                stream.write(junk)
            if sent >= len(rev):
                scan: PublishedScan | None = self.board.next_after(seq, 0.0)
                if scan is None:
                    continue
                seq = scan.seq
                rev, sent, t0 = self.revolution_bytes(scan.ranges_m), 0, time.monotonic()
            if self.pace:
                due = min(len(rev) // 5, int((time.monotonic() - t0) / self.sample_time_s) + 1) * 5
            else:
                due = len(rev)
            if due > sent:
                stream.write(rev[sent:due])
                sent = due
