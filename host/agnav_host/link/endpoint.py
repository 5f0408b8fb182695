"""The host's MAVLink endpoint: one session with one robot over serial/USB/XBee, TCP or UDP.

    ep = Endpoint("serial:/dev/ttyUSB0:57600", tlog="out/run.tlog", key=load_key())
    ep.start(wait_heartbeat_s=5)
    ... ep.state.pose, ep.stats.rx_rate_bytes_s, ep.send(msg), ep.request(...)
    ep.close()

Transports are pymavlink ``mavutil`` connections (device strings as in MAVProxy):

    serial:/dev/ttyUSB0:57600   /dev/ttyUSB0 (baud from ``baud``)   USB serial or an XBee in
    /dev/ttyUSB0,57600  COM3,57600                                  transparent mode (it is just a
                                serial port); PATH,BAUD is MAVProxy's and Mission Planner's form
    tcp:HOST:PORT               connect (the SIL serves 127.0.0.1:5760)
    udp:HOST:PORT  udpin:...    listen; udpout:HOST:PORT sends to a peer

A session outlives its transport: one I/O thread reads, parses, sends the 1 Hz GCS heartbeat and,
when the transport fails (cable unplugged, TCP peer closed), reopens it every
``reconnect_delay_s`` while keeping the codec (sequence numbers, signing timestamp), the
:class:`RobotState`, the :class:`LinkStats` counters and the tlog. Silence longer than
``link_timeout_s`` (a radio drop) marks the link down without reopening anything; the first byte
back marks it up again.

Every frame, in and out, is appended to the tlog (8-byte big-endian microsecond timestamp + the
frame, readable by ``mavutil.mavlogfile``). The receive rate is measured over a sliding window and a
warning is raised when it exceeds the telemetry budget (1500 B/s: ~26 % of a 57600-baud link,
which carries 5760 B/s at 10 bits per byte).

Signing (MAVLink 2): with ``key`` set every outgoing frame is signed; incoming unsigned frames are
accepted unless ``require_signed`` (an AgNav firmware holding the key signs all its telemetry, so
``require_signed`` suits it; keys.py tells how the robot gets the key).
"""

from __future__ import annotations

import errno
import ipaddress
import logging
import os
import queue
import select
import socket
import stat
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

from ..protocol import dialect
from .state import LinkStats, RobotState
from .tlog import TlogWriter

__all__ = ["Endpoint", "LinkDown", "LinkTimeout", "parse_device", "RateMeter", "Subscription",
           "TELEMETRY_BUDGET_BYTES_S", "DeviceSpec"]

log = logging.getLogger(__name__)

#: Default receive budget at 57600 baud (5760 B/s line rate): leaves room for the host's own
#: traffic, PARAM and calibration exchanges and radio retries.
TELEMETRY_BUDGET_BYTES_S = 1500.0
GCS_SYSID = 255
GCS_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER
#: Before the first open, a missing device file (ENOENT) or a refused connection to this machine is
#: retried for this long only (a USB board re-enumerating after a reset or a flash, a SIL that is
#: still starting), then reported; see :meth:`Endpoint.start`.
OPEN_GRACE_S = 1.0


class LinkDown(ConnectionError):
    """The transport failed (EOF, reset, unplugged); the endpoint reopens it."""


class LinkTimeout(TimeoutError):
    """No answer to a request within its timeout and retries."""


def _os_error_text(e: BaseException) -> str:
    """``[Errno N] text`` for an OS error (pyserial wraps it in a longer sentence), else str(e)."""
    if isinstance(e, socket.gaierror):
        return f"[Errno {e.errno}] {e.strerror}" if e.strerror else str(e)
    en = getattr(e, "errno", None)
    if isinstance(en, int) and en > 0:
        return f"[Errno {en}] {os.strerror(en)}"
    return str(e) or type(e).__name__


def _is_loopback(host: str) -> bool:
    if host.lower() in ("localhost", "localhost.localdomain", "ip6-localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _open_failure(spec: "DeviceSpec", e: BaseException) -> tuple[str, str]:
    """How to treat a failure to open ``spec`` before the first success: (policy, message).

    policy ``fatal``: waiting will not help (permission denied, unknown host, not a serial port, a
    bad address): give up at once. ``grace``: the thing may appear in a moment (a device file that
    does not exist yet, a refused connection to this machine): retry for OPEN_GRACE_S. ``retry``:
    anything else (no route, timeouts, a remote port not open yet, busy): retry until the open
    timeout, then report this error."""
    text = _os_error_text(e)
    en = getattr(e, "errno", None)
    host = spec.address.split(":", 1)[1].rpartition(":")[0] if spec.kind != "serial" else ""
    if isinstance(e, socket.gaierror):
        return "fatal", f"cannot resolve host {host!r}: {text}"
    if en in (errno.EACCES, errno.EPERM):
        hint = (" (add the user to the dialout group: sudo usermod -aG dialout $USER, then log out and in)"
                if spec.kind == "serial" else "")
        return "fatal", text + hint
    if en in (errno.ENOTTY, errno.EISDIR, errno.ENOTDIR, errno.ENXIO, errno.ENODEV) or \
            "Inappropriate ioctl" in str(e):
        return "fatal", f"{text} (not a serial port?)" if spec.kind == "serial" else text
    if en in (errno.EADDRINUSE, errno.EADDRNOTAVAIL) or isinstance(e, ValueError):
        return "fatal", text
    if en == errno.ENOENT:
        return "grace", text
    if en == errno.ECONNREFUSED:
        if _is_loopback(host):
            return "grace", f"{text} (nothing listens on that port: is the robot bridge or `agnav sil` running?)"
        return "retry", text
    return "retry", text


@dataclass(frozen=True)
class DeviceSpec:
    kind: str  # serial | tcp | udp | udpin | udpout | tcpin
    address: str  # what mavutil gets
    baud: int

    def __str__(self) -> str:
        return f"serial:{self.address}:{self.baud}" if self.kind == "serial" else self.address


def parse_device(device: str, baud: int = 57600) -> DeviceSpec:
    """Parse a device string (see module docstring); raises ValueError on nonsense: a port outside
    1..65535, a missing host, a baud that is not a whole number > 0 (``serial:PATH:BAUD``; a path
    that itself holds ':' takes an explicit baud, e.g. ``serial:/dev/serial/by-path/pci-0:1:1.0:57600``)."""
    d = device.strip()
    if not d:
        raise ValueError("empty device")
    for pfx in ("tcpin:", "tcp:", "udpin:", "udpout:", "udpbcast:", "udp:"):
        if d.startswith(pfx):
            rest = d[len(pfx):]
            host, sep, port = rest.rpartition(":")
            if not sep or not port.strip().isdigit():
                raise ValueError(f"{device!r}: expected {pfx}HOST:PORT, e.g. {pfx}127.0.0.1:5760")
            if not 0 < int(port) < 65536:
                raise ValueError(f"{device!r}: port {int(port)} out of range: the port must be 1..65535")
            if ":" in host:
                raise ValueError(f"{device!r}: IPv6 addresses are not supported: use an IPv4 address or a host name")
            if not host and pfx in ("tcp:", "udpout:", "udpbcast:"):
                raise ValueError(f"{device!r}: no host: expected {pfx}HOST:PORT, e.g. {pfx}127.0.0.1:5760")
            return DeviceSpec(pfx[:-1], d, baud)
    path, comma, b = d.rpartition(",")
    if comma and not d.startswith(("tcp", "udp")):  # MAVProxy's PATH,BAUD (serial:PATH,BAUD too)
        path = path[len("serial:"):] if path.startswith("serial:") else path
        return DeviceSpec("serial", _serial_path(path.strip(), device), _baud(b.strip(), device))
    if d.startswith("serial:"):
        rest = d[len("serial:"):]
        path, sep, b = rest.rpartition(":")
        if sep and "/" not in b and "\\" not in b and not Path(rest).exists():
            # the part after the last ':' is the baud (unless the whole thing is an existing path)
            return DeviceSpec("serial", _serial_path(path, device), _baud(b, device))
        return DeviceSpec("serial", _serial_path(rest, device), _baud(baud, device))
    if d.startswith(("/", "COM", "com")) or "tty" in d:
        return DeviceSpec("serial", d, _baud(baud, device))
    raise ValueError(f"unknown device {device!r}: use serial:/dev/ttyUSB0:57600, tcp:HOST:PORT or udp:HOST:PORT")


def _serial_path(path: str, device: str) -> str:
    if not path.strip():
        raise ValueError(f"{device!r}: no serial device path: expected serial:/dev/ttyUSB0:57600")
    return path


def _baud(b: object, device: str) -> int:
    """A baud rate: a whole number > 0, else ValueError naming the device string."""
    text = str(b).strip()
    try:
        v = int(text)
    except ValueError:
        raise ValueError(f"{device!r}: baud {text!r} is not a whole number: expected serial:PATH:BAUD, e.g. "
                         "serial:/dev/ttyUSB0:57600 (a path containing ':' needs the baud at the end)") from None
    if v <= 0:
        raise ValueError(f"{device!r}: baud {v} must be > 0 (e.g. 57600)")
    return v


class RateMeter:
    """Bytes per second over a sliding window (``add`` from one thread, ``rate`` from any)."""

    def __init__(self, window_s: float = 5.0) -> None:
        self.window_s = window_s
        self._q: deque[tuple[float, int]] = deque()
        self._sum = 0
        self._t0: float | None = None
        self._lock = threading.Lock()

    def add(self, t: float, n: int) -> None:
        with self._lock:
            if self._t0 is None:
                self._t0 = t
            self._q.append((t, n))
            self._sum += n
            self._trim(t)

    def _trim(self, t: float) -> None:
        while self._q and self._q[0][0] < t - self.window_s:
            self._sum -= self._q.popleft()[1]

    def rate(self, t: float) -> float:
        with self._lock:
            self._trim(t)
            if self._t0 is None:
                return 0.0
            span = min(self.window_s, max(t - self._t0, 1e-3))
            return self._sum / span

    def full(self, t: float) -> bool:
        """True once a whole window has been observed."""
        return self._t0 is not None and t - self._t0 >= self.window_s


_CLOSED = object()  # put into every subscription's queue when the endpoint closes


class Subscription:
    """Queue of received messages matching types and an optional predicate."""

    def __init__(self, ep: "Endpoint", types: Iterable[str] | None, predicate: Callable[[Any], bool] | None) -> None:
        self._ep = ep
        self.types = None if types is None else frozenset(types)
        self.predicate = predicate
        self.q: queue.Queue[Any] = queue.Queue()

    def wants(self, msg: Any) -> bool:
        if self.types is not None and msg.get_type() not in self.types:
            return False
        return self.predicate is None or bool(self.predicate(msg))

    def get(self, timeout: float) -> Any:
        """Next matching message, or None after ``timeout`` seconds or at once when the endpoint is closed."""
        try:
            m = self.q.get(timeout=max(timeout, 0.0))
        except queue.Empty:
            return None
        if m is _CLOSED:
            self.q.put(m)  # every later wait ends at once too
            return None
        return m

    def drain(self) -> list[Any]:
        out: list[Any] = []
        while True:
            try:
                m = self.q.get_nowait()
            except queue.Empty:
                return out
            if m is _CLOSED:
                self.q.put(m)
                return out
            out.append(m)

    def close(self) -> None:
        self._ep._unsubscribe(self)

    def __enter__(self) -> "Subscription":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Endpoint:
    """One MAVLink session with a robot (see the module docstring)."""

    def __init__(self, device: str, baud: int = 57600, *, source_system: int = GCS_SYSID,
                 source_component: int = GCS_COMPID, target_system: int = 0, target_component: int = 0,
                 tlog: str | Path | None = None, key: bytes | None = None, require_signed: bool = False,
                 heartbeat_hz: float = 1.0, link_timeout_s: float = 3.0, reconnect_delay_s: float = 0.5,
                 budget_bytes_s: float = TELEMETRY_BUDGET_BYTES_S, budget_window_s: float = 5.0,
                 budget_warn_every_s: float = 60.0, on_event: Callable[[str], None] | None = None) -> None:
        self.spec = parse_device(device, baud)
        self.d = dialect()
        self.mav = self.d.MAVLink(None, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True
        self._fixed_target = (target_system, target_component)
        self._target = (target_system, target_component)
        self.heartbeat_hz = heartbeat_hz
        self.link_timeout_s = link_timeout_s
        self.reconnect_delay_s = reconnect_delay_s
        self.budget_bytes_s = budget_bytes_s
        self.meter = RateMeter(budget_window_s)
        self.budget_warn_every_s = budget_warn_every_s
        self.state = RobotState()
        self.stats = LinkStats()
        self.events: deque[tuple[float, str]] = deque(maxlen=500)
        self.on_event = on_event
        self.tlog: TlogWriter | None = TlogWriter(tlog) if tlog else None
        self._tlog_error_reported = False
        self._conn: Any = None
        self._broken = False
        self._send_lock = threading.Lock()
        self._subs: list[Subscription] = []
        self._subs_lock = threading.Lock()
        self._listeners: list[Callable[[Any], None]] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_rx: float | None = None
        self._last_hb = -1e9
        self._last_budget_check = 0.0
        self._last_budget_warn = -1e9
        self._next_open = 0.0
        self._last_seq: dict[tuple[int, int], int] = {}
        self._opened_once = threading.Event()
        self._open_done = threading.Event()  # first open succeeded, or gave up (_open_error)
        self._open_error: tuple[BaseException, str] | None = None  # last failure before the first open
        self.require_signed = require_signed
        if key is not None:
            self.set_signing_key(key)

    # ---- configuration -------------------------------------------------------------------------
    def set_signing_key(self, key: bytes | None, link_id: int = 1) -> None:
        """Sign outgoing frames with ``key`` (32 bytes); None disables signing."""
        s = self.mav.signing
        if key is None:
            s.secret_key, s.sign_outgoing, s.allow_unsigned_callback, s.link_id = None, False, None, 0
            return
        if len(key) != 32:
            raise ValueError("MAVLink signing key must be 32 bytes")
        s.secret_key = bytes(key)
        s.sign_outgoing = True
        s.link_id = link_id
        # 10 us units since 2015-01-01, as the MAVLink spec asks
        s.timestamp = max(s.timestamp, int((time.time() - 1420070400) * 100_000))
        s.allow_unsigned_callback = None if self.require_signed else (lambda mav, msgid: True)

    @property
    def signing(self) -> bool:
        return bool(self.mav.signing.sign_outgoing)

    @property
    def target_system(self) -> int:
        return self._target[0]

    @property
    def target_component(self) -> int:
        return self._target[1]

    def add_listener(self, fn: Callable[[Any], None]) -> None:
        """Call ``fn(msg)`` from the I/O thread for every received message (keep it short)."""
        self._listeners.append(fn)

    # ---- life cycle ------------------------------------------------------------------------------
    def start(self, wait_heartbeat_s: float | None = None, open_timeout_s: float | None = None) -> "Endpoint":
        """Start the I/O thread; wait until the transport opened once and optionally for the robot's
        first heartbeat (LinkTimeout after ``wait_heartbeat_s``).

        Opening raises ConnectionError naming the OS error (``could not open serial:/dev/ttyNOPE:57600:
        [Errno 2] No such file or directory``):

        * at once when waiting cannot help: permission denied (with the dialout hint), an unknown
          host, not a serial port, an address that cannot be bound;
        * after OPEN_GRACE_S (1 s) of retries for a device file that does not exist or a connection
          refused by this machine: a USB board re-enumerates within about that after a reset or a
          flash, and a SIL just started in the background begins listening;
        * otherwise (no route, timeouts, a remote port not open yet) after ``open_timeout_s`` of
          retries, with the last error. ``open_timeout_s`` defaults to ``wait_heartbeat_s`` (at
          least 1 s) when that is given, else 10 s, so one ``--wait`` bounds the wait to open.

        After the first open the session never gives up: a transport that fails later (cable
        pulled) is reopened every ``reconnect_delay_s``."""
        if open_timeout_s is None:
            open_timeout_s = 10.0 if wait_heartbeat_s is None else max(1.0, float(wait_heartbeat_s))
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="agnav-link", daemon=True)
            self._thread.start()
        self._open_done.wait(open_timeout_s)
        if not self._opened_once.is_set():
            failure = self._open_error
            gave_up = self._open_done.is_set()  # the I/O thread stopped trying (else: timed out)
            self.close()
            if failure is None:
                raise ConnectionError(f"could not open {self.spec} within {open_timeout_s:g} s "
                                      "(the open/connect call did not return)")
            err, text = failure
            if gave_up:
                raise ConnectionError(f"could not open {self.spec}: {text}") from err
            raise ConnectionError(f"could not open {self.spec} within {open_timeout_s:g} s: {text}") from err
        if wait_heartbeat_s is not None:
            self.wait_heartbeat(wait_heartbeat_s)
        return self

    def close(self) -> None:
        self._stop.set()
        with self._subs_lock:  # wake whoever waits for an answer: none will come now
            for sub in self._subs:
                sub.q.put(_CLOSED)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._close_conn()
        if self.tlog is not None:
            self.tlog.close()

    def __enter__(self) -> "Endpoint":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _event(self, text: str, level: int = logging.INFO) -> None:
        self.events.append((time.monotonic(), text))
        # with a callback the event is shown there: logged at DEBUG only, or Python's last-resort
        # handler prints every warning a second time on a console without logging set up
        log.log(level if self.on_event is None else logging.DEBUG, "%s: %s", self.spec, text)
        if self.on_event is not None:
            try:
                self.on_event(text)
            except Exception:  # a UI callback must not kill the link
                log.exception("on_event callback failed")

    # ---- transport ---------------------------------------------------------------------------------
    def _open_conn(self) -> None:
        from pymavlink import mavutil

        sp = self.spec
        if sp.kind == "serial":
            try:
                mode = os.stat(sp.address).st_mode
            except OSError:
                mode = None  # missing: pymavlink's open reports it (and a USB board may appear in a moment)
            if mode is not None and not stat.S_ISCHR(mode):
                # pymavlink would take a regular file for a log to read and fail on the first write
                what = "a directory" if stat.S_ISDIR(mode) else "a regular file" if stat.S_ISREG(mode) else "not a device"
                raise OSError(errno.ENOTTY, f"{sp.address} is not a serial device ({what})")
            conn = mavutil.mavlink_connection(sp.address, baud=sp.baud, autoreconnect=False)
        elif sp.kind == "tcp":
            conn = mavutil.mavlink_connection(sp.address, retries=1, autoreconnect=False)

            def _down(*_a: object) -> None:
                raise LinkDown("TCP peer closed the connection")

            conn.handle_eof = _down
            conn.handle_disconnect = _down
        else:
            conn = mavutil.mavlink_connection(sp.address, input=sp.kind in ("udp", "udpin", "tcpin"))
        # Our codec (AgNav dialect, MAVLink 2) replaces mavutil's; it lives as long as the session.
        conn.mav = self.mav
        self.mav.file = conn
        conn.first_byte = False
        conn.WIRE_PROTOCOL_VERSION = "2.0"
        self._conn = conn
        self._broken = False
        self.stats.transport_open = True

    def _close_conn(self) -> None:
        conn, self._conn = self._conn, None
        self.stats.transport_open = False
        if conn is not None:
            try:
                conn.close()
            except Exception:
                pass

    # ---- I/O thread --------------------------------------------------------------------------------
    def _run(self) -> None:
        first_try: float | None = None
        while not self._stop.is_set():
            now = time.monotonic()
            if now - self._last_budget_check >= 0.5:  # rates, transport open or not
                self._last_budget_check = now
                self._check_rates(now)
            self._check_silence(now)  # every pass: a loss is reported within link_timeout_s + ~0.05 s
            if self._conn is None:
                if now < self._next_open:
                    self._stop.wait(min(0.05, self._next_open - now))
                    continue
                try:
                    self._open_conn()
                except Exception as e:  # device missing, connection refused...
                    self._next_open = now + self.reconnect_delay_s
                    if not self._opened_once.is_set():
                        log.debug("open %s failed: %s", self.spec, e)
                        first_try = now if first_try is None else first_try
                        policy, text = _open_failure(self.spec, e)
                        self._open_error = (e, text)
                        if policy == "fatal" or (policy == "grace" and now - first_try >= OPEN_GRACE_S):
                            self._open_done.set()  # without an open: start() raises; nothing left to do
                            break
                    continue
                if self._opened_once.is_set():
                    self.stats.reconnects += 1
                    self._event(f"transport reopened (reconnect #{self.stats.reconnects})")
                else:
                    self._event("transport open")
                self._opened_once.set()
                self._open_done.set()
                self._last_hb = -1e9  # announce ourselves at once
            try:
                self._service(now)
            except Exception as e:  # LinkDown, OSError, serial.SerialException
                self._event(f"transport failed: {e}", logging.WARNING)
                self._close_conn()
                self._next_open = time.monotonic() + self.reconnect_delay_s
        self._close_conn()

    def _service(self, now: float) -> None:
        if self._broken:
            raise LinkDown("write failed")
        if self.heartbeat_hz > 0 and now - self._last_hb >= 1.0 / self.heartbeat_hz:
            self._last_hb = now
            self.send(self.mav.heartbeat_encode(self.d.MAV_TYPE_GCS, self.d.MAV_AUTOPILOT_INVALID, 0, 0,
                                                self.d.MAV_STATE_ACTIVE))
        conn = self._conn
        if conn is None:
            return
        fd = getattr(conn, "fd", None)
        if fd is not None:
            r, _, _ = select.select([fd], [], [], 0.02)
            if not r:
                return
        data = conn.recv(4096)
        if not data:
            if fd is None:
                time.sleep(0.005)
            return
        if isinstance(data, str):
            data = data.encode("latin-1")
        t = time.monotonic()
        self.stats.rx_bytes += len(data)
        self.meter.add(t, len(data))
        if self._last_rx is None or not self.stats.link_up:
            self.stats.link_up = True
            if self._last_rx is not None:
                self._event("link up again (data flowing)")
        self._last_rx = t
        msgs = self.mav.parse_buffer(data) or []
        for m in msgs:
            self._handle(m, t)

    def _check_rates(self, now: float) -> None:
        rate = self.meter.rate(now)
        self.stats.rx_rate_bytes_s = rate
        if self.meter.full(now):
            self.stats.peak_rx_rate_bytes_s = max(self.stats.peak_rx_rate_bytes_s, rate)
            if rate > self.budget_bytes_s:
                self.stats.budget_windows_over += 1
            if rate > self.budget_bytes_s and now - self._last_budget_warn >= self.budget_warn_every_s:
                self._last_budget_warn = now
                self.stats.budget_warnings += 1
                self._event(f"telemetry over budget: {rate:.0f} B/s received > {self.budget_bytes_s:.0f} B/s",
                            logging.WARNING)
        tl = self.tlog
        if tl is not None and tl.error is not None and not self._tlog_error_reported:
            self._tlog_error_reported = True  # the link goes on; the log keeps what was written before
            self._event(f"telemetry log stopped: {tl.error} ({tl.frames} frames kept)", logging.ERROR)

    def _check_silence(self, now: float) -> None:
        if self.stats.link_up and self._last_rx is not None and now - self._last_rx > self.link_timeout_s:
            self.stats.link_up = False
            self.stats.link_losses += 1
            self._event(f"link lost: nothing received for {now - self._last_rx:.1f} s", logging.WARNING)

    def _handle(self, m: Any, t: float) -> None:
        mtype = m.get_type()
        if mtype == "BAD_DATA":
            self.stats.rx_parse_errors += 1
            return
        self.stats.rx_msgs += 1
        if self.tlog is not None:
            self.tlog.write(m.get_msgbuf())
        src = (m.get_srcSystem(), m.get_srcComponent())
        last = self._last_seq.get(src)
        if last is not None:
            gap = (m.get_seq() - last - 1) % 256
            # a gap of more than half the sequence space is a step back (a duplicate, or the robot
            # rebooted and started again at 0), not 128-255 frames lost
            self.stats.rx_seq_lost += gap if gap < 128 else 0
        self._last_seq[src] = m.get_seq()
        if mtype == "HEARTBEAT" and self._target[0] == 0 and m.type != self.d.MAV_TYPE_GCS:
            self._target = (src[0], self._fixed_target[1] or src[1])
            self._event(f"target is system {src[0]} component {src[1]}")
        self.state.update(m, t, self._target[0] or None)
        with self._subs_lock:
            subs = list(self._subs)
        for s in subs:
            if s.wants(m):
                s.q.put(m)
        for fn in self._listeners:
            try:
                fn(m)
            except Exception:
                log.exception("listener failed on %s", mtype)

    # ---- sending -----------------------------------------------------------------------------------
    def send(self, msg: Any) -> bool:
        """Pack (and sign) ``msg`` with the session codec, log it, write it. False when the
        transport is down (the frame is dropped and counted; nothing is queued for later)."""
        with self._send_lock:
            buf = msg.pack(self.mav)
            self.mav.seq = (self.mav.seq + 1) % 256
            self.mav.total_packets_sent += 1
            self.mav.total_bytes_sent += len(buf)
            conn = self._conn
            if conn is None or self._broken:
                self.stats.tx_dropped += 1
                return False
            try:
                r = conn.write(buf)
            except Exception as e:
                self._broken = True
                self.stats.tx_dropped += 1
                log.debug("write failed: %s", e)
                return False
            if r == -1:  # mavserial reports a dead port this way
                self._broken = True
                self.stats.tx_dropped += 1
                return False
            if self.tlog is not None:  # what went out on the wire: a dropped frame is not logged as sent
                self.tlog.write(buf)
            self.stats.tx_msgs += 1
            self.stats.tx_bytes += len(buf)
            return True

    # ---- receiving -----------------------------------------------------------------------------
    def subscribe(self, types: Iterable[str] | str | None = None,
                  predicate: Callable[[Any], bool] | None = None) -> Subscription:
        if isinstance(types, str):
            types = [types]
        s = Subscription(self, types, predicate)
        with self._subs_lock:
            self._subs.append(s)
        return s

    def _unsubscribe(self, s: Subscription) -> None:
        with self._subs_lock:
            if s in self._subs:
                self._subs.remove(s)

    def wait_message(self, types: Iterable[str] | str | None, predicate: Callable[[Any], bool] | None = None,
                     timeout: float = 1.0) -> Any:
        """Next message (received from now on) matching ``types``/``predicate``, or None."""
        with self.subscribe(types, predicate) as s:
            return s.get(timeout)

    def request(self, make: Callable[[], Any], types: Iterable[str] | str, predicate: Callable[[Any], bool] | None = None,
                timeout: float = 1.0, retries: int = 3, what: str = "request",
                accept: Callable[[Any], bool] | None = None) -> Any:
        """Send ``make()`` and wait for a matching answer, resending up to ``retries`` times.

        ``accept``: a matching answer it refuses may be a late answer to an earlier try (a slow radio), so it
        is waited past; only when the tries are used up is the last such answer returned (the caller tells
        it from an accepted one)."""
        other: Any = None
        with self.subscribe(types, predicate) as s:
            for _ in range(max(1, retries)):
                if self._stop.is_set():
                    raise LinkTimeout(f"{what}: the link to {self.spec} was closed")
                self.send(make())
                end = time.monotonic() + timeout
                while (left := end - time.monotonic()) > 0:
                    m = s.get(left)
                    if m is None:
                        break
                    if accept is None or accept(m):
                        return m
                    other = m
        if other is not None:
            return other
        if self._stop.is_set():
            raise LinkTimeout(f"{what}: the link to {self.spec} was closed")
        raise LinkTimeout(f"{what}: no answer from {self.spec} after {retries} x {timeout:.1f} s")

    def wait_heartbeat(self, timeout: float = 5.0) -> Any:
        """Block until a non-GCS heartbeat arrives (returns it) or raise LinkTimeout."""
        hb = self.wait_message("HEARTBEAT", lambda m: m.type != self.d.MAV_TYPE_GCS, timeout)
        if hb is None:
            raise LinkTimeout(f"no heartbeat from {self.spec} within {timeout:.1f} s")
        return hb
