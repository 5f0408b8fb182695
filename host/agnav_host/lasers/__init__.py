"""Laser scanners behind one source interface (:class:`LaserSource`), opened from a URL.

=====================  =====================================================  ==============================
URL                    device                                                 module
=====================  =====================================================  ==============================
``tim5xx://HOST[:P]``  SICK TiM5xx over Ethernet, CoLa-B on 2112 (default)    :mod:`.sick`
``lms1xx://HOST[:P]``  SICK LMS1xx, CoLa-B on 2112 (CoLa-A on 2111)           :mod:`.sick`
``lms5xx://HOST[:P]``  SICK LMS5xx, CoLa-B on 2112 (CoLa-A on 2111)           :mod:`.sick`
``ust://HOST[:P]``     Hokuyo UST / UTM over Ethernet, SCIP 2.0, port 10940   :mod:`.scip`
``urg:DEVICE``         Hokuyo URG over USB serial (``/dev/ttyACM0``), SCIP    :mod:`.scip`
``rplidar:DEVICE``     Slamtec RPLIDAR A1/A2 over serial (``/dev/ttyUSB0``)   :mod:`.rplidar`
``replay:FILE``        a laser log written by ``agnav run --out`` / the SIL   :mod:`.log`
=====================  =====================================================  ==============================

A query string sets driver options: ``tim5xx://192.168.0.1?cola=a&mode=poll`` (CoLa-A, polled with ``sRN``),
``urg:/dev/ttyACM0?baud=115200``, ``replay:run.alog?laser=1&rate=1``.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from urllib.parse import parse_qsl

from .base import (
    DeviceClock,
    LaserAddressError,
    LaserError,
    LaserInfo,
    LaserMount,
    LaserSource,
    LaserStats,
    TelegramError,
    ThreadedLaser,
    WrongDeviceError,
)

__all__ = ["LaserSource", "LaserMount", "LaserInfo", "LaserStats", "LaserError", "LaserAddressError",
           "WrongDeviceError", "TelegramError", "DeviceClock", "ThreadedLaser", "LaserUrl", "LaserUrlError",
           "parse_laser_url", "open_laser", "LASER_KINDS"]


class LaserUrlError(ValueError):
    """A ``--laser`` URL that names no known scanner or is malformed (the message shows the accepted forms)."""


# kind -> (module, class, transport, default port); transport "tcp" takes HOST[:PORT], "path" takes a device or file
LASER_KINDS: dict[str, tuple[str, str, str, int]] = {
    "tim5xx": ("sick", "SickScanner", "tcp", 2112),
    "lms1xx": ("sick", "SickScanner", "tcp", 2112),
    "lms5xx": ("sick", "SickScanner", "tcp", 2112),
    "ust": ("scip", "ScipScanner", "tcp", 10940),
    "urg": ("scip", "ScipScanner", "path", 0),
    "rplidar": ("rplidar", "RplidarScanner", "path", 0),
    "replay": ("log", "LaserLogReplay", "path", 0),
}

_FORMS = ("tim5xx://HOST[:PORT]", "lms1xx://HOST[:PORT]", "lms5xx://HOST[:PORT]", "ust://HOST[:PORT]",
          "urg:/dev/ttyACM0", "rplidar:/dev/ttyUSB0", "replay:FILE")


@dataclass(frozen=True)
class LaserUrl:
    """A parsed ``--laser`` URL."""

    text: str
    kind: str
    host: str = ""  # tcp kinds
    port: int = 0  # tcp kinds
    path: str = ""  # path kinds: device or file
    options: tuple[tuple[str, str], ...] = ()

    def option(self, key: str, default: str | None = None) -> str | None:
        for k, v in self.options:
            if k == key:
                return v
        return default


def parse_laser_url(text: str) -> LaserUrl:
    """Parse a ``--laser`` URL (forms in the module docstring); LaserUrlError says what is wrong."""
    t = text.strip()
    kind, sep, rest = t.partition(":")
    kind = kind.lower()
    if not sep or kind not in LASER_KINDS:
        raise LaserUrlError(f"--laser {text!r}: unknown scanner {kind!r}; use one of {', '.join(_FORMS)}")
    rest, _, query = rest.partition("?")
    try:
        opts = tuple(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
    except ValueError:
        raise LaserUrlError(f"--laser {text!r}: options must read key=value&key=value, got {query!r}") from None
    _, _, transport, default_port = LASER_KINDS[kind]
    if transport == "tcp":
        if not rest.startswith("//") or len(rest) <= 2:
            raise LaserUrlError(f"--laser {text!r}: {kind} is an Ethernet scanner: {kind}://HOST[:PORT]")
        hostport = rest[2:].rstrip("/")
        if hostport.startswith("["):
            host, _, tail = hostport[1:].partition("]")
            port_text = tail[1:] if tail.startswith(":") else ""
        else:
            host, _, port_text = hostport.partition(":")
        if not host:
            raise LaserUrlError(f"--laser {text!r}: no host; {kind}://HOST[:PORT]")
        port = default_port
        if port_text:
            if not port_text.isdigit() or not 0 < int(port_text) < 65536:
                raise LaserUrlError(f"--laser {text!r}: the port must be a number 1-65535, got {port_text!r}")
            port = int(port_text)
        return LaserUrl(t, kind, host=host, port=port, options=opts)
    path = rest[2:] if rest.startswith("//") else rest
    if not path:
        example = "FILE" if kind == "replay" else "/dev/ttyUSB0"
        raise LaserUrlError(f"--laser {text!r}: no {'file' if kind == 'replay' else 'device'}; {kind}:{example}")
    return LaserUrl(t, kind, path=path, options=opts)


def open_laser(url: str | LaserUrl, mount: LaserMount | None = None) -> LaserSource:
    """A source for ``url`` (not started: call ``start()``); LaserUrlError for a bad URL."""
    u = url if isinstance(url, LaserUrl) else parse_laser_url(url)
    module, cls, _, _ = LASER_KINDS[u.kind]
    mod = importlib.import_module(f"{__package__}.{module}")
    source: LaserSource = getattr(mod, cls)(u, mount or LaserMount())
    return source
