"""Hokuyo URG / UST scanners over SCIP 2.0: a pure codec and the :class:`ScipScanner` driver.

Sources (facts only; section and page numbers as printed in each document):

- Hokuyo Automatic Co., Ltd., *Communication Protocol Specification For SCIP2.0 Standard*, drawing C-42-03320B
  (25 pages, the URG-04LX / UBG-04LX-F01 / UHG-08LX / UTM-30LX edition):

  - section 2 (p.3): ``SCIP2.0`` switches a sensor from SCIP1.1; its reply is the echo, a one-character status
    ``0`` and the blank line; the sensor returns to SCIP1.1 on restart, so a driver sends it on every connect.
  - section 4 (p.4): RS-232C 19.2-750 kbit/s, 8N1, no flow control; USB is CDC (``cdc_acm`` on Linux), where the
    bit rate has no effect.
  - section 5 (p.5, figure 1 and table 2): the scanner turns anti-clockwise seen from the top; steps count in the
    turning direction from step 0, the first measurement point; step B (``AFRT``) is the front; the angular
    resolution is 360 deg / the slit division (``ARES``). So ``angle = (step - AFRT) * 2 pi / ARES`` is
    counter-clockwise positive with 0 = forward, the sensor frame of :mod:`.base`.
  - section 6 (p.6-8): 2-, 3- and 4-character encodings: 6-bit groups, most significant first, each plus 30H
    (examples: 1234 = ``CB``, 5432 = ``1Dh``, 16,000,000 = ``m2@0``).
  - section 7 (p.9): a command is the 2-character symbol, its parameters, optionally ``;`` and up to 16 string
    characters (letters, digits, blank, ``.``, ``_``, ``+``, ``@``), ended by LF, CR or both. A reply is the
    command echo, the 2-character status with its sum, the data lines, and two LFs. Statuses other than 00 and
    99 are errors. The sum is the lower 6 bits of the byte sum plus 30H.
  - section 8.1 (p.10-12) MD/MS: ``MD|MS start(4) end(4) cluster(2) interval(1) scans(2)``; first reply the
    echo with status 00; then per scan the echo with the *remaining* scans in place of the number of scans, status
    ``99b``, the 4-character time stamp and its sum, and the data in blocks of 64 characters each followed by its
    sum and LF; status codes 01-07, 21-49, 50-97, 98. The time stamp is a 24-bit, 1 ms timer read at step 0 of
    the scan. Distance values below 20 are error codes (table 3: URG-04LX family 0-19; table 4: UTM-30LX 1-5).
    MD is 3-character data, MS 2-character.
  - section 8.2 (p.13) GD/GS: ``GD|GS start(4) end(4) cluster(2)``, the newest scan with status 00; status 10
    when the laser is off (BM first). Section 8.3-8.5 (p.14): BM (00, 01, 02 = already on), QT and RS (00).
    Section 8.6 (p.15): TM0 adjust mode on, TM1 time request (``TM1``, ``00P``, 4-character time and sum),
    TM2 adjust mode off; statuses 01-04. Section 8.12 (p.21): PP lines MODL, DMIN, DMAX, ARES, AMIN, AMAX,
    AFRT, SCAN, each ``KEY:value;sum``. Sections 8.11 and 8.13: VV (VEND, PROD, FIRM, PROT, SERI) and II.
    Section 9 (p.23): errors 0A-0I for invalid commands (0E: undefined command).
  - The VV/PP/II examples (C-42-03320B p.21 and Hokuyo's URG Network wiki page *scip_status_en*, which prints
    the same examples legibly) show the line sum taken over ``KEY:value`` without the ``;``: ``DMIN:20;4``,
    ``PROT:SCIP 2.0;N``.

- Hokuyo, *Communication Protocol Specification For UST Series 10LX/20LX*, drawing C-42-04076 (sections 2-4):
  Ethernet 100BASE-T, TCP/IP, factory address 192.168.0.10, port 10940 (fixed); SCIP-compliant and kept
  compatible with the UTM-30LX-EW. The ME/GE commands (distance and intensity, 3 characters each per step) and
  RT (reset without the motor speed and bit rate) are the UTM-30LX-EW extensions that document refers to; the
  driver does not use them, the codec parses them.

The driver: connect (TCP for ``ust``, pyserial for ``urg``), QT, SCIP2.0, VV and PP (a reply that is not SCIP text
or not a VV answer is a :class:`WrongDeviceError`), TM0 / TM1 x5 / TM2 to bound the device clock offset and the
round trip, then MD for all steps AMIN..AMAX (``?mode=md``, the default) or BM and one GD per scan
(``?mode=gd``). Error codes (< 20) and values below DMIN are NaN; ``range_max_m`` is DMAX. Stamps: the scan's
time stamp (step 0) plus ``step * 60 / (SCAN * ARES)`` s gives the device time of its last step, mapped to the
host clock by :class:`DeviceClock` (24-bit ms wrap) seeded with the TM bound, then moved back to the middle step.
"""

from __future__ import annotations

import errno
import math
import os
import socket
import string
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Iterable, Sequence

import numpy as np

from ..types import LaserScan
from .base import (
    DeviceClock,
    LaserAddressError,
    LaserError,
    LaserInfo,
    LaserMount,
    TelegramError,
    ThreadedLaser,
    WrongDeviceError,
)

if TYPE_CHECKING:
    from . import LaserUrl

__all__ = ["ScipScanner", "ScipParams", "ScipReply", "ScipScan", "checksum", "encode", "decode", "encode_array",
           "decode_array", "build_command", "scan_command", "parse_block", "parse_reply", "parse_status",
           "parse_info", "parse_scan", "parse_time", "format_reply", "info_line", "data_lines", "time_line",
           "status_text", "TIMESTAMP_WRAP_MS", "ERROR_CODE_LIMIT_MM", "BLOCK_CHARS", "DEFAULT_PORT"]

DEFAULT_PORT = 10940  # UST series, C-42-04076 section 2 (fixed)
TIMESTAMP_WRAP_MS = 1 << 24  # 24-bit 1 ms timer (C-42-03320B section 8.1)
ERROR_CODE_LIMIT_MM = 20  # distance values 0..19 are error codes (tables 3 and 4)
BLOCK_CHARS = 64  # data block length before its sum character (section 8.1)
TAG_CHARS = frozenset(string.ascii_letters + string.digits + " ._+@")  # section 7
MAX_TAG = 16
SCAN_CODES = ("MD", "MS", "ME", "GD", "GS", "GE")

# ---- the character encoding (section 6) ------------------------------------------------------------------------


def checksum(text: str | bytes) -> str:
    """The SCIP sum character of ``text``: lower 6 bits of the byte sum, plus 30H (section 7)."""
    data = text.encode("ascii") if isinstance(text, str) else bytes(text)
    return chr((sum(data) & 0x3F) + 0x30)


def encode(value: int, width: int) -> str:
    """``value`` as ``width`` (2, 3 or 4) characters: 6-bit groups, most significant first, each + 30H."""
    if width not in (2, 3, 4):
        raise ValueError(f"SCIP encodes in 2, 3 or 4 characters, not {width}")
    v = int(value)
    if not 0 <= v < 1 << (6 * width):
        raise ValueError(f"SCIP: {value} does not fit {width} characters (0..{(1 << (6 * width)) - 1})")
    return "".join(chr(((v >> (6 * (width - 1 - k))) & 0x3F) + 0x30) for k in range(width))


def decode(chars: str) -> int:
    """The value of SCIP-encoded characters (any width); TelegramError for a character outside 30H-6FH."""
    v = 0
    for c in chars:
        d = ord(c) - 0x30
        if not 0 <= d < 64:
            raise TelegramError(f"SCIP: {c!r} in {chars!r} is not an encoded character (0x30-0x6F)")
        v = (v << 6) | d
    return v


def decode_array(chars: str, width: int) -> np.ndarray:
    """Values of consecutive ``width``-character groups (int64 array)."""
    if len(chars) % width:
        raise TelegramError(f"SCIP: {len(chars)} data characters are not whole {width}-character values")
    raw = np.frombuffer(chars.encode("ascii", "replace"), dtype=np.uint8).astype(np.int64) - 0x30
    bad = (raw < 0) | (raw > 63)
    if bad.any():
        i = int(np.argmax(bad))
        raise TelegramError(f"SCIP: data character {chars[i]!r} at {i} is not an encoded character (0x30-0x6F)")
    groups = raw.reshape(-1, width)
    out = np.zeros(len(groups), dtype=np.int64)
    for k in range(width):
        out = (out << 6) | groups[:, k]
    return out


def encode_array(values: Sequence[int] | np.ndarray, width: int) -> str:
    """``values`` encoded back to back, ``width`` characters each."""
    v = np.asarray(values, dtype=np.int64).reshape(-1)
    if width not in (2, 3, 4):
        raise ValueError(f"SCIP encodes in 2, 3 or 4 characters, not {width}")
    if v.size and (v.min() < 0 or v.max() >= 1 << (6 * width)):
        raise ValueError(f"SCIP: values outside 0..{(1 << (6 * width)) - 1} do not fit {width} characters")
    cols = [((v >> (6 * (width - 1 - k))) & 0x3F) + 0x30 for k in range(width)]
    return np.stack(cols, axis=1).astype(np.uint8).tobytes().decode("ascii") if v.size else ""


# ---- commands (sections 7, 8) ------------------------------------------------------------------------------------


def build_command(code: str, params: str = "", tag: str = "") -> bytes:
    """One command line: symbol, parameters, optional ``;`` and string characters, LF."""
    if tag:
        if len(tag) > MAX_TAG or not set(tag) <= TAG_CHARS:
            raise ValueError(f"SCIP string characters: at most {MAX_TAG} of letters, digits, ' ._+@'; got {tag!r}")
        return f"{code}{params};{tag}\n".encode("ascii")
    return f"{code}{params}\n".encode("ascii")


def scan_command(code: str, start: int, end: int, cluster: int = 0, interval: int = 0, scans: int = 0,
                 tag: str = "") -> bytes:
    """MD/MS/ME (with interval and number of scans, 00 = continuous) or GD/GS/GE (start, end, cluster)."""
    if code not in SCAN_CODES:
        raise ValueError(f"not a SCIP scan command: {code!r}")
    if not (0 <= start <= 9999 and 0 <= end <= 9999 and 0 <= cluster <= 99):
        raise ValueError(f"SCIP {code}: start/end 0-9999 and cluster 0-99, got {start}, {end}, {cluster}")
    params = f"{start:04d}{end:04d}{cluster:02d}"
    if code[0] == "M":
        if not (0 <= interval <= 9 and 0 <= scans <= 99):
            raise ValueError(f"SCIP {code}: interval 0-9 and scans 0-99, got {interval}, {scans}")
        params += f"{interval:01d}{scans:02d}"
    return build_command(code, params, tag)


# ---- statuses (sections 8, 9) ------------------------------------------------------------------------------------

_INVALID = {
    "0A": "unable to create the transmission data or reply internally",
    "0B": "buffer shortage, or a command repeated that is already being processed",
    "0C": "command with insufficient parameters",
    "0D": "undefined command (1)",
    "0E": "undefined command",
    "0F": "command with insufficient parameters (2)",
    "0G": "string characters exceed 16 letters",
    "0H": "string characters have invalid letters",
    "0I": "the sensor is in firmware update mode",
}
_SCAN = {
    "01": "starting step has a non-numeric value",
    "02": "end step has a non-numeric value",
    "03": "cluster count has a non-numeric value",
    "04": "end step is out of range",
    "05": "end step is smaller than the starting step",
    "06": "scan interval has a non-numeric value",
    "07": "number of scans has a non-numeric value",
    "10": "the laser is off (GD needs BM first)",
    "98": "resumption of processing after confirming normal laser operation",
}
_PER_COMMAND = {
    "BM": {"01": "unable to control the laser (malfunction)", "02": "the laser is already on"},
    "TM": {"01": "invalid control code", "02": "adjust mode is already on", "03": "adjust mode is already off",
           "04": "adjust mode is off when the time was requested"},
    "SS": {"01": "bit rate has a non-numeric value", "02": "invalid bit rate", "03": "already at that bit rate",
           "04": "not compatible with this sensor model"},
}


def status_text(code: str, status: str) -> str:
    """What a status means for command ``code`` (C-42-03320B sections 8 and 9)."""
    if status in ("00", "99"):
        return "normal"
    if status in _INVALID:
        return _INVALID[status]
    if code in _PER_COMMAND and status in _PER_COMMAND[code]:
        return _PER_COMMAND[code][status]
    if code in SCAN_CODES and status in _SCAN:
        return _SCAN[status]
    if status.isdigit():
        n = int(status)
        if 21 <= n <= 49:
            return "processing stopped to verify an error"
        if 50 <= n <= 97:
            return "hardware trouble (laser, motor malfunction)"
    return "error status"


# ---- replies (section 7) -----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScipReply:
    """A reply block: the echo line, the 2-character status (its sum checked) and the lines after it."""

    echo: str
    status: str
    body: tuple[str, ...]

    @property
    def code(self) -> str:
        return self.echo[:2]

    def require(self, *ok: str) -> "ScipReply":
        """This reply, or TelegramError when its status is not one of ``ok`` (default 00)."""
        allowed = ok or ("00",)
        if self.status not in allowed:
            raise TelegramError(f"SCIP {self.echo!r}: status {self.status} ({status_text(self.code, self.status)})")
        return self


def parse_block(data: bytes) -> list[str]:
    """The lines of one reply block (``data`` ends with the blank-line terminator LF LF)."""
    if not data.endswith(b"\n\n"):
        raise TelegramError(f"SCIP: truncated reply (no LF LF terminator): {data[-40:]!r}")
    try:
        text = data[:-2].decode("ascii")
    except UnicodeDecodeError:
        raise TelegramError(f"SCIP: reply has non-ASCII bytes: {data[:40]!r}") from None
    lines = text.split("\n")
    for ln in lines:
        if not ln:
            raise TelegramError(f"SCIP: empty line inside a reply block: {data[:60]!r}")
        if not ln.isprintable():
            raise TelegramError(f"SCIP: control characters in reply line {ln!r}")
    return lines


def parse_status(line: str) -> str:
    """The status of a status line (2 characters and their sum); TelegramError for a bad length or sum."""
    if len(line) != 3:
        raise TelegramError(f"SCIP: status line {line!r} is not 2 status characters and a sum")
    st, s = line[:2], line[2]
    want = checksum(st)
    if s != want:
        raise TelegramError(f"SCIP: status {st!r} has sum {s!r}, expected {want!r}")
    return st


def parse_reply(lines: Sequence[str], command: str | None = None) -> ScipReply:
    """Echo, status and body; ``command`` (the line sent, without LF) must equal the echo."""
    if len(lines) < 2:
        raise TelegramError(f"SCIP: reply {list(lines)!r} has no status line")
    echo = lines[0]
    if command is not None and echo != command:
        raise TelegramError(f"SCIP: echo {echo!r} does not match the command {command!r}")
    return ScipReply(echo, parse_status(lines[1]), tuple(lines[2:]))


def parse_info(body: Iterable[str]) -> dict[str, str]:
    """VV / PP / II lines ``KEY:value;sum`` (sum over ``KEY:value``) as a dict."""
    out: dict[str, str] = {}
    for line in body:
        if len(line) < 3 or line[-2] != ";":
            raise TelegramError(f"SCIP: information line {line!r} does not end in ';' and a sum")
        text, s = line[:-2], line[-1]
        want = checksum(text)
        if s != want:
            raise TelegramError(f"SCIP: information line {line!r} has sum {s!r}, expected {want!r}")
        key, sep, value = text.partition(":")
        if not sep or not key:
            raise TelegramError(f"SCIP: information line {line!r} is not KEY:value")
        out[key] = value
    return out


def parse_time(line: str) -> int:
    """A 4-character time (ms, 24 bits) with its sum: the scan time stamp line or the TM1 time line."""
    if len(line) != 5:
        raise TelegramError(f"SCIP: time line {line!r} is not 4 characters and a sum")
    want = checksum(line[:4])
    if line[4] != want:
        raise TelegramError(f"SCIP: time {line[:4]!r} has sum {line[4]!r}, expected {want!r}")
    return decode(line[:4])


def _join_blocks(lines: Sequence[str], what: str) -> str:
    parts = []
    for k, line in enumerate(lines):
        if len(line) < 2:
            raise TelegramError(f"SCIP {what}: data line {k + 1} {line!r} has no data before its sum")
        block, s = line[:-1], line[-1]
        if len(block) > BLOCK_CHARS or (k < len(lines) - 1 and len(block) != BLOCK_CHARS):
            raise TelegramError(f"SCIP {what}: data block {k + 1} has {len(block)} characters; blocks are "
                                f"{BLOCK_CHARS} (only the last may be shorter)")
        want = checksum(block)
        if s != want:
            raise TelegramError(f"SCIP {what}: data block {k + 1} has sum {s!r}, expected {want!r}")
        parts.append(block)
    return "".join(parts)


@dataclass(frozen=True)
class ScipScan:
    """One scan reply (MD/MS/ME with status 99, GD/GS/GE with status 00)."""

    code: str
    start: int
    end: int
    cluster: int
    remaining: int | None  # MD/MS/ME: remaining scans from the echo
    tag: str
    timestamp_ms: int  # 24-bit device time at step 0
    ranges_mm: np.ndarray  # int64, error codes < 20 kept as sent
    intensities: np.ndarray | None  # ME/GE

    @property
    def steps_per_value(self) -> int:
        return max(self.cluster, 1)


def scan_value_count(start: int, end: int, cluster: int) -> int:
    """How many values a scan command over steps ``start..end`` returns with ``cluster`` steps merged."""
    return -(-(end - start + 1) // max(cluster, 1))


def _parse_echo(echo: str) -> tuple[str, int, int, int, int | None, str]:
    code = echo[:2]
    if code not in SCAN_CODES:
        raise TelegramError(f"SCIP: {echo!r} is not the echo of a scan command ({', '.join(SCAN_CODES)})")
    params, _, tag = echo[2:].partition(";")
    need = 13 if code[0] == "M" else 10
    if len(params) != need or not params.isdigit():
        raise TelegramError(f"SCIP: echo {echo!r}: {code} takes {need} digits of parameters")
    start, end, cluster = int(params[0:4]), int(params[4:8]), int(params[8:10])
    remaining = int(params[11:13]) if code[0] == "M" else None
    if end < start:
        raise TelegramError(f"SCIP: echo {echo!r} has the end step before the start step")
    return code, start, end, cluster, remaining, tag


def parse_scan(lines: Sequence[str]) -> ScipScan:
    """A scan reply block: echo, status (99 for MD/MS/ME, 00 for GD/GS/GE), time stamp, data blocks."""
    if not lines:
        raise TelegramError("SCIP: empty scan reply")
    code, start, end, cluster, remaining, tag = _parse_echo(lines[0])
    if len(lines) < 2:
        raise TelegramError(f"SCIP {code}: reply {lines[0]!r} has no status line")
    status = parse_status(lines[1])
    want = "99" if code[0] == "M" else "00"
    if status != want:
        raise TelegramError(f"SCIP {lines[0]!r}: status {status} ({status_text(code, status)}), "
                            f"a scan has {want}")
    if len(lines) < 3:
        raise TelegramError(f"SCIP {code}: truncated reply, no time stamp")
    ts = parse_time(lines[2])
    chars = _join_blocks(lines[3:], code)
    width = 2 if code[1] == "S" else 3
    per = width * (2 if code[1] == "E" else 1)
    n = scan_value_count(start, end, cluster)
    if len(chars) != n * per:
        raise TelegramError(f"SCIP {code}: {len(chars)} data characters for {n} values of {per} "
                            f"(expected {n * per}): truncated or corrupt")
    values = decode_array(chars, width)
    if code[1] == "E":
        pairs = values.reshape(n, 2)
        return ScipScan(code, start, end, cluster, remaining, tag, ts, pairs[:, 0].copy(), pairs[:, 1].copy())
    return ScipScan(code, start, end, cluster, remaining, tag, ts, values, None)


# ---- reply builders (used by the emulator; the same framing) ------------------------------------------------------


def format_reply(echo: str, status: str, body: Iterable[str] = ()) -> bytes:
    """``echo LF status sum LF [body lines LF] LF`` (body lines complete with their own sums)."""
    lines = [echo, status + checksum(status), *body]
    return ("\n".join(lines) + "\n\n").encode("ascii")


def info_line(key: str, value: str) -> str:
    text = f"{key}:{value}"
    return f"{text};{checksum(text)}"


def time_line(ms: int) -> str:
    enc = encode(int(ms) % TIMESTAMP_WRAP_MS, 4)
    return enc + checksum(enc)


def data_lines(chars: str) -> list[str]:
    """``chars`` cut into 64-character blocks, each with its sum."""
    return [chars[i:i + BLOCK_CHARS] + checksum(chars[i:i + BLOCK_CHARS]) for i in range(0, len(chars), BLOCK_CHARS)]


# ---- PP parameters (section 8.12) ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScipParams:
    """The PP specification: model, DMIN/DMAX (mm), ARES (steps in 360 deg), AMIN..AMAX, AFRT, SCAN (rpm)."""

    model: str
    dmin_mm: int
    dmax_mm: int
    ares: int
    amin: int
    amax: int
    afrt: int
    scan_rpm: int

    def __post_init__(self) -> None:
        if self.ares <= 0 or self.scan_rpm <= 0:
            raise ValueError(f"SCIP PP: ARES and SCAN must be positive, got {self.ares}, {self.scan_rpm}")
        if not 0 <= self.amin <= self.amax:
            raise ValueError(f"SCIP PP: need 0 <= AMIN <= AMAX, got {self.amin}, {self.amax}")
        if not 0 <= self.dmin_mm < self.dmax_mm:
            raise ValueError(f"SCIP PP: need 0 <= DMIN < DMAX, got {self.dmin_mm}, {self.dmax_mm}")

    @classmethod
    def from_info(cls, info: dict[str, str]) -> "ScipParams":
        keys = ("DMIN", "DMAX", "ARES", "AMIN", "AMAX", "AFRT", "SCAN")
        missing = [k for k in keys if k not in info]
        if missing:
            raise TelegramError(f"SCIP PP: reply lacks {', '.join(missing)} (has {', '.join(info) or 'nothing'})")
        vals: dict[str, int] = {}
        for k in keys:
            try:
                vals[k] = int(info[k].strip())
            except ValueError:
                raise TelegramError(f"SCIP PP: {k} is {info[k]!r}, not a whole number") from None
        try:
            return cls(info.get("MODL", ""), vals["DMIN"], vals["DMAX"], vals["ARES"], vals["AMIN"], vals["AMAX"],
                       vals["AFRT"], vals["SCAN"])
        except ValueError as e:
            raise TelegramError(str(e)) from None

    @property
    def step_rad(self) -> float:
        return 2.0 * math.pi / self.ares

    @property
    def step_s(self) -> float:
        """Time from one step to the next: one turn (60 / SCAN s) over ARES steps."""
        return 60.0 / (self.scan_rpm * self.ares)

    @property
    def scan_hz(self) -> float:
        return self.scan_rpm / 60.0

    def angle_rad(self, step: float) -> float:
        """Sensor-frame angle of a step (counter-clockwise positive, 0 = the front step AFRT)."""
        return (step - self.afrt) * self.step_rad

    def info_lines(self) -> list[str]:
        return [info_line("MODL", self.model), info_line("DMIN", str(self.dmin_mm)),
                info_line("DMAX", str(self.dmax_mm)), info_line("ARES", str(self.ares)),
                info_line("AMIN", str(self.amin)), info_line("AMAX", str(self.amax)),
                info_line("AFRT", str(self.afrt)), info_line("SCAN", str(self.scan_rpm))]


# ---- framing on a byte stream ------------------------------------------------------------------------------------


class _ReadTimeout(Exception):
    """No complete reply block within the time allowed (the partial block is kept for the next call)."""


class NotScipText(TelegramError):
    """Bytes that SCIP never sends (control or non-ASCII bytes): the peer is not a SCIP device, or noise."""

    def __init__(self, message: str, raw: bytes) -> None:
        super().__init__(message)
        self.raw = raw


_TEXT = bytes([10, 13, *range(0x20, 0x7F)])
_NOT_TEXT = bytes(b for b in range(256) if b not in _TEXT)
_MAX_LINE = 8192


class BlockReader:
    """Cuts a byte stream into SCIP reply blocks (lines up to the blank line).

    ``recv(timeout_s)`` returns the bytes available (b"" on time-out) and raises ConnectionError at end of stream.
    Bytes SCIP never sends raise :class:`NotScipText` once the complete blocks before them are read; the reader
    then skips to the next blank line (dropping further such bytes quietly), so one bad telegram costs one block.
    """

    def __init__(self, recv: Callable[[float], bytes]) -> None:
        self._recv = recv
        self._buf = bytearray()
        self._lines: list[str] = []
        self._nbytes = 0
        self._resync = False
        self._poison: tuple[bytes, bytes] | None = None  # (the bad bytes as seen, the text after them)
        self.seen: list[str] = []  # the first lines of blocks skipped by read_reply (for error messages)

    def read_block(self, timeout_s: float) -> tuple[list[str], int]:
        """The next block's lines and its size in bytes; _ReadTimeout when it is not complete in time."""
        end = time.monotonic() + timeout_s
        while True:
            i = self._buf.find(b"\n")
            while i >= 0:
                raw = bytes(self._buf[:i])
                del self._buf[:i + 1]
                self._nbytes += i + 1
                if raw.endswith(b"\r"):
                    raw = raw[:-1]
                if not raw:
                    if self._resync:
                        self._resync = False
                        self._lines, self._nbytes = [], 0
                    elif self._lines:
                        lines, n = self._lines, self._nbytes
                        self._lines, self._nbytes = [], 0
                        return lines, n
                    else:
                        self._nbytes = 0  # a stray LF between blocks
                elif not self._resync:
                    self._lines.append(raw.decode("ascii"))
                i = self._buf.find(b"\n")
            if self._poison is not None:
                raw, after = self._poison
                self._poison = None
                self._drop()
                self._buf += after
                raise NotScipText(f"SCIP: bytes that are not SCIP text ({raw.translate(None, _TEXT)[:8]!r} in "
                                  f"{raw[:40]!r})", raw)
            if len(self._buf) > _MAX_LINE:
                raw = bytes(self._buf[:40])
                self._drop()
                raise NotScipText(f"SCIP: a line of more than {_MAX_LINE} bytes without LF: {raw!r}", raw)
            left = end - time.monotonic()
            if left <= 0:
                raise _ReadTimeout()
            chunk = self._recv(left)
            if not chunk:
                continue
            bad = chunk.translate(None, _TEXT)
            if bad and not self._resync:
                j = chunk.index(bad[:1])
                self._buf += chunk[:j]
                self._poison = (chunk[j:], chunk[j:].translate(None, _NOT_TEXT))
            else:
                self._buf += chunk.translate(None, _NOT_TEXT) if bad else chunk

    def _drop(self) -> None:
        self._buf.clear()
        self._lines, self._nbytes = [], 0
        self._resync = True


# ---- transports ------------------------------------------------------------------------------------------------


class _TcpLink:
    def __init__(self, host: str, port: int, timeout_s: float, label: str) -> None:
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except ConnectionRefusedError:
            raise LaserAddressError(f"{label}: connection refused at {host}:{port}; nothing listens there. Check the "
                                    f"address (a UST-10LX answers on 192.168.0.10:{DEFAULT_PORT} unless re-addressed) "
                                    f"and that the scanner is powered") from None
        except socket.gaierror as e:
            raise LaserAddressError(f"{label}: unknown host {host!r} ({e.strerror})") from None
        except TimeoutError:
            raise LaserAddressError(f"{label}: no answer from {host}:{port} within {timeout_s:g} s; check the cable "
                                    f"and that this computer has an address on the scanner's subnet "
                                    f"(192.168.0.x for a factory-set UST)") from None
        except OSError as e:
            raise LaserAddressError(f"{label}: cannot reach {host}:{port}: {e.strerror or e}") from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.baud_limited = False

    def recv(self, timeout_s: float) -> bytes:
        self.sock.settimeout(max(timeout_s, 1e-3))
        try:
            data = self.sock.recv(65536)
        except TimeoutError:
            return b""
        if not data:
            raise ConnectionError("the scanner closed the connection")
        return data

    def send(self, data: bytes) -> None:
        self.sock.settimeout(2.0)
        self.sock.sendall(data)

    def transfer_s(self, nbytes: int) -> float:
        return 0.0

    def close(self) -> None:
        self.sock.close()


def _no_baud(path: str) -> bool:
    """A USB CDC-ACM port (the URG's USB, section 4) or a pseudo-terminal: the bit rate does not pace it."""
    real = os.path.realpath(path)
    base = os.path.basename(real)
    return base.startswith("ttyACM") or "usbmodem" in base or real.startswith("/dev/pts/")


class _SerialLink:
    def __init__(self, path: str, baud: int, label: str) -> None:
        import serial  # pyserial

        if not os.path.exists(path):
            raise LaserAddressError(f"{label}: no such serial device {path!r}. Check the path (a URG on USB is "
                                    f"usually /dev/ttyACM0: ls /dev/ttyACM*) and the cable")
        try:
            self.ser = serial.Serial(path, baudrate=baud, timeout=0.05, write_timeout=2.0)
        except serial.SerialException as e:
            code = e.errno if isinstance(e.errno, int) else None
            if code in (errno.EACCES, errno.EPERM):
                raise LaserAddressError(f"{label}: permission denied on {path}; add your user to the 'dialout' "
                                        f"group (sudo usermod -aG dialout $USER, then log in again)") from None
            if code == errno.ENOENT:
                raise LaserAddressError(f"{label}: no such serial device {path!r}; check the path and the cable") \
                    from None
            if code == errno.EBUSY:
                raise LaserAddressError(f"{label}: {path} is busy (another program has it open)") from None
            raise LaserAddressError(f"{label}: cannot open {path}: {e}") from None
        self.baud = baud
        self.baud_limited = not _no_baud(path)  # a USB ACM port or a pty moves bytes at USB / memory speed
        self.ser.reset_input_buffer()

    def recv(self, timeout_s: float) -> bytes:
        end = time.monotonic() + timeout_s
        while True:
            data: bytes = self.ser.read(self.ser.in_waiting or 1)
            if data:
                more = self.ser.in_waiting
                return data + self.ser.read(more) if more else data
            if time.monotonic() >= end:
                return b""

    def send(self, data: bytes) -> None:
        self.ser.write(data)
        self.ser.flush()

    def transfer_s(self, nbytes: int) -> float:
        return nbytes * 10.0 / self.baud if self.baud_limited else 0.0  # 8N1: 10 bits a byte (section 4)

    def close(self) -> None:
        self.ser.close()


# ---- the driver ----------------------------------------------------------------------------------------------


_OPTIONS = ("mode", "baud")
_TM_SAMPLES = 5
_TM1_BYTES = 19  # "TM1" LF, then "TM1" LF "00P" LF, 4 characters, sum, LF LF
_TM_SLACK_S = 0.25  # a TM offset bound this much tighter than the scans' is taken for another clock and dropped


class ScipScanner(ThreadedLaser):
    """A Hokuyo URG (``urg:DEVICE``, serial/USB) or UST/UTM (``ust://HOST[:PORT]``, TCP) over SCIP 2.0.

    Options: ``mode=md`` (continuous MD, default) or ``mode=gd`` (one GD per scan after BM); ``baud=`` for serial
    (default 115200; USB ACM devices ignore it). After :meth:`start`, :attr:`params` holds the PP answer and
    :attr:`version` the VV lines; :attr:`tm_round_trip_s` the fastest TM1 round trip (None without TM).
    """

    kind = "scip"

    def __init__(self, url: "LaserUrl", mount: LaserMount) -> None:
        from . import LaserUrlError

        super().__init__(url.text, mount)
        if url.kind not in ("ust", "urg"):
            raise LaserUrlError(f"--laser {url.text!r}: the SCIP driver serves ust:// and urg:, not {url.kind}")
        self.kind = url.kind
        self._u = url
        unknown = [k for k, _ in url.options if k not in _OPTIONS]
        if unknown:
            raise LaserUrlError(f"--laser {url.text!r}: unknown option {unknown[0]!r}; {url.kind} takes "
                                f"mode=md|gd" + (" and baud=N" if url.kind == "urg" else ""))
        mode = (url.option("mode", "md") or "md").lower()
        if mode not in ("md", "gd"):
            raise LaserUrlError(f"--laser {url.text!r}: mode must be md (continuous) or gd (polled), got {mode!r}")
        self.mode = mode
        baud_text = url.option("baud", "115200") or "115200"
        if not baud_text.isdigit() or int(baud_text) <= 0:
            raise LaserUrlError(f"--laser {url.text!r}: baud must be a positive number, got {baud_text!r}")
        self.baud = int(baud_text)
        self.address = f"{url.host}:{url.port}" if url.kind == "ust" else url.path
        self.label = f"{url.kind} {self.address}"
        self.params: ScipParams | None = None
        self.version: dict[str, str] = {}
        self.tm_round_trip_s: float | None = None
        self.tm_used = False  # whether the TM bound seeded the clock (False: dropped or no TM)
        self._link: _TcpLink | _SerialLink | None = None
        self._reader: BlockReader | None = None
        self._clock = DeviceClock(wrap_s=TIMESTAMP_WRAP_MS / 1000.0)
        self._tm_best: tuple[float, float] | None = None  # (device s, host arrival s) of the fastest TM1
        self._last_scan_t = 0.0
        self._last_ts: int | None = None
        self._scan_cmd = b""

    # ---- I/O ---------------------------------------------------------------------------------------------------
    def _send(self, line: bytes) -> None:
        assert self._link is not None
        self._link.send(line)

    def _read_reply(self, command: str, deadline: float) -> ScipReply:
        """Blocks until one whose echo is ``command`` (others are skipped: stale scans); _ReadTimeout at deadline."""
        assert self._reader is not None
        while True:
            lines, _ = self._reader.read_block(max(deadline - time.monotonic(), 0.0))
            if lines[0] == command:
                return parse_reply(lines, command)
            if len(self._reader.seen) < 4:
                self._reader.seen.append(lines[0][:60])

    def _request(self, command: str, deadline: float, *ok: str) -> ScipReply:
        self._send(command.encode("ascii") + b"\n")
        return self._read_reply(command, deadline).require(*ok)

    # ---- connect -----------------------------------------------------------------------------------------------
    def _open(self, timeout_s: float) -> None:
        if self._u.kind == "ust":
            self._link = _TcpLink(self._u.host, self._u.port, timeout_s, self.label)
        else:
            self._link = _SerialLink(self._u.path, self.baud, self.label)
        self._reader = BlockReader(self._link.recv)

    def _not_scip(self, what: str) -> WrongDeviceError:
        where = f"UST/UTM on TCP port {DEFAULT_PORT}" if self.kind == "ust" else "URG on a USB/serial port"
        return WrongDeviceError(f"{self.label}: {what}; this is not a Hokuyo scanner speaking SCIP 2.0 "
                                f"(a {where})")

    def _identify(self, deadline: float) -> None:
        assert self._reader is not None
        now = time.monotonic()
        try:
            self._send(b"QT\n")  # stops a scan stream left running by a previous client
            try:
                self._read_reply("QT", min(deadline, now + 1.0))
            except NotScipText:
                raise
            except (_ReadTimeout, TelegramError):  # SCIP1.1 has no QT; a bad QT status is no verdict yet
                pass
            self._send(b"SCIP2.0\n")  # URG-04LX starting in SCIP1.1; others ignore it
            try:
                self._reader.read_block(min(deadline, time.monotonic() + 0.5) - time.monotonic())
            except _ReadTimeout:
                pass
            self._reader.seen.clear()
            vv = self._request("VV", deadline)
        except NotScipText as e:
            raw = e.raw
            if raw[:1] == b"\x02":
                raise self._not_scip(f"it answers with a STX-framed telegram {raw[:48]!r}, like a SICK CoLa "
                                     f"scanner") from None
            raise self._not_scip(f"it answers with binary bytes {raw[:24]!r}") from None
        except _ReadTimeout:
            seen = f"; it sent {', '.join(repr(s) for s in self._reader.seen)}" if self._reader.seen else ""
            raise self._not_scip(f"nothing answered the SCIP VV command within the time-out{seen}") from None
        except ConnectionError:
            raise self._not_scip("it closed the connection when sent SCIP commands (QT, VV)") from None
        except TelegramError as e:
            raise self._not_scip(f"its VV answer breaks SCIP ({e})") from None
        info = parse_info(vv.body)
        if not ("PROD" in info or "VEND" in info):
            raise self._not_scip(f"its VV answer has no VEND/PROD line ({', '.join(info) or 'empty'})")
        self.version = info
        pp = self._request("PP", deadline)
        self.params = ScipParams.from_info(parse_info(pp.body))

    def _time_sync(self, deadline: float) -> None:
        """TM0, TM1 x5, TM2 (section 8.6): the fastest TM1 bounds the clock offset (device read before arrival)."""
        self._tm_best, self.tm_round_trip_s = None, None
        try:
            self._request("TM0", deadline, "00", "02")
        except TelegramError:  # a device without TM: stamps come from the scans alone
            return
        best: tuple[float, float, float] | None = None
        try:
            for _ in range(_TM_SAMPLES):
                t0 = time.monotonic()
                r = self._request("TM1", deadline, "00")
                t1 = time.monotonic()
                if not r.body:
                    raise TelegramError("SCIP TM1: reply has no time line")
                dev_s = parse_time(r.body[0]) / 1000.0
                if best is None or t1 - t0 < best[0]:
                    best = (t1 - t0, dev_s, t1)
        except TelegramError:
            best = None
        try:
            self._request("TM2", deadline, "00", "03")
        except TelegramError:
            best = None  # still in adjust mode? the MD/BM status below will tell
        if best is not None:
            self.tm_round_trip_s = best[0]
            self._tm_best = (best[1], best[2])
            link = self._link
            if link is not None and link.baud_limited and best[0] < 0.5 * link.transfer_s(_TM1_BYTES):
                link.baud_limited = False  # measured: faster than the bit rate allows, so not an RS-232 line

    def _start_scans(self, deadline: float) -> None:
        p = self.params
        assert p is not None
        if self.mode == "md":
            cmd = scan_command("MD", p.amin, p.amax, 0, 0, 0)
            self._request(cmd.decode("ascii").strip(), deadline, "00")
        else:
            self._request("BM", deadline, "00", "02")
            cmd = scan_command("GD", p.amin, p.amax, 0)
        self._scan_cmd = cmd

    def _connect(self, timeout_s: float) -> LaserInfo:
        deadline = time.monotonic() + timeout_s
        self._open(timeout_s)
        try:
            self._identify(deadline)
            self._time_sync(deadline)
            self._start_scans(deadline)
        except _ReadTimeout:
            self._disconnect()
            raise LaserError(f"{self.label}: the scanner stopped answering during set-up (no reply within "
                             f"{timeout_s:g} s)") from None
        except LaserError:
            self._disconnect()
            raise
        except OSError as e:
            self._disconnect()
            raise LaserError(f"{self.label}: the connection failed during set-up: {e}") from None
        except BaseException:
            self._disconnect()
            raise
        self._clock = DeviceClock(wrap_s=TIMESTAMP_WRAP_MS / 1000.0)
        self.tm_used = False
        self._last_ts = None
        self._last_scan_t = time.monotonic()
        p = self.params
        assert p is not None
        return LaserInfo(kind=self.kind, address=self.address,
                         model=self.version.get("PROD", "") or p.model, serial=self.version.get("SERI", ""),
                         stamps="device", latency_s=(self.tm_round_trip_s or 0.0) / 2.0, scan_hz=p.scan_hz)

    def _disconnect(self) -> None:
        link, self._link = self._link, None
        self._reader = None
        if link is None:
            return
        try:
            link.send(b"QT\n")  # stop the stream and the laser; a pty or a serial URG keeps no other state
        except Exception:
            pass
        try:
            link.close()
        except Exception:
            pass

    # ---- scans -------------------------------------------------------------------------------------------------
    def _stall_s(self) -> float:
        hz = self.params.scan_hz if self.params else 10.0
        return max(2.0, 10.0 / hz)

    def _watchdog(self) -> None:
        quiet = time.monotonic() - self._last_scan_t
        if quiet > self._stall_s():
            raise ConnectionError(f"no scan for {quiet:.1f} s")

    def _read_scan(self) -> LaserScan | None:
        if self._reader is None or self._link is None:
            raise ConnectionError("not connected")
        if self.mode == "gd":
            return self._poll_scan()
        try:
            lines, nbytes = self._reader.read_block(0.25)
        except _ReadTimeout:
            self._watchdog()
            return None
        arrival = time.monotonic()
        if len(lines) == 2 and lines[0].encode("ascii") + b"\n" == self._scan_cmd:
            parse_reply(lines).require("00")  # the MD acknowledgement seen again: nothing to deliver
            return None
        scan = parse_scan(lines)
        if scan.code != "MD":
            raise TelegramError(f"SCIP: {lines[0]!r} in the MD stream")
        return self._to_scan(scan, arrival, nbytes)

    def _poll_scan(self) -> LaserScan | None:
        assert self._reader is not None and self._link is not None
        cmd = self._scan_cmd.decode("ascii").strip()
        self._send(self._scan_cmd)
        try:
            reply_end = time.monotonic() + 1.0
            while True:
                lines, nbytes = self._reader.read_block(max(reply_end - time.monotonic(), 0.0))
                if lines[0] == cmd:
                    break
        except _ReadTimeout:
            self._watchdog()
            return None
        arrival = time.monotonic()
        scan = parse_scan(lines)
        if scan.timestamp_ms == self._last_ts:  # the same scan as last time: wait a quarter period
            self._watchdog()
            time.sleep(0.25 / (self.params.scan_hz if self.params else 10.0))
            return None
        self._last_ts = scan.timestamp_ms
        return self._to_scan(scan, arrival, nbytes)

    def _to_scan(self, scan: ScipScan, arrival: float, nbytes: int) -> LaserScan:
        p = self.params
        assert p is not None and self._link is not None
        c = scan.steps_per_value
        mm = scan.ranges_mm
        bad = (mm < ERROR_CODE_LIMIT_MM) | (mm < p.dmin_mm)
        ranges = np.where(bad, np.nan, mm.astype(np.float64) / 1000.0)
        t0 = scan.timestamp_ms / 1000.0
        d_end = t0 + scan.end * p.step_s
        d_mid = t0 + 0.5 * (scan.start + scan.end) * p.step_s
        seen = arrival - self._link.transfer_s(nbytes)
        if self._tm_best is not None:  # first scan of this connection: take the TM bound if it fits this clock
            tm_dev, tm_arrival = self._tm_best
            self._tm_best = None
            # both are upper bounds of one offset; the transfer estimate is allowed again as its own error
            if (seen - d_end) - (tm_arrival - tm_dev) <= _TM_SLACK_S + self._link.transfer_s(nbytes):
                self._clock.to_host(tm_dev, tm_arrival)
                self.tm_used = True
        host_end = self._clock.to_host(d_end, seen)
        self._last_scan_t = arrival
        return LaserScan(angle_min_rad=p.angle_rad(scan.start + 0.5 * (c - 1)), angle_increment_rad=c * p.step_rad,
                         ranges_m=ranges, range_max_m=p.dmax_mm / 1000.0, stamp_s=host_end - (d_end - d_mid))
