"""SICK TiM5xx, LMS1xx and LMS5xx over Ethernet: a CoLa-A / CoLa-B codec for ``LMDscandata`` and the driver.

The module has two halves. The *codec* is pure (bytes in, typed records out and back): framing, the SOPAS
command layout, the ``LMDscandata`` telegram and the ``sFA`` error codes. :class:`SickScanner` is the TCP
driver built on it (a :class:`~agnav_host.lasers.base.ThreadedLaser`); the SIL's emulator
(:mod:`agnav_host.sil.emulators.sick`) uses the same codec to answer as the device does.

Sources. Facts come from these documents (the code is this module's own); each fact below names its source:

- [TL] SICK Technical Information "Telegram Listing, LiDAR sensors LMS1xx, LMS5xx, TiM2xx, TiM5xx, TiM7xx, ...",
  8014631/16U4/2020-08-21: the reference the device manuals point to for ``LMDscandata`` ("see the telegram listing
  (no. 8014631) under Send Data Permanently in Chapter 4"); ch. 2.1 binary telegram (CoLa B), 2.2 ASCII telegram
  (CoLa A), 2.3 variable types, 2.4 command basics. Its field tables are reproduced in the manuals below, which is
  where they were read here.
- [TIM] SICK Technical Information "TiM55x/56x/57x ranging laser scanner", 8015883/YZK8/2016-07-07, ch. 5.2 (``sRN
  LMDscandata`` single output, ``sEN LMDscandata`` continuous output; "the TiM5xx begins ... to measure
  automatically") and ch. 5.3 (the measured value output table).
- [LMS4] SICK Operating Instructions LMS4000 8023198 (2018-06-18 and 16S6/2020-01-24) annex 12.1, LMS4400/LMS4500
  8023202/16S6/2020-01-24 annex 12.1, LMS4000 8027168/1MNR/2024-10-25 annex 12.3.1.2: the per-field CoLa-A / CoLa-B
  value table of ``LMDscandata``, the framing sentence, the examples with hex, the reserved values.
- [LMS1] SICK Operating Instructions LMS1xx 8012471/ZN27/2017-06-09 ch. 3.8.3; [LMS5] SICK Operating Instructions
  LMS5xx 8013796/ZM63/2017-05-09 ch. 3 (log in, ``LMCstartmeas``, ``Run``) and LMS500 product family
  8013796/UL20/2010-09-27 ch. 10.2.1 (``sAN LMCstartmeas 0`` = no error), 10.2.5 (start/stop angle -50 000 ... +1
  850 000 in 1/10 000 deg), 10.2.7 (``sMN SetAccessMode 03 F4724744`` -> ``sAN SetAccessMode 1``, user level 3
  "authorised client", hash F4724744h; level 2 maintenance B21ACE26h; "measurement values will not be provided until
  the user logs out"), 10.2.12 (``sMN Run`` logs out; its answer's value is described both as "0 = accepted" and as
  "1 = no error", so the driver does not judge it).
- [TIM781] SICK Operating Instructions TiM781 8024232/1ONO/2024-09-25 12.3.1.5.1 "SOPAS error codes", and
  8024231/2019-03-29 ch. 7.3 (270 deg "(-45 deg to 225 deg)").
- [BULK] SICK Operating Instructions Bulkscan LMS511 8014829/ZNC5/2017-06-06, tab. 11 (CoLa-B frame).

Framing
  CoLa-A (defined in [TL 2.2]; read in [LMS4 12.1, 12.3.1.2]): ``STX (02h) + ASCII payload + ETX (03h)``; fields are
  separated by one space (20h). Numbers are hexadecimal without leading zeros ("Leading zeros are not displayed in
  ASCII" [LMS4]); a number written with a sign (``+20``) is decimal ([LMS4] table 84: ``sWN
  LMCminValidMeasPointOutput 1 +20`` and the value columns "+841d (349h)"). A signed field in hex is its two's
  complement (a TiM start angle of -45 deg is ``FFF92230`` [TIM 5.3, TL]). A ``Real`` is the 8 hex digits of its
  IEEE 754 single (``3F800000`` = 1.0).
  CoLa-B (defined in [TL 2.1]; read in [LMS4 12.1, 12.3.1.2], [BULK tab. 11]): ``02 02 02 02`` + payload length (4
  bytes, big-endian, without the framing) + payload + 1 byte checksum = XOR of the payload bytes. "With CoLa Binary,
  framing has a length of 9 bytes" [LMS4]. Vendor examples that this codec reproduces byte for byte: ``sEN
  LMDscandata 1`` = ``02 02 02 02 00 00 00 11 ... 20 01 33`` and ``sRN LMDscandata`` checksum ``05`` [LMS4 table 13,
  TIM781 7.3.2], ``sMN SetAccessMode 03 F4724744``: length 17h, checksum B3 [LMS4 12.3.1.2.2]. (The LMS4000 manual
  prints ``33`` as the checksum of the ``sEA`` confirmation too; its XOR is ``3C``: that example repeats the ``sEN``
  one.) A CoLa-A payload begins with a letter, so ``02 02`` at the start means CoLa-B: that is how :class:`Deframer`
  tells the two apart, telegram by telegram.

Command layout (every example in [TIM], [LMS1], [LMS5], [LMS4]): three letters (``sRN`` read, ``sWN`` write, ``sMN``
  method, ``sEN`` event; answers ``sRA``, ``sWA``, ``sAN``, ``sEA``, ``sSN`` event data, ``sFA`` error), a space,
  the name, a space, the parameters (ASCII fields, or the binary values in CoLa-B). A string parameter of variable
  length is its length then its text: CoLa-A ``sRA DeviceIdent 10 LMS10x_FieldEval 10 V1.36-21.10.2010`` (length in
  hex), CoLa-B ``sRA DeviceIdent 00 08 "MRS6124R" 00 0A "1.1.0.565C"`` (uint_16 length); both as SICK devices answer
  in the logs of SICK's sick_scan driver. The error answer is ``sFA`` + its code: ``sFA A`` / ``sFA 11`` in CoLa-A
  (hex), ``sFA`` + uint_16 without a space in CoLa-B (``sFA\\x00\\x04``), as logged in the sick_scan_xd issues #444,
  #128, #136 and #39. The codes are numbered in the order of the table in [TIM781 12.3.1.5.1] (see
  :data:`SOPAS_ERRORS`); the logged cases agree (4 LOCALCONDITIONFAILED for an out-of-range angle, 8
  BUFFER_UNDERFLOW for missing parameters, A VARIABLE_WRITE_ACCESSDENIED without log-in, 11h
  COLA_A_INVALID_CHARACTER for binary bytes sent in CoLa-A).

``LMDscandata`` (``sRA`` answer to ``sRN``, ``sSN`` event after ``sEN LMDscandata 1``), field by field (defined in
  [TL ch. 4]; read in [TIM 5.3] and [LMS4] tables 16/17): version (uint_16; "always 1 up to now" [LMS4], 0 is
  accepted too), device number (uint_16), serial number (uint_32), device status (2 x uint_8), telegram counter
  (uint_16), scan counter (uint_16), time since start-up (uint_32, us: "the time at the zero index before the
  measurement itself starts" [LMS4]), time of transmission (uint_32, us: "when the complete scan is transmitted to
  the buffer for data output"), digital inputs (2 x uint_8), digital outputs (2 x uint_8), reserved / layer angle
  (uint_16), scanning frequency (uint_32, 1/100 Hz), measurement frequency (uint_32, 100 Hz [TIM]), number of
  encoders (uint_16) then per encoder position (uint_32, ticks) and speed (uint_16, mm/s), number of 16-bit channels
  (uint_16) then per channel: content (string of 5, ``DIST1``..``DIST5``, ``RSSI1``..), scale factor (Real), scale
  offset (Real), start angle (int_32, 1/10 000 deg), angular step (uint_16, 1/10 000 deg), number of data (uint_16),
  the data (uint_16 each); number of 8-bit channels (uint_16) and the same block with uint_8 data; position (uint_16
  flag; if 1: x, y, z, x/y/z rotation as Real and the rotation type as Enum_8 [TIM]); name (uint_16 flag; if 1: the
  device name as a string of variable length); comment (likewise); time (uint_16 flag; if 1: year uint_16, month,
  day, hour, minute, second uint_8, microsecond uint_32 [TIM, LMS4]); event info (uint_16 flag; if 1: type string of
  4, encoder position uint_32, event time uint_32, angle int_32). In CoLa-B the name and comment carry a uint_16
  length (as Wireshark's CoLa dissector reads them); in CoLa-A the length is a hex field and the text follows after
  one space and may contain spaces (``1 B not defined`` in recorded TiM551 telegrams), so the parser reads it by its
  length. Distance values: 0 = no valid measurement (too dark, out of range or filtered), 1 = dazzled, 4-15
  reserved, >= 16 valid [LMS4 "LMDscandata - reserved values", stated for the LMS4000 family; the driver masks the
  value 0 and whatever lies below range_min]; distance = value x scale factor + offset, in mm for DIST (the
  LMS4000's scale factor 0.1 gives 1/10 mm units, so mm is what the scale yields).

Angles. The device's angle 0 points to its right and angles grow counter-clockwise seen from above: a TiM5xx /
LMS1xx scans 270 deg "(-45 deg to 225 deg)" [TIM781 7.3, TIM 5.3 start angle -450 000 ... +2 250 000], an LMS5xx
-5 ... 185 deg [LMS5 10.2.5], both symmetric about 90 deg = straight ahead; "the X-axis points to the right in
the SICK lidar system" and the ROS angle is the SICK angle minus 90 deg (SICK's maintainers in sick_scan_xd
issue #478). So the sensor-frame angle (0 = forward, CCW positive) is ``SICK angle - 90 deg`` with the same sense
and the same beam order.

Time stamps. ``time since start-up`` is taken as the time of the scan's first beam and ``time of transmission`` as
the moment the finished scan went out; the driver maps the transmission time to the host clock with
:class:`~agnav_host.lasers.base.DeviceClock` (a 32-bit microsecond counter: it wraps every 4294.97 s) and goes
back to the middle beam: ``stamp = host(tx) - (tx - start) + (n - 1) / 2 x beam interval``, the beam interval
being ``step / 360 deg / scan frequency``. The stamp is never later than the mapped transmission time (recorded
TiM551 telegrams show ``tx - start`` = 3.8 ms, less than a scan takes, so the zero index is not always the first
beam; the cap bounds that error by half a scan).

Driver (URL forms in :mod:`agnav_host.lasers`): ``tim5xx://HOST[:PORT]``, ``lms1xx://...``, ``lms5xx://...``, port
2112 by default; options ``cola=a|b`` (default b), ``mode=stream|poll`` (default stream: ``sEN LMDscandata 1``;
poll: one ``sRN LMDscandata`` per scan), ``range_min=M`` / ``range_max=M`` (metres; defaults per kind in
:data:`SICK_KINDS`, typical data-sheet values of the TiM561, LMS111 and LMS511, not taken from the documents above);
the mounting-pose keys ``x``, ``y``, ``yaw``, ``pitch``, ``height`` are accepted and left to ``agnav run``. On
connect it reads ``sRN DeviceIdent`` and checks the name starts with the kind's prefix (``TiM5``, ``LMS1``,
``LMS5``), reads ``sRN SerialNumber``, on an LMS logs in (``sMN SetAccessMode 03 F4724744``, the "authorised client"
[LMS5 10.2.7]), starts the measurement (``sMN LMCstartmeas`` -> ``sAN LMCstartmeas 0`` [LMS1 3.8.3, LMS5 10.2.1])
and logs out (``sMN Run`` [LMS5 10.2.12]); a TiM5xx measures from power-up [TIM 5.2]. Beams with the value 0 and
beams closer than ``range_min`` are NaN. In stream mode a connection silent for :attr:`SickScanner.stall_s` is
treated as lost and re-made (the device streams at its scan rate).
"""

from __future__ import annotations

import math
import re
import socket
import struct
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from ..types import LaserScan
from .base import (
    DeviceClock,
    LaserAddressError,
    LaserInfo,
    LaserMount,
    TelegramError,
    ThreadedLaser,
    WrongDeviceError,
)

if TYPE_CHECKING:
    from . import LaserUrl

__all__ = [
    "COLA_A", "COLA_B", "SOPAS_ERRORS", "SICK_KINDS", "SopasError", "Deframer", "Command", "ScanChannel",
    "ScanTelegram", "xor_checksum", "frame", "unframe", "frame_kind", "split_command", "encode_command",
    "read_fields", "parse_scandata", "encode_scandata", "sopas_error_payload", "describe_foreign_bytes",
    "SickScanner", "DEVICE_CLOCK_WRAP_S", "CLIENT_LEVEL", "CLIENT_PASSWORD_HASH",
]

COLA_A = "a"
COLA_B = "b"
_STX = 0x02
_ETX = 0x03
_B_MAGIC = b"\x02\x02\x02\x02"
MAX_TELEGRAM_BYTES = 1 << 20  # no LMDscandata comes near (5 channels x 1141 x 2 bytes is ~11 kB)
DEVICE_CLOCK_WRAP_S = 2**32 * 1e-6  # time since start-up: uint_32 microseconds
CLIENT_LEVEL = 3  # "Authorised client" [LMS5 10.2.7]
CLIENT_PASSWORD_HASH = 0xF4724744

#: ``sFA`` error codes, numbered in the order of the table "SOPAS error codes" [TIM781 12.3.1.5.1]:
#: code -> (name, meaning in short).
SOPAS_ERRORS: dict[int, tuple[str, str]] = dict(enumerate([
    ("Sopas_Ok", "no error"),
    ("Sopas_Error_METHODIN_ACCESSDENIED", "wrong user level: the method needs a log-in"),
    ("Sopas_Error_METHODIN_UNKNOWNINDEX", "no method with that index"),
    ("Sopas_Error_VARIABLE_UNKNOWNINDEX", "no variable with that index"),
    ("Sopas_Error_LOCALCONDITIONFAILED", "a value outside what the variable allows"),
    ("Sopas_Error_INVALID_DATA", "invalid data (no longer used)"),
    ("Sopas_Error_UNKNOWN_ERROR", "an error of unknown cause (no longer used)"),
    ("Sopas_Error_BUFFER_OVERFLOW", "the answer does not fit the communication buffer"),
    ("Sopas_Error_BUFFER_UNDERFLOW", "more data expected: parameters are missing"),
    ("Sopas_Error_ERROR_UNKNOWN_TYPE", "a variable of a type the device description does not know"),
    ("Sopas_Error_VARIABLE_WRITE_ACCESSDENIED", "the variable may not be written (read-only, or log in first)"),
    ("Sopas_Error_UNKNOWN_CMD_FOR_NAMESERVER", "the name server does not know that name"),
    ("Sopas_Error_UNKNOWN_COLA_COMMAND", "not a CoLa command"),
    ("Sopas_Error_METHODIN_SERVER_BUSY", "the device is busy with another method call"),
    ("Sopas_Error_FLEX_OUT_OF_BOUNDS", "a variable-length value longer than allowed"),
    ("Sopas_Error_EVENTREG_UNKNOWNINDEX", "no event with that index"),
    ("Sopas_Error_COLA_A_VALUE_OVERFLOW", "a CoLa-A number too large for its type"),
    ("Sopas_Error_COLA_A_INVALID_CHARACTER", "a character that CoLa-A does not allow"),
    ("Sopas_Error_OSAI_NO_MESSAGE", "no message (internal)"),
    ("Sopas_Error_OSAI_NO_ANSWER_MESSAGE", "no answer message (internal)"),
    ("Sopas_Error_INTERNAL", "internal error"),
    ("Sopas_Error_HubAddressCorrupted", "corrupted hub address"),
    ("Sopas_Error_HubAddressDecoding", "hub address not decodable"),
    ("Sopas_Error_HubAddressAddressExceeded", "hub address too long"),
    ("Sopas_Error_HubAddressBlankExpected", "a blank was expected in the hub address"),
    ("Sopas_Error_AsyncMethodsAreSuppressed", "asynchronous methods are suppressed"),
    ("Sopas_Error_ComplexArraysNotSupported", "complex arrays are not supported"),
]))


class SopasError(TelegramError):
    """The device answered ``sFA``: it refused or did not understand the request (``code``, ``name``)."""

    def __init__(self, code: int, context: str = "") -> None:
        self.code = code
        self.name, meaning = SOPAS_ERRORS.get(code, (f"unknown error code {code}", "not in the telegram listing"))
        where = f"{context}: " if context else ""
        super().__init__(f"{where}the scanner answered sFA {code:X}h = {self.name} ({meaning})")


# ---------------------------------------------------------------------------------------------------------------
# framing
# ---------------------------------------------------------------------------------------------------------------


def xor_checksum(payload: bytes) -> int:
    """The CoLa-B checksum: XOR of every payload byte [BULK tab. 11]."""
    x = 0
    for c in payload:
        x ^= c
    return x


def frame(payload: bytes, cola: str) -> bytes:
    """Frame one payload: ``STX payload ETX`` (CoLa-A) or ``02020202 + length + payload + XOR`` (CoLa-B)."""
    if not payload:
        raise ValueError("a CoLa telegram needs a payload")
    if cola == COLA_A:
        if b"\x02" in payload or b"\x03" in payload:
            raise ValueError("a CoLa-A payload cannot contain STX (02h) or ETX (03h)")
        return b"\x02" + payload + b"\x03"
    if cola == COLA_B:
        return _B_MAGIC + struct.pack(">I", len(payload)) + payload + bytes([xor_checksum(payload)])
    raise ValueError(f"cola must be {COLA_A!r} or {COLA_B!r}, got {cola!r}")


def frame_kind(data: bytes) -> str | None:
    """``"a"`` / ``"b"`` from a telegram's first bytes, ``""`` when too few bytes arrived to tell, None when the
    bytes cannot start a CoLa telegram at all."""
    if not data:
        return ""
    if data[0] != _STX:
        return None
    if len(data) < 2:
        return ""
    if data[1] != _STX:
        return COLA_A
    if len(data) < 4:
        return ""
    return COLA_B if data[:4] == _B_MAGIC else None


def _show(data: bytes, limit: int = 32) -> str:
    """Bytes for an error message: text where printable, hex otherwise."""
    head = data[:limit]
    more = f" ... ({len(data)} bytes)" if len(data) > limit else ""
    if all(32 <= c < 127 for c in head):
        return repr(head.decode("ascii")) + more
    return head.hex(" ").upper() + more


class Deframer:
    """Splits a byte stream into CoLa telegrams of either encoding (told apart by their first bytes).

    :meth:`feed` what arrives, then call :meth:`next` until it returns None. A bad frame (bytes outside any
    telegram, a wrong checksum, an impossible length, a CoLa-A telegram cut off by a new STX) raises
    TelegramError after dropping the offending bytes, so the next call goes on with what follows.
    """

    def __init__(self, max_bytes: int = MAX_TELEGRAM_BYTES) -> None:
        self.max_bytes = max_bytes
        self._buf = bytearray()

    def feed(self, data: bytes) -> None:
        self._buf += data

    @property
    def pending(self) -> bytes:
        """Bytes received but not yet returned as a telegram."""
        return bytes(self._buf)

    def clear(self) -> None:
        self._buf.clear()

    def next(self) -> tuple[str, bytes] | None:
        """The next whole telegram as ``(cola, payload)``, None when more bytes are needed."""
        buf = self._buf
        if not buf:
            return None
        if buf[0] != _STX:
            i = buf.find(b"\x02")
            junk = bytes(buf[: i if i >= 0 else len(buf)])
            del buf[: len(junk)]
            raise TelegramError(f"{len(junk)} bytes outside any CoLa telegram (a telegram starts with STX 02h): "
                                f"{_show(junk)}")
        kind = frame_kind(bytes(buf[:4]))
        if kind == "":
            return None
        if kind is None:
            del buf[:2]
            raise TelegramError(f"a telegram starting 02 02 must be CoLa-B (02 02 02 02), got {_show(bytes(buf[:6]))}")
        if kind == COLA_B:
            if len(buf) < 8:
                return None
            n = int.from_bytes(buf[4:8], "big")
            if n == 0 or n > self.max_bytes:
                del buf[:4]
                raise TelegramError(f"CoLa-B telegram with length {n}: not a length a scanner sends "
                                    f"(1 ... {self.max_bytes} bytes)")
            if len(buf) < 9 + n:
                return None
            payload = bytes(buf[8 : 8 + n])
            sent = buf[8 + n]
            del buf[: 9 + n]
            calc = xor_checksum(payload)
            if sent != calc:
                raise TelegramError(f"CoLa-B checksum mismatch: the telegram says {sent:02X}h, the XOR of its "
                                    f"{n} payload bytes is {calc:02X}h ({_show(payload)})")
            return COLA_B, payload
        end = buf.find(b"\x03", 1)
        restart = buf.find(b"\x02", 1, end if end >= 0 else len(buf))
        if restart > 0:
            junk = bytes(buf[:restart])
            del buf[:restart]
            raise TelegramError(f"CoLa-A telegram cut off (a new STX came before its ETX): {_show(junk)}")
        if end < 0:
            if len(buf) > self.max_bytes:
                n = len(buf)
                buf.clear()
                raise TelegramError(f"CoLa-A telegram without ETX after {n} bytes")
            return None
        payload = bytes(buf[1:end])
        del buf[: end + 1]
        if not payload:
            raise TelegramError("empty CoLa-A telegram (STX ETX)")
        return COLA_A, payload


def unframe(data: bytes) -> tuple[str, bytes]:
    """Exactly one framed telegram -> ``(cola, payload)``; TelegramError when it is incomplete, bad or followed
    by more bytes."""
    d = Deframer(max_bytes=max(MAX_TELEGRAM_BYTES, len(data)))
    d.feed(data)
    t = d.next()
    if t is None:
        kind = frame_kind(data[:4])
        what = {COLA_A: "CoLa-A (no ETX)", COLA_B: "CoLa-B (fewer bytes than its length field says)"}.get(kind or "",
                                                                                                   "telegram")
        raise TelegramError(f"truncated {what}: {_show(data)}")
    if d.pending:
        raise TelegramError(f"{len(d.pending)} bytes after the telegram: {_show(d.pending)}")
    return t


# ---------------------------------------------------------------------------------------------------------------
# commands and fields
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Command:
    """One SOPAS telegram split into its command type (``sRA``, ``sSN``, ``sFA``, ...), name and parameters."""

    cola: str
    kind: str
    name: str
    body: bytes  # the parameters: ASCII fields (CoLa-A) or binary values (CoLa-B); for sFA the code

    @property
    def is_error(self) -> bool:
        return self.kind == "sFA"

    def error_code(self) -> int:
        """The code of an ``sFA`` answer (TelegramError if it has none)."""
        if not self.is_error:
            raise TelegramError(f"{self.kind} {self.name} is not an sFA answer")
        if self.cola == COLA_B and len(self.body) == 2:
            return int.from_bytes(self.body, "big")
        text = self.body.strip()
        if self.cola == COLA_A and re.fullmatch(rb"[0-9A-Fa-f]{1,4}", text):
            return int(text, 16)
        raise TelegramError(f"sFA answer without a readable error code: {_show(self.body)}")

    def raise_if_error(self, context: str = "") -> "Command":
        if self.is_error:
            raise SopasError(self.error_code(), context)
        return self

    def expect(self, kind: str, name: str, context: str = "") -> "Command":
        """This answer if it is ``kind name``; SopasError for sFA, TelegramError for any other answer."""
        self.raise_if_error(context)
        if (self.kind, self.name) != (kind, name):
            where = f"{context}: " if context else ""
            raise TelegramError(f"{where}expected {kind} {name}, the scanner answered {self.kind} {self.name}")
        return self


def split_command(cola: str, payload: bytes) -> Command:
    """Split a payload into command type, name and parameters (TelegramError if it is no SOPAS command)."""
    head = payload[:3]
    if len(head) < 3 or not (head[:1] == b"s" and head[1:].isalpha() and head.isascii()):
        raise TelegramError(f"not a SOPAS command (they start with s + two letters, e.g. sRA): {_show(payload)}")
    kind = head.decode("ascii")
    if kind == "sFA":
        body = payload[3:]
        if cola == COLA_A or (len(body) == 3 and body[:1] == b" "):
            body = body[1:] if body[:1] == b" " else body
        return Command(cola, kind, "", body)
    if len(payload) == 3:
        return Command(cola, kind, "", b"")
    if payload[3] != 0x20:
        raise TelegramError(f"{kind} must be followed by a space, got {_show(payload[:16])}")
    rest = payload[4:]
    sp = rest.find(b" ")
    name_b, body = (rest, b"") if sp < 0 else (rest[:sp], rest[sp + 1 :])
    if not name_b or not all(33 <= c < 127 for c in name_b):
        raise TelegramError(f"{kind}: no readable command name in {_show(payload[:32])}")
    return Command(cola, kind, name_b.decode("ascii"), body)


class _Reader(Protocol):
    def uint(self, what: str, bits: int) -> int: ...
    def sint(self, what: str, bits: int) -> int: ...
    def real(self, what: str) -> float: ...
    def fixed(self, what: str, n: int) -> str: ...
    def flex(self, what: str) -> str: ...
    def array(self, what: str, n: int, bits: int) -> npt.NDArray[np.integer]: ...
    def done(self) -> None: ...


_HEX = re.compile(rb"[0-9A-Fa-f]{1,16}")
_DEC = re.compile(rb"[+-][0-9]{1,20}")
_HEX_RUN = re.compile(rb"(?:[0-9A-Fa-f]{1,8} )*[0-9A-Fa-f]{1,8}")


class _AsciiReader:
    """CoLa-A parameters: space-separated hex numbers (or signed decimals), strings as ``LEN TEXT``."""

    def __init__(self, body: bytes, what: str) -> None:
        self.b, self.i, self.what = body, 0, what

    def _skip(self) -> int:
        b, i = self.b, self.i
        while i < len(b) and b[i] == 0x20:
            i += 1
        return i

    def _token(self, field: str) -> bytes:
        i = self._skip()
        if i >= len(self.b):
            raise TelegramError(f"{self.what} ends before '{field}': the telegram is truncated or a field is missing")
        j = self.b.find(b" ", i)
        j = len(self.b) if j < 0 else j
        self.i = j
        return self.b[i:j]

    def _number(self, field: str, bits: int, signed: bool) -> int:
        t = self._token(field)
        if _HEX.fullmatch(t):
            v = int(t, 16)
            if v >= 1 << bits:
                raise TelegramError(f"{self.what}: '{field}' = {t.decode()}h does not fit {bits} bits")
            if signed and v >= 1 << (bits - 1):
                v -= 1 << bits
            return v
        if _DEC.fullmatch(t):
            v = int(t)
            lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
            if not lo <= v <= hi:
                raise TelegramError(f"{self.what}: '{field}' = {t.decode()} is outside {lo} ... {hi}")
            return v
        raise TelegramError(f"{self.what}: '{field}' is {_show(t)}, not a CoLa-A number (hex, or decimal with a sign)")

    def uint(self, what: str, bits: int) -> int:
        return self._number(what, bits, False)

    def sint(self, what: str, bits: int) -> int:
        return self._number(what, bits, True)

    def real(self, what: str) -> float:
        t = self._token(what)
        if not _HEX.fullmatch(t) or len(t) > 8:
            raise TelegramError(f"{self.what}: '{what}' is {_show(t)}, not the 8 hex digits of an IEEE 754 float")
        return float(struct.unpack(">f", int(t, 16).to_bytes(4, "big"))[0])

    def fixed(self, what: str, n: int) -> str:
        t = self._token(what)
        if len(t) != n:
            raise TelegramError(f"{self.what}: '{what}' must have {n} characters, got {_show(t)}")
        return t.decode("latin-1")

    def flex(self, what: str) -> str:
        n = self.uint(f"{what} (length)", 16)
        if n == 0:
            return ""
        start = self.i + 1
        if self.i >= len(self.b) or start + n > len(self.b):
            raise TelegramError(f"{self.what}: '{what}' announces {n} characters, the telegram ends first")
        text = self.b[start : start + n]
        self.i = start + n
        if self.i < len(self.b) and self.b[self.i] != 0x20:
            raise TelegramError(f"{self.what}: '{what}' announces {n} characters, but the text goes on "
                                f"({_show(self.b[start:start + n + 8])})")
        return text.decode("latin-1")

    def array(self, what: str, n: int, bits: int) -> npt.NDArray[np.integer]:
        dtype = np.uint16 if bits == 16 else np.uint8
        if n == 0:
            return np.zeros(0, dtype=dtype)
        i = self._skip()
        parts = self.b[i:].split(b" ", n)
        if len(parts) < n or (len(parts) == n and not parts[-1]):
            got = len([p for p in parts if p])
            raise TelegramError(f"{self.what}: '{what}' announces {n} values, the telegram ends after {got}")
        tokens = parts[:n]
        run = b" ".join(tokens)
        if not _HEX_RUN.fullmatch(run):
            bad = next((t for t in tokens if not _HEX.fullmatch(t) or len(t) > 8), b"")
            raise TelegramError(f"{self.what}: '{what}' holds {_show(bad) if bad else 'an empty field'}, "
                                "not a hex value")
        values = np.array([int(t, 16) for t in tokens], dtype=np.int64)
        if values.max() >= 1 << bits:
            raise TelegramError(f"{self.what}: '{what}' has a value {int(values.max()):X}h over {bits} bits")
        self.i = i + len(run)
        return values.astype(dtype)

    def done(self) -> None:
        i = self._skip()
        if i < len(self.b):
            rest = self.b[i:]
            raise TelegramError(f"{self.what}: {len(rest)} bytes after the last field ({_show(rest)}): "
                                "a field count is wrong")


class _BinaryReader:
    """CoLa-B parameters: big-endian binary values, strings as uint_16 length + text."""

    def __init__(self, body: bytes, what: str) -> None:
        self.b, self.i, self.what = body, 0, what

    def _take(self, what: str, n: int) -> bytes:
        if self.i + n > len(self.b):
            raise TelegramError(f"{self.what} ends in '{what}' (needs {n} bytes at offset {self.i}, "
                                f"{len(self.b) - self.i} left): the telegram is truncated or a count is wrong")
        out = self.b[self.i : self.i + n]
        self.i += n
        return out

    def uint(self, what: str, bits: int) -> int:
        return int.from_bytes(self._take(what, bits // 8), "big")

    def sint(self, what: str, bits: int) -> int:
        return int.from_bytes(self._take(what, bits // 8), "big", signed=True)

    def real(self, what: str) -> float:
        return float(struct.unpack(">f", self._take(what, 4))[0])

    def fixed(self, what: str, n: int) -> str:
        return self._take(what, n).decode("latin-1")

    def flex(self, what: str) -> str:
        n = self.uint(f"{what} (length)", 16)
        return self._take(what, n).decode("latin-1")

    def array(self, what: str, n: int, bits: int) -> npt.NDArray[np.integer]:
        raw = self._take(what, n * bits // 8)
        if bits == 16:
            return np.frombuffer(raw, dtype=">u2").astype(np.uint16)
        return np.frombuffer(raw, dtype=np.uint8).copy()

    def done(self) -> None:
        if self.i < len(self.b):
            rest = self.b[self.i :]
            raise TelegramError(f"{self.what}: {len(rest)} bytes after the last field ({_show(rest)}): "
                                "a field count is wrong")


def read_fields(cmd: Command) -> _Reader:
    """A reader over a command's parameters in its encoding (methods ``uint(what, bits)``, ``sint``, ``real``,
    ``fixed(what, n)``, ``flex``, ``array(what, n, bits)``, ``done``)."""
    what = f"{cmd.kind} {cmd.name}".strip()
    return _AsciiReader(cmd.body, what) if cmd.cola == COLA_A else _BinaryReader(cmd.body, what)


class _Writer(Protocol):
    def uint(self, v: int, bits: int) -> None: ...
    def sint(self, v: int, bits: int) -> None: ...
    def real(self, v: float) -> None: ...
    def fixed(self, s: str, n: int) -> None: ...
    def flex(self, s: str) -> None: ...
    def array(self, values: npt.NDArray[np.integer], bits: int) -> None: ...
    def body(self) -> bytes: ...


def _check_uint(v: int, bits: int) -> int:
    v = int(v)
    if not 0 <= v < 1 << bits:
        raise ValueError(f"{v} does not fit an unsigned {bits}-bit field")
    return v


def _check_sint(v: int, bits: int) -> int:
    v = int(v)
    if not -(1 << (bits - 1)) <= v < 1 << (bits - 1):
        raise ValueError(f"{v} does not fit a signed {bits}-bit field")
    return v


class _AsciiWriter:
    def __init__(self) -> None:
        self.parts: list[bytes] = []

    def uint(self, v: int, bits: int) -> None:
        self.parts.append(b"%X" % _check_uint(v, bits))

    def sint(self, v: int, bits: int) -> None:
        self.parts.append(b"%X" % (_check_sint(v, bits) & ((1 << bits) - 1)))

    def real(self, v: float) -> None:
        self.parts.append(b"%08X" % struct.unpack(">I", struct.pack(">f", v))[0])

    def fixed(self, s: str, n: int) -> None:
        b = s.encode("latin-1")
        if len(b) != n or b" " in b:
            raise ValueError(f"{s!r} must be {n} characters without spaces")
        self.parts.append(b)

    def flex(self, s: str) -> None:
        b = s.encode("latin-1")
        self.parts.append(b"%X %s" % (len(b), b) if b else b"0")

    def array(self, values: npt.NDArray[np.integer], bits: int) -> None:
        v = np.asarray(values, dtype=np.int64)
        if v.size and (v.min() < 0 or v.max() >= 1 << bits):
            raise ValueError(f"array values must fit {bits} bits")
        self.parts.extend(b"%X" % x for x in v.tolist())

    def body(self) -> bytes:
        return b" ".join(self.parts)


class _BinaryWriter:
    def __init__(self) -> None:
        self.out = bytearray()

    def uint(self, v: int, bits: int) -> None:
        self.out += _check_uint(v, bits).to_bytes(bits // 8, "big")

    def sint(self, v: int, bits: int) -> None:
        self.out += _check_sint(v, bits).to_bytes(bits // 8, "big", signed=True)

    def real(self, v: float) -> None:
        self.out += struct.pack(">f", v)

    def fixed(self, s: str, n: int) -> None:
        b = s.encode("latin-1")
        if len(b) != n:
            raise ValueError(f"{s!r} must be {n} characters")
        self.out += b

    def flex(self, s: str) -> None:
        b = s.encode("latin-1")
        self.out += _check_uint(len(b), 16).to_bytes(2, "big") + b

    def array(self, values: npt.NDArray[np.integer], bits: int) -> None:
        v = np.asarray(values, dtype=np.int64)
        if v.size and (v.min() < 0 or v.max() >= 1 << bits):
            raise ValueError(f"array values must fit {bits} bits")
        self.out += v.astype(">u2" if bits == 16 else np.uint8).tobytes()

    def body(self) -> bytes:
        return bytes(self.out)


def _writer(cola: str) -> _Writer:
    if cola == COLA_A:
        return _AsciiWriter()
    if cola == COLA_B:
        return _BinaryWriter()
    raise ValueError(f"cola must be {COLA_A!r} or {COLA_B!r}, got {cola!r}")


#: a parameter for :func:`encode_command`: (type, value) with type "u8", "u16", "u32", "i16", "i32", "str"
Param = tuple[str, "int | str"]


def encode_command(cola: str, kind: str, name: str, *params: Param) -> bytes:
    """The payload of ``kind name params...`` (e.g. ``("sMN", "SetAccessMode", ("u8", 3), ("u32", 0xF4724744))``)."""
    w = _writer(cola)
    for typ, value in params:
        if typ == "str":
            w.flex(str(value))
        elif typ in ("u8", "u16", "u32"):
            w.uint(int(value), int(typ[1:]))
        elif typ in ("i16", "i32"):
            w.sint(int(value), int(typ[1:]))
        else:
            raise ValueError(f"unknown parameter type {typ!r}")
    body = w.body()
    return f"{kind} {name}".encode("ascii") + (b" " + body if body else b"")


def sopas_error_payload(cola: str, code: int) -> bytes:
    """The payload of an ``sFA`` answer with ``code`` (CoLa-A ``sFA B``, CoLa-B ``sFA`` + uint_16)."""
    if cola == COLA_A:
        return b"sFA %X" % code
    return b"sFA" + _check_uint(code, 16).to_bytes(2, "big")


# ---------------------------------------------------------------------------------------------------------------
# LMDscandata
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ScanChannel:
    """One output channel of ``LMDscandata`` (16-bit or 8-bit), angles in the device's convention."""

    content: str  # "DIST1" (first echo distances), "RSSI1" (signal strength), ...
    scale_factor: float
    scale_offset: float
    start_angle: int  # 1/10 000 deg, SICK angle (90 deg = straight ahead)
    angular_step: int  # 1/10 000 deg
    data: npt.NDArray[np.integer]  # the raw values (uint16 or uint8)

    @property
    def start_angle_deg(self) -> float:
        return self.start_angle / 10000.0

    @property
    def angular_step_deg(self) -> float:
        return self.angular_step / 10000.0

    def scaled(self) -> npt.NDArray[np.float64]:
        """``value x scale factor + offset`` (mm for DIST channels)."""
        return self.data.astype(np.float64) * float(self.scale_factor) + float(self.scale_offset)


@dataclass(frozen=True, eq=False)
class ScanTelegram:
    """An ``LMDscandata`` telegram, field by field (see the module docstring for sources and units)."""

    version: int = 1
    device_number: int = 1
    serial_number: int = 0
    device_status: tuple[int, int] = (0, 0)
    telegram_counter: int = 0
    scan_counter: int = 0
    time_since_startup_us: int = 0
    time_of_transmission_us: int = 0
    inputs: tuple[int, int] = (0, 0)
    outputs: tuple[int, int] = (0, 0)
    layer_angle: int = 0  # "reserved" on the 2-D scanners
    scan_frequency: int = 0  # 1/100 Hz
    measurement_frequency: int = 0  # 100 Hz
    encoders: tuple[tuple[int, int], ...] = ()  # (position in ticks, speed in mm/s)
    channels16: tuple[ScanChannel, ...] = ()
    channels8: tuple[ScanChannel, ...] = ()
    position: tuple[float, float, float, float, float, float, int] | None = None  # x, y, z, rx, ry, rz, type
    device_name: str | None = None
    comment: str | None = None
    timestamp: tuple[int, int, int, int, int, int, int] | None = None  # year, month, day, h, min, s, us
    event: tuple[str, int, int, int] | None = None  # type, encoder position, time (us), angle
    kind: str = field(default="sSN")  # "sRA" (polled) or "sSN" (event stream)

    @property
    def scan_frequency_hz(self) -> float:
        return self.scan_frequency / 100.0

    @property
    def measurement_frequency_hz(self) -> float:
        return self.measurement_frequency * 100.0

    def channel(self, content: str) -> ScanChannel | None:
        """The first 16-bit, then 8-bit channel with this content."""
        for ch in self.channels16 + self.channels8:
            if ch.content == content:
                return ch
        return None

    @property
    def dist1(self) -> ScanChannel:
        """The first-echo distance channel (TelegramError if the device is set to send none)."""
        ch = self.channel("DIST1")
        if ch is None:
            have = ", ".join(c.content for c in self.channels16 + self.channels8) or "none"
            raise TelegramError(f"LMDscandata without a DIST1 channel (channels: {have}): set the scanner to "
                                "output distances (SOPAS ET: data output, first echo)")
        return ch

    def distances_m(self) -> npt.NDArray[np.float64]:
        """DIST1 in metres; NaN where the device sent 0 (no valid measurement)."""
        ch = self.dist1
        r = ch.scaled() / 1000.0
        r[ch.data == 0] = np.nan
        return r

    def rssi(self) -> npt.NDArray[np.integer] | None:
        """The RSSI1 values when the telegram carries them."""
        ch = self.channel("RSSI1")
        return None if ch is None else ch.data


def _read_channel(r: _Reader, bits: int, k: int) -> ScanChannel:
    tag = f"{bits}-bit channel {k + 1}"
    content = r.fixed(f"{tag} content", 5)
    scale = r.real(f"{tag} scale factor")
    offset = r.real(f"{tag} scale offset")
    start = r.sint(f"{tag} start angle", 32)
    step = r.uint(f"{tag} angular step", 16)
    n = r.uint(f"{tag} number of data", 16)
    data = r.array(f"{tag} data", n, bits)
    return ScanChannel(content, scale, offset, start, step, data)


def _flag(r: _Reader, what: str) -> bool:
    v = r.uint(what, 16)
    if v > 1:
        raise TelegramError(f"LMDscandata: '{what}' must be 0 or 1, got {v}")
    return v == 1


def parse_scandata(cmd: Command | bytes, cola: str | None = None) -> ScanTelegram:
    """Parse an ``sRA`` / ``sSN LMDscandata`` telegram (a :class:`Command`, or a payload and its encoding).

    TelegramError names the field that is missing, malformed or left over; SopasError for an ``sFA`` answer.
    """
    if not isinstance(cmd, Command):
        if cola is None:
            raise ValueError("a raw payload needs its encoding (cola='a' or 'b')")
        cmd = split_command(cola, cmd)
    cmd.raise_if_error("LMDscandata")
    if cmd.kind not in ("sRA", "sSN") or cmd.name != "LMDscandata":
        raise TelegramError(f"expected sRA or sSN LMDscandata, got {cmd.kind} {cmd.name}".rstrip())
    r = read_fields(cmd)
    version = r.uint("version", 16)
    if version > 1:
        raise TelegramError(f"LMDscandata version {version}: this parser reads versions 0 and 1")
    device_number = r.uint("device number", 16)
    serial = r.uint("serial number", 32)
    status = (r.uint("device status 1", 8), r.uint("device status 2", 8))
    telegram_counter = r.uint("telegram counter", 16)
    scan_counter = r.uint("scan counter", 16)
    t_start = r.uint("time since start-up", 32)
    t_tx = r.uint("time of transmission", 32)
    inputs = (r.uint("inputs 1", 8), r.uint("inputs 2", 8))
    outputs = (r.uint("outputs 1", 8), r.uint("outputs 2", 8))
    layer = r.sint("reserved (layer angle)", 16)
    scan_freq = r.uint("scanning frequency", 32)
    meas_freq = r.uint("measurement frequency", 32)
    n_enc = r.uint("number of encoders", 16)
    encoders = tuple((r.uint(f"encoder {k + 1} position", 32), r.uint(f"encoder {k + 1} speed", 16))
                     for k in range(n_enc))
    ch16 = tuple(_read_channel(r, 16, k) for k in range(r.uint("number of 16-bit channels", 16)))
    ch8 = tuple(_read_channel(r, 8, k) for k in range(r.uint("number of 8-bit channels", 16)))
    position = None
    if _flag(r, "position"):
        xyz = tuple(r.real(w) for w in ("x position", "y position", "z position", "x rotation", "y rotation",
                                        "z rotation"))
        position = (*xyz, r.uint("rotation type", 8))
    name = r.flex("device name") if _flag(r, "name") else None
    comment = r.flex("comment") if _flag(r, "comment") else None
    stamp = None
    if _flag(r, "time"):
        stamp = (r.uint("year", 16), r.uint("month", 8), r.uint("day", 8), r.uint("hour", 8), r.uint("minute", 8),
                 r.uint("second", 8), r.uint("microsecond", 32))
    event = None
    if _flag(r, "event info"):
        event = (r.fixed("event type", 4), r.uint("event encoder position", 32), r.uint("event time", 32),
                 r.sint("event angle", 32))
    r.done()
    return ScanTelegram(
        version=version, device_number=device_number, serial_number=serial, device_status=status,
        telegram_counter=telegram_counter, scan_counter=scan_counter, time_since_startup_us=t_start,
        time_of_transmission_us=t_tx, inputs=inputs, outputs=outputs, layer_angle=layer, scan_frequency=scan_freq,
        measurement_frequency=meas_freq, encoders=encoders, channels16=ch16, channels8=ch8,
        position=position,  # type: ignore[arg-type]
        device_name=name, comment=comment, timestamp=stamp, event=event, kind=cmd.kind)


def _write_channel(w: _Writer, ch: ScanChannel, bits: int) -> None:
    w.fixed(ch.content, 5)
    w.real(ch.scale_factor)
    w.real(ch.scale_offset)
    w.sint(ch.start_angle, 32)
    w.uint(ch.angular_step, 16)
    w.uint(len(ch.data), 16)
    w.array(ch.data, bits)


def encode_scandata(tel: ScanTelegram, cola: str, kind: str | None = None) -> bytes:
    """The payload of ``kind LMDscandata ...`` (kind defaults to ``tel.kind``: "sSN" event or "sRA" answer)."""
    w = _writer(cola)
    w.uint(tel.version, 16)
    w.uint(tel.device_number, 16)
    w.uint(tel.serial_number, 32)
    for v in tel.device_status:
        w.uint(v, 8)
    w.uint(tel.telegram_counter, 16)
    w.uint(tel.scan_counter, 16)
    w.uint(tel.time_since_startup_us, 32)
    w.uint(tel.time_of_transmission_us, 32)
    for v in (*tel.inputs, *tel.outputs):
        w.uint(v, 8)
    w.sint(tel.layer_angle, 16)
    w.uint(tel.scan_frequency, 32)
    w.uint(tel.measurement_frequency, 32)
    w.uint(len(tel.encoders), 16)
    for pos, speed in tel.encoders:
        w.uint(pos, 32)
        w.uint(speed, 16)
    w.uint(len(tel.channels16), 16)
    for ch in tel.channels16:
        _write_channel(w, ch, 16)
    w.uint(len(tel.channels8), 16)
    for ch in tel.channels8:
        _write_channel(w, ch, 8)
    w.uint(0 if tel.position is None else 1, 16)
    if tel.position is not None:
        for coord in tel.position[:6]:
            w.real(float(coord))
        w.uint(int(tel.position[6]), 8)
    for text in (tel.device_name, tel.comment):
        w.uint(0 if text is None else 1, 16)
        if text is not None:
            w.flex(text)
    w.uint(0 if tel.timestamp is None else 1, 16)
    if tel.timestamp is not None:
        y, mo, d, h, mi, s, us = tel.timestamp
        w.uint(y, 16)
        for v in (mo, d, h, mi, s):
            w.uint(v, 8)
        w.uint(us, 32)
    w.uint(0 if tel.event is None else 1, 16)
    if tel.event is not None:
        etype, epos, etime, eangle = tel.event
        w.fixed(etype, 4)
        w.uint(epos, 32)
        w.uint(etime, 32)
        w.sint(eangle, 32)
    return f"{kind or tel.kind} LMDscandata ".encode("ascii") + w.body()


def describe_foreign_bytes(raw: bytes) -> str:
    """What a non-CoLa answer looks like, for WrongDeviceError messages."""
    if not raw:
        return "it sent nothing"
    head = raw[:64]
    printable = sum(32 <= c < 127 or c in (9, 10, 13) for c in head)
    if b"\n" in raw and printable >= 0.8 * len(head):
        lines = [ln for ln in raw.replace(b"\x02", b"").replace(b"\x03", b"").split(b"\n")]
        scipish = (len(lines) >= 2 and re.fullmatch(rb"[0-9A-F]{2}.?", lines[1].strip()) is not None) or \
            raw.lstrip(b"\x02").startswith((b"VV", b"PP", b"II", b"MD", b"GD", b"BM", b"QT", b"SCIP"))
        if scipish:
            return (f"it answers in LF-terminated text lines ({_show(raw, 40)}), like a Hokuyo scanner speaking "
                    "SCIP 2.0 (open it as ust://HOST or urg:DEVICE)")
        return f"it answers in text lines ({_show(raw, 40)}), which are no CoLa telegrams"
    if raw[:2] == b"\xa5\x5a":
        return f"it answers with binary A5 5A ... ({_show(raw, 16)}), like a Slamtec RPLIDAR (rplidar:DEVICE)"
    if printable >= 0.8 * len(head):
        return f"it answers with text {_show(raw, 40)}, which is no CoLa telegram"
    return f"it answers with binary bytes {_show(raw, 16)}, which are no CoLa telegram"


# ---------------------------------------------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SickKind:
    """What the driver knows of one URL kind."""

    ident_prefix: str  # the start of the device's sRA DeviceIdent name
    range_min_m: float
    range_max_m: float
    needs_start: bool  # log in + LMCstartmeas + Run on connect (a TiM measures from power-up)


#: URL kind -> device facts (ranges: typical data-sheet values of a TiM561, LMS111, LMS511; override them with
#: ``range_min=`` / ``range_max=``).
SICK_KINDS: dict[str, SickKind] = {
    "tim5xx": SickKind("TiM5", 0.05, 10.0, False),
    "lms1xx": SickKind("LMS1", 0.5, 20.0, True),
    "lms5xx": SickKind("LMS5", 1.0, 80.0, True),
}

_OPTIONS = "cola=a|b, mode=stream|poll, range_min=M, range_max=M"
_MOUNT_KEYS = ("x", "y", "yaw", "pitch", "height")  # the mounting pose, read by ``agnav run`` from the same URL


class SickScanner(ThreadedLaser):
    """A SICK TiM5xx / LMS1xx / LMS5xx over TCP (see the module docstring for the protocol and the options)."""

    kind = "sick"
    stall_s = 3.0  # stream mode: no telegram for this long means the connection is gone
    read_timeout_s = 0.1  # one wait of the reader thread (bounds how long close() waits for it)

    def __init__(self, url: LaserUrl, mount: LaserMount) -> None:
        super().__init__(url.text, mount)
        from . import LaserUrlError  # the package imports this module lazily, so this is no cycle

        if url.kind not in SICK_KINDS:
            raise LaserUrlError(f"--laser {url.text!r}: {url.kind} is not a SICK kind ({', '.join(SICK_KINDS)})")
        self.kind = url.kind
        self.device = SICK_KINDS[url.kind]
        self.host, self.port = url.host, url.port
        known = {"cola", "mode", "range_min", "range_max", *_MOUNT_KEYS}
        for key, _ in url.options:
            if key not in known:
                raise LaserUrlError(f"--laser {url.text!r}: unknown option {key!r}; {url.kind} takes {_OPTIONS}")
        self.cola = (url.option("cola", COLA_B) or "").lower()
        if self.cola not in (COLA_A, COLA_B):
            raise LaserUrlError(f"--laser {url.text!r}: cola must be a or b (CoLa-A ASCII / CoLa-B binary), "
                                f"got {self.cola!r}")
        self.mode = (url.option("mode", "stream") or "").lower()
        if self.mode not in ("stream", "poll"):
            raise LaserUrlError(f"--laser {url.text!r}: mode must be stream or poll, got {self.mode!r}")
        self.range_min_m = self._metres(url, "range_min", self.device.range_min_m)
        self.range_max_m = self._metres(url, "range_max", self.device.range_max_m)
        if not 0 <= self.range_min_m < self.range_max_m:
            raise LaserUrlError(f"--laser {url.text!r}: need 0 <= range_min < range_max, got "
                                f"{self.range_min_m:g} and {self.range_max_m:g}")
        self._sock: socket.socket | None = None
        self._deframer = Deframer()
        self._rx_time = 0.0
        self._clock = DeviceClock(wrap_s=DEVICE_CLOCK_WRAP_S)
        self._streaming = False
        self._last_rx = 0.0
        self._poll_sent: float | None = None
        self._next_poll = 0.0
        self._last_key: tuple[int, int] | None = None

    @staticmethod
    def _metres(url: LaserUrl, key: str, default: float) -> float:
        from . import LaserUrlError

        text = url.option(key)
        if text is None:
            return default
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        if not math.isfinite(v) or v < 0:
            raise LaserUrlError(f"--laser {url.text!r}: {key} must be a distance in metres, got {text!r}")
        return v

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    # ---- transport ----------------------------------------------------------------------------------------
    def _send(self, payload: bytes) -> None:
        if self._sock is None:
            raise ConnectionError(f"{self.address}: not connected")
        self._sock.sendall(frame(payload, self.cola))

    def _recv(self, timeout_s: float) -> tuple[str, bytes, float] | None:
        """The next telegram ``(cola, payload, arrival)``, None on time-out; ConnectionError when the peer closed."""
        deadline = time.monotonic() + timeout_s
        while True:
            t = self._deframer.next()
            if t is not None:
                return t[0], t[1], self._rx_time
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            if self._sock is None:
                raise ConnectionError(f"{self.address}: not connected")
            self._sock.settimeout(left)
            try:
                data = self._sock.recv(65536)
            except TimeoutError:
                return None
            if not data:
                raise ConnectionError(f"{self.address} closed the connection")
            self._rx_time = time.monotonic()
            self._deframer.feed(data)

    def _request(self, payload: bytes, kind: str, name: str, deadline: float) -> Command:
        """Send one request and wait for its answer (scan telegrams in between are skipped)."""
        request = payload.split(b" ", 2)
        what = b" ".join(request[:2]).decode("ascii", "replace")
        self._send(payload)
        while True:
            t = self._recv(max(0.0, deadline - time.monotonic()))
            if t is None:
                raise TelegramError(f"{self.address}: no answer to {what} in time")
            cmd = split_command(t[0], t[1])
            if cmd.is_error or (cmd.kind, cmd.name) == (kind, name):
                return cmd.expect(kind, name, what)

    # ---- ThreadedLaser -------------------------------------------------------------------------------------
    def _connect(self, timeout_s: float) -> LaserInfo:
        self._disconnect()
        deadline = time.monotonic() + timeout_s
        try:
            self._sock = socket.create_connection((self.host, self.port), timeout=max(0.05, timeout_s))
        except OSError as e:
            reason = "refused" if isinstance(e, ConnectionRefusedError) else \
                "timed out" if isinstance(e, TimeoutError) else str(e) or type(e).__name__
            raise LaserAddressError(
                f"{self.url}: nothing answers at {self.address} ({reason}); check the scanner's IP address "
                f"(SICK's default is 192.168.0.1, and the host needs an address in the same subnet) and the port "
                f"(2112 for CoLa-B; an LMS1xx/LMS5xx takes CoLa-A on 2111)") from e
        try:
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._deframer.clear()
            self._clock.reset()
            self._streaming, self._poll_sent, self._last_key = False, None, None
            model, version = self._identify(deadline)
            serial = ""
            try:
                ans = self._request(encode_command(self.cola, "sRN", "SerialNumber"), "sRA", "SerialNumber", deadline)
                serial = read_fields(ans).flex("serial number")
            except SopasError:
                pass  # not every firmware has it; the telegrams carry the serial number too
            if self.device.needs_start:
                self._start_measurement(deadline)
            if self.mode == "stream":
                ans = self._request(encode_command(self.cola, "sEN", "LMDscandata", ("u8", 1)), "sEA", "LMDscandata",
                                    deadline)
                if read_fields(ans).uint("start/stop", 8) != 1:
                    raise TelegramError(f"{self.address}: sEN LMDscandata 1 was answered sEA LMDscandata 0")
                self._streaming = True
            self._last_rx = time.monotonic()
        except BaseException:
            self._disconnect()
            raise
        info = LaserInfo(kind=self.kind, address=self.address, model=f"{model} {version}".strip(), serial=serial,
                         stamps="device", latency_s=0.0,
                         scan_hz=self.info.scan_hz if self.info is not None else 0.0)
        return info

    def _identify(self, deadline: float) -> tuple[str, str]:
        """Send ``sRN DeviceIdent`` and check what answers: (name, version) of a device of the URL's kind."""
        where = f"{self.url}: the device at {self.address}"
        self._send(encode_command(self.cola, "sRN", "DeviceIdent"))
        seen = bytearray()
        t = None
        while t is None:
            try:
                t = self._deframer.next()
            except TelegramError:
                raise WrongDeviceError(f"{where} is no SICK scanner speaking CoLa: "
                                       f"{describe_foreign_bytes(bytes(seen))}") from None
            if t is not None:
                break
            left = deadline - time.monotonic()
            if left <= 0:
                other = "a" if self.cola == COLA_B else "b"
                raise WrongDeviceError(
                    f"{where} accepted the connection but did not answer sRN DeviceIdent "
                    + (f"(it sent {_show(bytes(seen))}) " if seen else "")
                    + f"in CoLa-{self.cola.upper()}: if it is a SICK scanner, try cola={other} or the other port "
                    "(LMS1xx/LMS5xx: CoLa-A on 2111, CoLa-B on 2112)")
            assert self._sock is not None
            self._sock.settimeout(left)
            try:
                data = self._sock.recv(4096)
            except TimeoutError:
                continue
            if not data:
                if seen:
                    raise WrongDeviceError(f"{where} is no SICK scanner speaking CoLa: "
                                           f"{describe_foreign_bytes(bytes(seen))}")
                raise WrongDeviceError(f"{where} accepted the connection and closed it without answering sRN "
                                       "DeviceIdent (a SICK scanner that serves as many clients as it allows may do "
                                       "this)")
            self._rx_time = time.monotonic()
            if len(seen) < 512:
                seen += data[: 512 - len(seen)]
            self._deframer.feed(data)
        cola, payload = t
        if cola != self.cola:
            raise WrongDeviceError(
                f"{where} answered in CoLa-{cola.upper()} to a CoLa-{self.cola.upper()} request: that port speaks "
                f"CoLa-{cola.upper()}; use cola={cola} or the CoLa-{self.cola.upper()} port "
                "(LMS1xx/LMS5xx: CoLa-A on 2111, CoLa-B on 2112)")
        try:
            cmd = split_command(cola, payload)
        except TelegramError:
            raise WrongDeviceError(f"{where} is no SICK scanner speaking CoLa: "
                                   f"{describe_foreign_bytes(payload)}") from None
        cmd.raise_if_error("sRN DeviceIdent")
        if (cmd.kind, cmd.name) != ("sRA", "DeviceIdent"):
            raise WrongDeviceError(f"{where} answered sRN DeviceIdent with {cmd.kind} {cmd.name}: a SOPAS device, "
                                   "but not one of the TiM / LMS scanners")
        r = read_fields(cmd)
        name = r.flex("device name").strip()
        version = r.flex("version").strip()
        prefix = self.device.ident_prefix
        if not name.upper().startswith(prefix.upper()):
            fits = [k for k, d in SICK_KINDS.items() if name.upper().startswith(d.ident_prefix.upper())]
            hint = (f"open it as {fits[0]}://{self.address}" if fits else
                    "this driver reads TiM5xx, LMS1xx and LMS5xx scanners")
            raise WrongDeviceError(f"{where} is a {name} ({version}), not a {self.kind} (whose device ident starts "
                                   f"with {prefix!r}); {hint}")
        return name, version

    def _start_measurement(self, deadline: float) -> None:
        ans = self._request(encode_command(self.cola, "sMN", "SetAccessMode", ("u8", CLIENT_LEVEL),
                                           ("u32", CLIENT_PASSWORD_HASH)), "sAN", "SetAccessMode", deadline)
        if read_fields(ans).uint("success", 8) != 1:
            raise TelegramError(f"{self.address}: log-in as authorized client refused (sAN SetAccessMode 0)")
        ans = self._request(encode_command(self.cola, "sMN", "LMCstartmeas"), "sAN", "LMCstartmeas", deadline)
        if (err := read_fields(ans).uint("error code", 8)) != 0:
            raise TelegramError(f"{self.address}: sMN LMCstartmeas answered error {err}")
        self._request(encode_command(self.cola, "sMN", "Run"), "sAN", "Run", deadline)  # value: see [LMS5 10.2.12]

    def _disconnect(self) -> None:
        sock, self._sock = self._sock, None
        if sock is None:
            return
        if self._streaming:
            try:
                sock.settimeout(0.2)
                sock.sendall(frame(encode_command(self.cola, "sEN", "LMDscandata", ("u8", 0)), self.cola))
            except OSError:
                pass
        self._streaming = False
        try:
            sock.close()
        except OSError:
            pass

    def _read_scan(self) -> LaserScan | None:
        if self.mode == "poll":
            return self._read_polled()
        t = self._recv(self.read_timeout_s)
        if t is None:
            if time.monotonic() - self._last_rx > self.stall_s:
                raise ConnectionError(f"{self.address}: no telegram for {self.stall_s:g} s")
            return None
        self._last_rx = t[2]
        cmd = split_command(t[0], t[1]).raise_if_error("scan stream")
        if cmd.name != "LMDscandata" or cmd.kind not in ("sSN", "sRA"):
            return None  # e.g. the sEA confirmation
        return self._to_scan(parse_scandata(cmd), t[2])

    def _read_polled(self) -> LaserScan | None:
        if self._poll_sent is None:
            wait = self._next_poll - time.monotonic()
            if wait > 0 and self._stop.wait(wait):
                return None
            self._send(encode_command(self.cola, "sRN", "LMDscandata"))
            self._poll_sent = time.monotonic()
        t = self._recv(self.read_timeout_s)
        if t is None:
            if time.monotonic() - self._poll_sent > self.stall_s:
                raise ConnectionError(f"{self.address}: no answer to sRN LMDscandata for {self.stall_s:g} s")
            return None
        cmd = split_command(t[0], t[1])
        if cmd.is_error:
            self._poll_sent = None
            cmd.raise_if_error("sRN LMDscandata")
        if (cmd.kind, cmd.name) != ("sRA", "LMDscandata"):
            return None
        sent, self._poll_sent = self._poll_sent, None
        assert sent is not None  # set when the poll went out; an error answer raised above
        tel = parse_scandata(cmd)
        hz = tel.scan_frequency_hz if tel.scan_frequency > 0 else 15.0
        self._next_poll = sent + 1.0 / hz
        key = (tel.scan_counter, tel.time_since_startup_us)
        if key == self._last_key:
            return None  # the device had no newer scan yet
        self._last_key = key
        return self._to_scan(tel, t[2])

    def _to_scan(self, tel: ScanTelegram, arrival_s: float) -> LaserScan:
        ch = tel.dist1
        n = len(ch.data)
        if n < 1:
            raise TelegramError("LMDscandata: the DIST1 channel has no values")
        ranges = ch.scaled() / 1000.0
        ranges[(ch.data == 0) | (ranges < self.range_min_m)] = np.nan
        hz = tel.scan_frequency_hz
        beam_dt = ch.angular_step_deg / 360.0 / hz if hz > 0 else 0.0
        span_s = ((tel.time_of_transmission_us - tel.time_since_startup_us) % 2**32) * 1e-6
        if tel.time_of_transmission_us == 0 or span_s > 1.0:  # no usable transmission time: use the start
            span_s = 0.0
            tx_host = self._clock.to_host(tel.time_since_startup_us * 1e-6, arrival_s)
        else:
            tx_host = self._clock.to_host(tel.time_of_transmission_us * 1e-6, arrival_s)
        stamp = tx_host - span_s + 0.5 * (n - 1) * beam_dt
        if span_s > 0:
            stamp = min(stamp, tx_host)
        if self.info is not None and self.info.scan_hz == 0.0 and hz > 0:
            self.info = replace(self.info, scan_hz=hz)
        return LaserScan(
            angle_min_rad=math.radians(ch.start_angle_deg) - math.pi / 2,
            angle_increment_rad=math.radians(ch.angular_step_deg),
            ranges_m=ranges,
            range_max_m=self.range_max_m,
            stamp_s=stamp,
        )
