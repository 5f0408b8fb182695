"""Slamtec RPLIDAR A1/A2 over a serial port (``rplidar:/dev/ttyUSB0``): the wire codec and the driver.

The protocol is Slamtec's *RPLIDAR Interface Protocol and Application Notes, applied to RPLIDAR A1 & A2*
(rev. 1.1, 2018-03-08; the A2 "Communication Protocol" of 2019 has the same sections):

- section 2 "Protocol Basics", *Request Packets' Format* (Figure 2-4): a request is ``0xA5`` and a command
  byte; a request with a payload adds a size byte, the payload and a checksum, the XOR of every byte before
  it starting with the ``0xA5``. Every request with a payload in the document's table has bit 7 of its
  command set (EXPRESS_SCAN 0x82, GET_LIDAR_CONF 0x84, SET_MOTOR_PWM 0xF0), which is how
  :func:`split_requests` knows one.
- *Response Packets' Format* (Figures 2-6 to 2-8): a response descriptor is ``0xA5 0x5A``, a little-endian
  32-bit word holding the 30-bit data response length and the 2-bit send mode in its top bits (0 single,
  1 multiple), and a data type byte.
- section 4 "Request and Response Data" (Figure 4-1): STOP 0x25 and RESET 0x40 (no answer; wait >= 1 ms /
  >= 2 ms before the next request), SCAN 0x20 and FORCE_SCAN 0x21 (descriptor ``A5 5A 05 00 00 40 81``,
  then one 5-byte sample after another), EXPRESS_SCAN 0x82 (not used here), GET_INFO 0x50 (``A5 5A 14 00 00
  00 04``: model, firmware minor, firmware major, hardware, 16-byte serial number, printed least significant
  byte first), GET_HEALTH 0x52 (``A5 5A 03 00 00 00 06``: status 0 good / 1 warning / 2 error = protection
  stop, then the 16-bit error code, low byte first), GET_SAMPLERATE 0x59 (``A5 5A 04 00 00 00 15``: the
  time of one sample in SCAN and in EXPRESS_SCAN mode, us, 16 bits each, firmware >= 1.17).
- Figures 4-4/4-5, the measurement sample: byte 0 holds the start flag S in bit 0, its inverse !S in bit 1
  and the 6-bit quality in bits 2-7; byte 1 holds the check bit C (always 1) in bit 0 and angle_q6 bits 0-6
  in bits 1-7; byte 2 angle_q6 bits 7-14; bytes 3-4 distance_q2, little-endian. Heading = angle_q6 / 64
  degrees in [0, 360), distance = distance_q2 / 4 mm, 0 = invalid. S = 1 marks the first sample of a new
  360-degree scan.
- section 5 "Application Notes" (Figure 5-1): GET_HEALTH before SCAN; in the protection stop state a RESET
  may bring the device back, repeated protection stops mean it is damaged.

Facts from elsewhere, and where: the A1 and the A2 run at 115200 baud (their datasheets' *communication
interface* tables; the A2M12 talks at 256000, ``?baud=256000``); the A1M8 measures 0.15-12 m (A1M8 datasheet,
*Measurement Performance*); the motor of an A1/A2 on Slamtec's USB adapter runs while DTR is deasserted
(pyserial ``dtr=False``), and an A2 takes the motor PWM duty by SET_MOTOR_PWM 0xF0 with a 16-bit payload,
0-1023, 660 by default (``DEFAULT_MOTOR_PWM`` / ``MAX_MOTOR_PWM`` of the SDK's published ``rplidar_cmd.h``).
The document gives no table of model bytes: an A1M8 answers 0x18 (24) with firmware 1.29 and hardware 7, a
sample time of 508 us, and quality 47 for every valid sample, as its users report; the upper nibble is the
series (1 = A1, 2 = A2, 3 = A3, 6 = S1).

Angles. The device's heading turns **clockwise** seen from above, 0 at the direction the document's
Figure 4-6 marks. The :class:`~agnav_host.types.LaserScan` frame is counter-clockwise with 0 forward, so a
sample at device heading ``theta`` lies at ``-theta`` (wrapped to [-pi, pi)); the scanner's 0-degree mark is
the sensor frame's forward axis and :class:`~agnav_host.lasers.base.LaserMount` ``yaw_rad`` turns it on the
robot.

Scans. The driver gathers samples into revolutions (a revolution ends where the next sample with S = 1
arrives; samples before the first S = 1 are dropped) and resamples each onto a fixed grid of ``beams``
beams (360 of 1 degree by default, ``?beams=N``), beam 0 at -pi: a beam takes the valid sample nearest its
angle within half a step, else NaN. Valid means distance_q2 > 0 and ``range_min`` <= distance <=
``range_max`` (defaults 0.15 m and 12 m, the A1M8's; ``?range_min=`` / ``?range_max=`` in m).

Time stamps. The device sends none, so ``LaserInfo.stamps`` is ``"arrival"``. A revolution's stamp is the
host time its last sample was read, minus half the revolution's duration (its sample count times the
GET_SAMPLERATE sample time, or the arrival span when the device does not answer GET_SAMPLERATE), minus the
stated latency ``latency_s``: the time one 5-byte sample takes on the wire (50 bits at the baud rate,
0.43 ms at 115200) plus 1 ms assumed for the USB-serial adapter's buffering. ``?latency_ms=`` states
another figure.

Connecting. The port is opened with DTR deasserted (the A1/A2 motor spins up while the driver asks),
then STOP, a 50 ms pause and a flush of what was in flight, GET_HEALTH (error -> LaserError: RESET or
power-cycle it), GET_INFO, GET_SAMPLERATE (firmware >= 1.17; optional), SET_MOTOR_PWM for an A2 (``?pwm=``
sets the duty for any model), SCAN and its descriptor. An answer that does not begin ``A5 5A`` is a
WrongDeviceError naming what came back; no answer at all is a LaserAddressError. :meth:`close` sends STOP
(and PWM 0 to an A2), asserts DTR and clears HUPCL so that DTR stays asserted and the motor stays off.

Reconnects. A USB serial port that is unplugged makes reads raise ``SerialException`` (an ``OSError``);
:class:`~agnav_host.lasers.base.ThreadedLaser` then reopens the path until it answers again. A stream that
goes silent for ``stall_s`` (2 s, ``?stall_s=``; 3 s more after SCAN for the motor to settle) while scanning
counts as lost too, so a device that stopped (a protection stop ends the scanning state) is asked for its
health again.
"""

from __future__ import annotations

import errno
import math
import struct
import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .base import (
    LaserAddressError,
    LaserError,
    LaserInfo,
    LaserMount,
    TelegramError,
    ThreadedLaser,
    WrongDeviceError,
)

if TYPE_CHECKING:
    import serial  # pyserial, imported when a port is opened

    from ..types import LaserScan
    from . import LaserUrl

__all__ = [
    "SYNC", "SYNC2", "CMD_STOP", "CMD_RESET", "CMD_SCAN", "CMD_FORCE_SCAN", "CMD_EXPRESS_SCAN", "CMD_GET_INFO",
    "CMD_GET_HEALTH", "CMD_GET_SAMPLERATE", "CMD_SET_MOTOR_PWM", "TYPE_INFO", "TYPE_HEALTH", "TYPE_SAMPLERATE",
    "TYPE_SAMPLE", "MODE_SINGLE", "MODE_MULTIPLE", "ANGLE_Q6_FULL", "DESCRIPTOR_SCAN", "DESCRIPTOR_INFO",
    "DESCRIPTOR_HEALTH", "DESCRIPTOR_SAMPLERATE", "Descriptor", "DeviceInfo", "Health",
    "SampleRate", "Sample", "SampleBlock", "request", "split_requests", "encode_descriptor", "parse_descriptor",
    "expect_descriptor", "encode_info", "parse_info", "encode_health", "parse_health", "encode_samplerate",
    "parse_samplerate", "encode_sample", "encode_samples", "parse_sample", "SampleStream", "Revolution",
    "RevolutionAssembler", "resample", "describe_bytes", "RplidarScanner",
]

# ---- protocol constants (section 4, Figure 4-1; data types from the descriptors of each request) ---------
SYNC = 0xA5
SYNC2 = 0x5A
CMD_STOP = 0x25
CMD_RESET = 0x40
CMD_SCAN = 0x20
CMD_FORCE_SCAN = 0x21
CMD_EXPRESS_SCAN = 0x82
CMD_GET_INFO = 0x50
CMD_GET_HEALTH = 0x52
CMD_GET_SAMPLERATE = 0x59
CMD_SET_MOTOR_PWM = 0xF0
TYPE_INFO = 0x04
TYPE_HEALTH = 0x06
TYPE_SAMPLERATE = 0x15
TYPE_SAMPLE = 0x81
MODE_SINGLE = 0
MODE_MULTIPLE = 1
DESCRIPTOR_LEN = 7
SAMPLE_LEN = 5
INFO_LEN = 20
HEALTH_LEN = 3
SAMPLERATE_LEN = 4
ANGLE_Q6_FULL = 360 * 64  # angle_q6 lies in [0, 23040)
MAX_MOTOR_PWM = 1023
DEFAULT_MOTOR_PWM = 660
HEALTH_NAMES = {0: "good", 1: "warning", 2: "error (protection stop)"}
SERIES = {1: "A1", 2: "A2", 3: "A3", 6: "S1"}
_COMMAND_NAMES = {CMD_STOP: "STOP", CMD_RESET: "RESET", CMD_SCAN: "SCAN", CMD_FORCE_SCAN: "FORCE_SCAN",
                  CMD_EXPRESS_SCAN: "EXPRESS_SCAN", CMD_GET_INFO: "GET_INFO", CMD_GET_HEALTH: "GET_HEALTH",
                  CMD_GET_SAMPLERATE: "GET_SAMPLERATE", CMD_SET_MOTOR_PWM: "SET_MOTOR_PWM"}


# ---- requests --------------------------------------------------------------------------------------------
def request(cmd: int, payload: bytes | None = None) -> bytes:
    """The request packet for ``cmd``: ``A5 cmd``, or with a payload ``A5 cmd size payload checksum``."""
    if not 0 <= cmd <= 0xFF:
        raise ValueError(f"RPLIDAR command must be a byte, got {cmd!r}")
    if payload is None:
        return bytes((SYNC, cmd))
    if len(payload) > 255:
        raise ValueError(f"RPLIDAR request payload holds at most 255 bytes, got {len(payload)}")
    body = bytes((SYNC, cmd, len(payload))) + bytes(payload)
    chk = 0
    for b in body:
        chk ^= b
    return body + bytes((chk,))


def split_requests(buf: bytearray) -> list[tuple[int, bytes]]:
    """Take whole requests off the front of ``buf`` (the device side): ``[(cmd, payload), ...]``.

    Bytes before an ``0xA5`` are dropped, a request whose checksum is wrong is dropped (as the device discards
    it), and an incomplete request stays in ``buf`` for the next call."""
    out: list[tuple[int, bytes]] = []
    while True:
        start = buf.find(bytes((SYNC,)))
        if start < 0:
            buf.clear()
            return out
        del buf[:start]
        if len(buf) < 2:
            return out
        cmd = buf[1]
        if not cmd & 0x80:
            out.append((cmd, b""))
            del buf[:2]
            continue
        if len(buf) < 3 or len(buf) < 4 + buf[2]:
            return out
        size = buf[2]
        chk = 0
        for b in buf[:3 + size]:
            chk ^= b
        if chk == buf[3 + size]:
            out.append((cmd, bytes(buf[3:3 + size])))
            del buf[:4 + size]
        else:
            del buf[:1]  # not a request after all: look for the next 0xA5


# ---- response descriptors ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Descriptor:
    length: int  # bytes of one data response packet (30 bits)
    mode: int  # send mode: 0 single response, 1 multiple responses
    dtype: int  # data type

    def __str__(self) -> str:
        mode = {MODE_SINGLE: "single", MODE_MULTIPLE: "multiple"}.get(self.mode, f"mode {self.mode}")
        return f"{self.length} bytes, {mode}, type 0x{self.dtype:02X}"


DESCRIPTOR_SCAN = Descriptor(SAMPLE_LEN, MODE_MULTIPLE, TYPE_SAMPLE)
DESCRIPTOR_INFO = Descriptor(INFO_LEN, MODE_SINGLE, TYPE_INFO)
DESCRIPTOR_HEALTH = Descriptor(HEALTH_LEN, MODE_SINGLE, TYPE_HEALTH)
DESCRIPTOR_SAMPLERATE = Descriptor(SAMPLERATE_LEN, MODE_SINGLE, TYPE_SAMPLERATE)


def encode_descriptor(d: Descriptor) -> bytes:
    if not 0 <= d.length < 1 << 30 or not 0 <= d.mode < 4 or not 0 <= d.dtype <= 0xFF:
        raise ValueError(f"RPLIDAR descriptor out of range: {d}")
    return bytes((SYNC, SYNC2)) + struct.pack("<I", d.length | d.mode << 30) + bytes((d.dtype,))


def parse_descriptor(data: bytes) -> Descriptor:
    """A response descriptor from its 7 bytes; TelegramError when truncated or without ``A5 5A``."""
    if len(data) < DESCRIPTOR_LEN:
        raise TelegramError(f"RPLIDAR response descriptor truncated: {len(data)} of 7 bytes ({data.hex(' ')})")
    if data[0] != SYNC or data[1] != SYNC2:
        raise TelegramError(f"RPLIDAR response descriptor must start A5 5A, got {data[:DESCRIPTOR_LEN].hex(' ')}")
    word = struct.unpack_from("<I", data, 2)[0]
    return Descriptor(word & 0x3FFFFFFF, word >> 30, data[6])


def expect_descriptor(data: bytes, want: Descriptor, what: str) -> Descriptor:
    """:func:`parse_descriptor` and check it is the one ``what`` (e.g. "GET_INFO") is answered with."""
    d = parse_descriptor(data)
    if d != want:
        raise TelegramError(f"RPLIDAR {what}: descriptor mismatch, expected {want}, got {d}")
    return d


# ---- single responses -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DeviceInfo:
    model: int
    firmware_major: int
    firmware_minor: int
    hardware: int
    serial: bytes  # 16 bytes, serialnumber[0] first

    @property
    def firmware(self) -> tuple[int, int]:
        return self.firmware_major, self.firmware_minor

    @property
    def serial_hex(self) -> str:
        """The serial number as text, serialnumber[0] (the least significant byte) first."""
        return self.serial.hex().upper()

    @property
    def series(self) -> str:
        return SERIES.get(self.model >> 4, f"series {self.model >> 4}")

    def describe(self) -> str:
        return (f"RPLIDAR {self.series} (model 0x{self.model:02X}), firmware {self.firmware_major}."
                f"{self.firmware_minor:02d}, hardware {self.hardware}")


def encode_info(info: DeviceInfo) -> bytes:
    if len(info.serial) != 16:
        raise ValueError(f"RPLIDAR serial number is 16 bytes, got {len(info.serial)}")
    return bytes((info.model, info.firmware_minor, info.firmware_major, info.hardware)) + bytes(info.serial)


def parse_info(data: bytes) -> DeviceInfo:
    if len(data) < INFO_LEN:
        raise TelegramError(f"RPLIDAR GET_INFO answer truncated: {len(data)} of {INFO_LEN} bytes")
    return DeviceInfo(model=data[0], firmware_minor=data[1], firmware_major=data[2], hardware=data[3],
                      serial=bytes(data[4:INFO_LEN]))


@dataclass(frozen=True)
class Health:
    status: int  # 0 good, 1 warning, 2 error (protection stop)
    error_code: int

    @property
    def name(self) -> str:
        return HEALTH_NAMES.get(self.status, f"status {self.status}")


def encode_health(h: Health) -> bytes:
    return bytes((h.status,)) + struct.pack("<H", h.error_code)


def parse_health(data: bytes) -> Health:
    if len(data) < HEALTH_LEN:
        raise TelegramError(f"RPLIDAR GET_HEALTH answer truncated: {len(data)} of {HEALTH_LEN} bytes")
    if data[0] not in HEALTH_NAMES:
        raise TelegramError(f"RPLIDAR GET_HEALTH: status must be 0, 1 or 2, got {data[0]}")
    return Health(data[0], struct.unpack_from("<H", data, 1)[0])


@dataclass(frozen=True)
class SampleRate:
    t_standard_us: int  # one sample in SCAN mode
    t_express_us: int  # one sample in EXPRESS_SCAN mode


def encode_samplerate(s: SampleRate) -> bytes:
    return struct.pack("<HH", s.t_standard_us, s.t_express_us)


def parse_samplerate(data: bytes) -> SampleRate:
    if len(data) < SAMPLERATE_LEN:
        raise TelegramError(f"RPLIDAR GET_SAMPLERATE answer truncated: {len(data)} of {SAMPLERATE_LEN} bytes")
    a, b = struct.unpack_from("<HH", data, 0)
    return SampleRate(a, b)


# ---- measurement samples (Figures 4-4, 4-5) ---------------------------------------------------------------
@dataclass(frozen=True)
class Sample:
    start: bool  # S: first sample of a new 360-degree scan
    quality: int  # 0-63
    angle_q6: int  # heading * 64, clockwise, [0, 23040)
    distance_q2: int  # distance * 4 (mm), 0 = invalid

    @property
    def angle_deg(self) -> float:
        return self.angle_q6 / 64.0

    @property
    def distance_mm(self) -> float:
        return self.distance_q2 / 4.0


def encode_sample(start: bool, quality: int, angle_q6: int, distance_q2: int) -> bytes:
    if not 0 <= quality < 64 or not 0 <= angle_q6 < ANGLE_Q6_FULL or not 0 <= distance_q2 < 1 << 16:
        raise ValueError(f"RPLIDAR sample out of range: quality {quality}, angle_q6 {angle_q6}, "
                         f"distance_q2 {distance_q2}")
    s = 1 if start else 0
    return bytes((quality << 2 | (s ^ 1) << 1 | s, (angle_q6 & 0x7F) << 1 | 1, angle_q6 >> 7,
                  distance_q2 & 0xFF, distance_q2 >> 8))


def encode_samples(start: np.ndarray, quality: np.ndarray, angle_q6: np.ndarray, distance_q2: np.ndarray) -> bytes:
    """:func:`encode_sample` for arrays of equal length, as one byte string (the emulator's revolution)."""
    s = np.asarray(start, dtype=np.uint8) & 1
    q = np.asarray(quality, dtype=np.int64)
    a = np.asarray(angle_q6, dtype=np.int64)
    d = np.asarray(distance_q2, dtype=np.int64)
    if np.any((q < 0) | (q > 63)) or np.any((a < 0) | (a >= ANGLE_Q6_FULL)) or np.any((d < 0) | (d > 0xFFFF)):
        raise ValueError("RPLIDAR samples out of range (quality 0-63, angle_q6 0-23039, distance_q2 0-65535)")
    out = np.empty((len(a), SAMPLE_LEN), dtype=np.uint8)
    out[:, 0] = q << 2 | (s ^ 1) << 1 | s
    out[:, 1] = (a & 0x7F) << 1 | 1
    out[:, 2] = a >> 7
    out[:, 3] = d & 0xFF
    out[:, 4] = d >> 8
    return out.tobytes()


def _sample_problem(b0: int, b1: int, b2: int) -> str:
    if (b0 & 1) == (b0 >> 1 & 1):
        return f"start flag S={b0 & 1} and its inverse !S={b0 >> 1 & 1} must differ"
    if not b1 & 1:
        return "check bit C must be 1"
    q6 = b1 >> 1 | b2 << 7
    if q6 >= ANGLE_Q6_FULL:
        return f"angle {q6 / 64:.3f} deg is not below 360"
    return ""


def parse_sample(data: bytes) -> Sample:
    """One 5-byte measurement sample; TelegramError when truncated or its check bits are wrong."""
    if len(data) < SAMPLE_LEN:
        raise TelegramError(f"RPLIDAR sample truncated: {len(data)} of 5 bytes ({bytes(data).hex(' ')})")
    b0, b1, b2, b3, b4 = data[:SAMPLE_LEN]
    problem = _sample_problem(b0, b1, b2)
    if problem:
        raise TelegramError(f"RPLIDAR sample {bytes(data[:SAMPLE_LEN]).hex(' ')}: {problem}")
    return Sample(bool(b0 & 1), b0 >> 2, b1 >> 1 | b2 << 7, b3 | b4 << 8)


@dataclass(frozen=True)
class SampleBlock:
    """Decoded samples as arrays, one entry per sample."""

    start: np.ndarray  # bool
    quality: np.ndarray  # uint8
    angle_q6: np.ndarray  # int64
    distance_q2: np.ndarray  # int64

    @staticmethod
    def empty() -> "SampleBlock":
        z = np.zeros(0, dtype=np.int64)
        return SampleBlock(np.zeros(0, dtype=bool), np.zeros(0, dtype=np.uint8), z, z.copy())

    def __len__(self) -> int:
        return len(self.angle_q6)

    def part(self, lo: int, hi: int) -> "SampleBlock":
        return SampleBlock(self.start[lo:hi], self.quality[lo:hi], self.angle_q6[lo:hi], self.distance_q2[lo:hi])

    def samples(self) -> list[Sample]:
        return [Sample(bool(s), int(q), int(a), int(d))
                for s, q, a, d in zip(self.start, self.quality, self.angle_q6, self.distance_q2)]


def _valid_rows(rows: np.ndarray) -> npt.NDArray[np.bool_]:
    b0 = rows[:, 0].astype(np.int64)
    b1 = rows[:, 1].astype(np.int64)
    b2 = rows[:, 2].astype(np.int64)
    valid: npt.NDArray[np.bool_] = ((b0 & 1) != (b0 >> 1 & 1)) & (b1 & 1 == 1) & ((b1 >> 1 | b2 << 7) < ANGLE_Q6_FULL)
    return valid


def _decode_rows(rows: np.ndarray) -> SampleBlock:
    r = rows.astype(np.int64)
    return SampleBlock((r[:, 0] & 1).astype(bool), (r[:, 0] >> 2).astype(np.uint8), r[:, 1] >> 1 | r[:, 2] << 7,
                       r[:, 3] | r[:, 4] << 8)


class SampleStream:
    """Cuts a SCAN stream into samples and recovers the 5-byte alignment after garbage.

    In step (``synced``) every 5 bytes are one sample while their check bits hold (S != !S, C = 1, angle below
    360 degrees). The first sample that breaks them ends the alignment: bytes are then dropped one at a time
    until ``confirm`` (3) consecutive samples pass the checks, and reading goes on from there; ``resyncs``
    counts the losses and ``skipped`` the dropped bytes. A garbage window that passes the check bits by chance
    (about one in six) is taken as one sample before the loss is seen. After a loss, up to ``confirm`` samples
    wait in the buffer until enough bytes have come to confirm them. Bytes that end in a partial sample wait
    for the rest."""

    def __init__(self, synced: bool = True, confirm: int = 3) -> None:
        self.synced = synced
        self.confirm = confirm
        self.resyncs = 0
        self.skipped = 0
        self._buf = bytearray()

    def feed(self, data: bytes) -> SampleBlock:
        self._buf += data
        parts: list[np.ndarray] = []
        buf = self._buf
        while True:
            if self.synced:
                k = len(buf) // SAMPLE_LEN
                if k == 0:
                    break
                rows = np.frombuffer(bytes(buf[:k * SAMPLE_LEN]), dtype=np.uint8).reshape(k, SAMPLE_LEN)
                ok = _valid_rows(rows)
                if ok.all():
                    parts.append(rows)
                    del buf[:k * SAMPLE_LEN]
                    break
                bad = int(np.argmin(ok))
                if bad:
                    parts.append(rows[:bad])
                del buf[:bad * SAMPLE_LEN]
                self.synced = False
                self.resyncs += 1
            else:
                need = self.confirm * SAMPLE_LEN
                if len(buf) < need:
                    break
                found = self._find_run(buf, need)
                if found is None:
                    drop = len(buf) - need + 1
                    self.skipped += drop
                    del buf[:drop]
                    break
                self.skipped += found
                del buf[:found]
                self.synced = True
        if not parts:
            return SampleBlock.empty()
        return _decode_rows(np.concatenate(parts))

    def _find_run(self, buf: bytearray, need: int) -> int | None:
        """The first offset where ``confirm`` consecutive samples pass the checks."""
        arr = np.frombuffer(bytes(buf), dtype=np.uint8)
        n = len(arr) - SAMPLE_LEN + 1  # windows that hold a whole sample
        if n <= 0:
            return None
        win = np.lib.stride_tricks.sliding_window_view(arr, SAMPLE_LEN)
        ok = _valid_rows(win)
        last = len(arr) - need  # the last offset that has a whole run after it
        for o in range(0, last + 1):
            if all(ok[o + j * SAMPLE_LEN] for j in range(self.confirm)):
                return o
        return None


# ---- revolutions and the beam grid -------------------------------------------------------------------------
@dataclass(frozen=True)
class Revolution:
    angle_q6: np.ndarray
    distance_q2: np.ndarray
    quality: np.ndarray
    t_first_s: float  # host time the chunk holding the first sample was read
    t_last_s: float  # host time the chunk holding the last sample was read

    def __len__(self) -> int:
        return len(self.angle_q6)


class RevolutionAssembler:
    """Gathers samples into revolutions: a revolution ends where the next sample with S = 1 begins; samples
    before the first S = 1 belong to no whole revolution and are dropped, and so is a revolution of fewer than
    ``min_samples`` samples (a start flag seen twice in a row)."""

    def __init__(self, min_samples: int = 5) -> None:
        self.min_samples = min_samples
        self._parts: list[SampleBlock] = []
        self._t_first = 0.0
        self._t_last = 0.0
        self._open = False  # a revolution has begun (an S = 1 was seen)

    def reset(self) -> None:
        self._parts, self._open = [], False

    def push(self, block: SampleBlock, t_s: float) -> list[Revolution]:
        """Add the samples of one read (``t_s``: when it was read); returns the revolutions it completed."""
        out: list[Revolution] = []
        n = len(block)
        if n == 0:
            return out
        cuts = sorted({0, *np.flatnonzero(block.start).tolist()})
        for i, lo in enumerate(cuts):
            hi = cuts[i + 1] if i + 1 < len(cuts) else n
            if block.start[lo]:
                rev = self._close()
                if rev is not None:
                    out.append(rev)
                self._open = True
                self._t_first = t_s
            if self._open:
                self._parts.append(block.part(lo, hi))
                self._t_last = t_s
        return out

    def _close(self) -> Revolution | None:
        parts, self._parts = self._parts, []
        if not self._open or not parts:
            return None
        a = np.concatenate([p.angle_q6 for p in parts])
        if len(a) < self.min_samples:
            return None
        return Revolution(a, np.concatenate([p.distance_q2 for p in parts]),
                          np.concatenate([p.quality for p in parts]), self._t_first, self._t_last)


def resample(angle_q6: np.ndarray, distance_q2: np.ndarray, beams: int, range_min_m: float,
             range_max_m: float) -> np.ndarray:
    """Ranges (m) on the grid of ``beams`` beams from -pi, counter-clockwise, 2 pi / beams apart: each beam
    the nearest valid sample within half a step (device heading theta lies at -theta), else NaN."""
    step = 2.0 * math.pi / beams
    a = -np.asarray(angle_q6, dtype=float) * (math.pi / (180.0 * 64.0))
    a = np.mod(a + math.pi, 2.0 * math.pi) - math.pi
    d = np.asarray(distance_q2, dtype=float) / 4000.0
    ok = (np.asarray(distance_q2) > 0) & (d >= range_min_m) & (d <= range_max_m)
    out = np.full(beams, np.nan)
    if not ok.any():
        return out
    a, d = a[ok], d[ok]
    pos = (a + math.pi) / step
    idx = np.rint(pos).astype(np.int64)
    err = np.abs(pos - idx)  # in steps, <= 0.5 by construction
    idx %= beams
    order = np.lexsort((err, idx))  # by beam, nearest first
    first = np.unique(idx[order], return_index=True)[1]
    chosen = order[first]
    out[idx[chosen]] = d[chosen]
    return out


# ---- what came back when it was not an RPLIDAR ---------------------------------------------------------------
def describe_bytes(data: bytes) -> str:
    """A short description of an answer that is not an RPLIDAR response, for the WrongDeviceError text."""
    if not data:
        return "nothing"
    printable = sum(1 for b in data if 32 <= b < 127 or b in (9, 10, 13))
    if printable >= 0.8 * len(data):
        text = data.decode("ascii", "replace")
        shown = text[:60].encode("unicode_escape").decode("ascii")
        hint = ""
        if "RP LIDAR" in text:
            hint = " (an RPLIDAR's boot text: it has just reset; try again)"
        elif text.lstrip().startswith("$") and "," in text:
            hint = " (NMEA sentences: a GPS receiver or another NMEA instrument)"
        elif "SCIP" in text or "\n\n" in text:
            hint = " (SCIP replies: a Hokuyo URG, use urg:PATH)"
        return f"ASCII text \"{shown}\"{'...' if len(text) > 60 else ''}{hint}"
    return f"bytes {data[:24].hex(' ')}{' ...' if len(data) > 24 else ''}"


# ---- the driver --------------------------------------------------------------------------------------------
_OPTIONS = ("baud", "beams", "pwm", "range_min", "range_max", "latency_ms", "stall_s")
_MOUNT_KEYS = ("x", "y", "yaw", "pitch", "height")  # the mount, read by ``agnav run`` from the same URL


class RplidarScanner(ThreadedLaser):
    """``rplidar:DEVICE[?baud=115200&beams=360&pwm=660&range_min=0.15&range_max=12&latency_ms=..&stall_s=2]``:
    an RPLIDAR A1/A2 in SCAN mode (module docstring: frames, grid, stamps)."""

    kind = "rplidar"
    adapter_latency_s = 0.001  # assumed USB-serial adapter buffering, part of the stated latency
    answer_timeout_s = 1.0  # for each single answer while connecting
    samplerate_timeout_s = 0.3  # GET_SAMPLERATE is optional (firmware >= 1.17)
    min_samples = 5
    spinup_s = 3.0  # after SCAN, the wait for the first samples allowed on top of stall_s

    def __init__(self, url: LaserUrl, mount: LaserMount | None = None) -> None:
        super().__init__(url.text, mount)
        from . import LaserUrlError  # the package is loaded by the time a driver is built

        unknown = [k for k, _ in url.options if k not in _OPTIONS and k not in _MOUNT_KEYS]
        if unknown:
            raise LaserUrlError(f"--laser {url.text!r}: unknown option {unknown[0]!r}; rplidar takes "
                                f"{', '.join(_OPTIONS)}")

        def number(key: str, default: float, lo: float, hi: float, integer: bool = False) -> float:
            text = url.option(key)
            if text is None:
                return default
            try:
                v = int(text) if integer else float(text)
            except ValueError:
                v = math.nan
            if not lo <= v <= hi:
                raise LaserUrlError(f"--laser {url.text!r}: {key} must be a {'whole ' if integer else ''}number "
                                    f"{lo:g}-{hi:g}, got {text!r}")
            return v

        self.path = url.path
        self.baud = int(number("baud", 115200, 1200, 4_000_000, integer=True))
        self.beams = int(number("beams", 360, 8, 8192, integer=True))
        self.pwm: int | None = None if url.option("pwm") is None else int(number("pwm", 0, 0, MAX_MOTOR_PWM, True))
        self.range_min_m = number("range_min", 0.15, 0.0, 100.0)
        self.range_max_m = number("range_max", 12.0, 0.01, 100.0)
        if self.range_min_m >= self.range_max_m:
            raise LaserUrlError(f"--laser {url.text!r}: range_min must be below range_max")
        wire_s = SAMPLE_LEN * 10 / self.baud
        self.latency_s = number("latency_ms", (wire_s + self.adapter_latency_s) * 1e3, 0.0, 1000.0) / 1e3
        self.stall_s = number("stall_s", 2.0, 0.2, 3600.0)
        self.device_info: DeviceInfo | None = None
        self.health: Health | None = None
        self.sample_time_s: float | None = None  # from GET_SAMPLERATE
        self._ser: serial.Serial | None = None
        self._stream = SampleStream()
        self._revs = RevolutionAssembler(self.min_samples)
        self._ready: deque[LaserScan] = deque()
        self._problem = ""
        self._last_data = 0.0

    # ---- connection ----------------------------------------------------------------------------------------
    def _open(self) -> serial.Serial:
        import serial  # pyserial

        ser = serial.Serial()
        ser.port = self.path
        ser.baudrate = self.baud
        ser.timeout = 0.05
        ser.write_timeout = 1.0
        ser.dtr = False  # the A1/A2 motor runs while DTR is deasserted (ignored by ports without modem lines)
        ser.rts = False
        try:
            ser.exclusive = True
        except (AttributeError, ValueError):
            pass
        try:
            ser.open()
        except (OSError, ValueError) as e:
            raise _open_error(self.path, e) from None
        return ser

    def _connect(self, timeout_s: float) -> LaserInfo:
        self._disconnect()
        self._ser = ser = self._open()
        try:
            return self._identify_and_scan(ser, timeout_s)
        except BaseException:
            self._disconnect()
            raise

    def _identify_and_scan(self, ser: serial.Serial, timeout_s: float) -> LaserInfo:
        answer_s = min(self.answer_timeout_s, max(timeout_s, 0.2))
        self._quiet(ser)
        try:
            health = parse_health(self._ask(ser, CMD_GET_HEALTH, DESCRIPTOR_HEALTH, answer_s))
        except WrongDeviceError as e:
            if "boot text" not in str(e):
                raise
            time.sleep(0.1)  # it has just rebooted: let the text end, then ask again
            self._quiet(ser)
            health = parse_health(self._ask(ser, CMD_GET_HEALTH, DESCRIPTOR_HEALTH, answer_s))
        self.health = health
        if health.status == 2:
            raise LaserError(f"{self.path}: the RPLIDAR reports health error (protection stop), error code "
                             f"0x{health.error_code:04X}: RESET it or power-cycle it (unplug the USB adapter) and "
                             "start again; repeated protection stops mean the scanner is damaged")
        if health.status == 1:
            self.stats.last_error = (f"{self.path}: the RPLIDAR reports a health warning, error code "
                                     f"0x{health.error_code:04X} (it still scans)")
        info = parse_info(self._ask(ser, CMD_GET_INFO, DESCRIPTOR_INFO, answer_s))
        self.device_info = info
        self.sample_time_s = None
        if info.firmware >= (1, 17):
            try:
                rate = parse_samplerate(self._ask(ser, CMD_GET_SAMPLERATE, DESCRIPTOR_SAMPLERATE,
                                                  self.samplerate_timeout_s))
                if rate.t_standard_us > 0:
                    self.sample_time_s = rate.t_standard_us * 1e-6
            except LaserAddressError:
                self._quiet(ser)  # not answered: stamps fall back to the arrival span
        pwm = self.pwm if self.pwm is not None else (DEFAULT_MOTOR_PWM if info.model >> 4 == 2 else None)
        if pwm is not None:
            ser.write(request(CMD_SET_MOTOR_PWM, struct.pack("<H", pwm)))
        self._stream = SampleStream(synced=True)
        self._revs = RevolutionAssembler(self.min_samples)
        self._ready.clear()
        self._problem = ""
        ser.write(request(CMD_SCAN))
        expect_descriptor(self._read_exact(ser, DESCRIPTOR_LEN, answer_s, "SCAN", True), DESCRIPTOR_SCAN,
                          "SCAN")
        ser.timeout = 0.1
        self._last_data = time.monotonic() + self.spinup_s  # samples flow once the motor runs steadily
        return LaserInfo(kind=self.kind, address=self.path, model=info.describe(), serial=info.serial_hex,
                         stamps="arrival", latency_s=self.latency_s, scan_hz=0.0)

    def _quiet(self, ser: serial.Serial) -> None:
        """STOP, wait for the bytes in flight, drop them (a scan left running, the boot text after a reset)."""
        ser.write(request(CMD_STOP))
        time.sleep(0.05)
        ser.reset_input_buffer()

    def _read_exact(self, ser: serial.Serial, n: int, timeout_s: float, what: str, descriptor: bool) -> bytes:
        """Up to ``n`` bytes within ``timeout_s``. For a descriptor: LaserAddressError when nothing came,
        WrongDeviceError (saying what came) when it does not start ``A5 5A``."""
        end = time.monotonic() + timeout_s
        data = b""
        while len(data) < n:
            left = end - time.monotonic()
            if left <= 0:
                break
            ser.timeout = min(0.05, left)
            data += ser.read(n - len(data))
            if descriptor and data and (data[0] != SYNC or (len(data) >= 2 and data[1] != SYNC2)):
                break  # not an RPLIDAR answer: no need to wait for the rest
        if not descriptor:
            return data
        if not data:
            raise LaserAddressError(
                f"{self.path}: no answer to {what} within {timeout_s:g} s at {self.baud} baud: is an RPLIDAR "
                "connected and powered (the A1/A2 need their 5 V supply)? An A2M12 talks at 256000 "
                f"baud: rplidar:{self.path}?baud=256000")
        if data[0] != SYNC or (len(data) >= 2 and data[1] != SYNC2):
            time.sleep(0.2)
            ser.timeout = 0
            data += ser.read(200)
            raise WrongDeviceError(
                f"{self.path}: the device answered {what} with {describe_bytes(data)}, not an RPLIDAR response "
                f"descriptor (A5 5A ...): is this the scanner's port, at the right baud rate ({self.baud})?")
        return data

    def _ask(self, ser: serial.Serial, cmd: int, want: Descriptor, timeout_s: float) -> bytes:
        what = _COMMAND_NAMES.get(cmd, f"0x{cmd:02X}")
        ser.write(request(cmd))
        expect_descriptor(self._read_exact(ser, DESCRIPTOR_LEN, timeout_s, what, True), want, what)
        payload = self._read_exact(ser, want.length, timeout_s, what, False)
        if len(payload) < want.length:
            raise TelegramError(f"RPLIDAR {what} answer truncated: {len(payload)} of {want.length} bytes")
        return payload

    def _disconnect(self) -> None:
        ser, self._ser = self._ser, None
        if ser is None:
            return
        a2 = self.device_info is not None and self.device_info.model >> 4 == 2
        try:
            ser.write(request(CMD_STOP))
            if a2:
                ser.write(request(CMD_SET_MOTOR_PWM, struct.pack("<H", 0)))
        except Exception:
            pass
        try:
            ser.dtr = True  # motor off on the USB adapter (a port without modem lines refuses: no matter)
            import termios  # keep DTR asserted after close: HUPCL would drop it, and the motor would spin on

            attrs = termios.tcgetattr(ser.fd)
            attrs[2] &= ~termios.HUPCL
            termios.tcsetattr(ser.fd, termios.TCSANOW, attrs)
        except Exception:
            pass
        try:
            ser.close()
        except Exception:
            pass

    # ---- reading -------------------------------------------------------------------------------------------
    def _read_scan(self) -> LaserScan | None:
        if self._ready:
            return self._ready.popleft()
        if self._problem:
            msg, self._problem = self._problem, ""
            raise TelegramError(msg)
        ser = self._ser
        if ser is None:
            raise LaserError(f"{self.path}: not connected")
        chunk = ser.read(1)
        now = time.monotonic()
        if not chunk:
            if now - self._last_data > self.stall_s:
                raise LaserError(f"{self.path}: no samples for {self.stall_s:g} s while scanning (motor stopped, "
                                 "protection stop, or the cable)")
            return None
        waiting = ser.in_waiting
        if waiting:
            chunk += ser.read(waiting)
            now = time.monotonic()
        self._last_data = now
        resyncs = self._stream.resyncs
        block = self._stream.feed(chunk)
        for rev in self._revs.push(block, now):
            self._ready.append(self._to_scan(rev))
        if self._stream.resyncs != resyncs:  # one TelegramError for each loss of the alignment
            self._problem = (f"{self.path}: garbage between RPLIDAR samples: a sample broke the check bits "
                             f"({self._stream.resyncs} losses, {self._stream.skipped} bytes dropped so far); the "
                             "5-byte alignment is taken up again at the next samples that pass them")
        if self._ready:
            return self._ready.popleft()
        return None

    def _to_scan(self, rev: Revolution) -> LaserScan:
        from ..types import LaserScan

        n = len(rev)
        if self.sample_time_s is not None:
            duration = n * self.sample_time_s
        else:
            duration = (rev.t_last_s - rev.t_first_s) * n / max(n - 1, 1)
        ranges = resample(rev.angle_q6, rev.distance_q2, self.beams, self.range_min_m, self.range_max_m)
        return LaserScan(angle_min_rad=-math.pi, angle_increment_rad=2.0 * math.pi / self.beams, ranges_m=ranges,
                         range_max_m=self.range_max_m, stamp_s=rev.t_last_s - 0.5 * duration - self.latency_s)


def _open_error(path: str, e: Exception) -> LaserError:
    code = getattr(e, "errno", None)
    text = str(e)
    if code == errno.ENOENT or "No such file" in text:
        return LaserAddressError(f"{path}: no such serial port (is the RPLIDAR's USB adapter plugged in? "
                                 "`ls /dev/ttyUSB* /dev/serial/by-id/` shows the ports there are)")
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return LaserAddressError(f"{path}: permission denied: add your user to the dialout group "
                                 "(`sudo usermod -aG dialout $USER`, then log in again)")
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "lock" in text.lower():
        return LaserAddressError(f"{path}: the serial port is busy: another program has it open ({text})")
    return LaserAddressError(f"{path}: cannot open the serial port: {text}")
