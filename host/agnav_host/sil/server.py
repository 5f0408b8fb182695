"""Serve the SIL firmware's MAVLink byte stream to a ground station, as ArduPilot SITL does.

``serve()`` runs a scenario's world + firmware in real time (times ``speedup``) and bridges the
radio link to a TCP client on a loopback address (default tcp:127.0.0.1:5760; one client at a
time, a new connection replaces the old one) and/or a pseudo-terminal. What the client sends goes
through the uplink model to the firmware's UART; what the firmware sends goes through the
downlink model to the client. MAVProxy: ``mavproxy.py --master tcp:127.0.0.1:5760``.

The firmware's link-loss failsafe needs a host heartbeat (or setpoint / manual control) at least
every LINK_TIMEOUT_MS (500 ms); ground stations send HEARTBEAT at 1 Hz by default, so raise the
station's heartbeat rate (MAVProxy: ``set heartbeat 4``) or store a longer timeout with
``--param LINK_TIMEOUT_MS=2000``.
"""

from __future__ import annotations

import errno
import ipaddress
import os
import select
import signal
import socket
import sys
import threading
import time
from dataclasses import dataclass
from typing import Callable

from ..sim.scenario import Scenario
from ..types import Pose2D
from .link import Tlog
from .session import SilConfig, SilSession

__all__ = ["ServeOptions", "ServeResult", "serve", "parse_endpoint"]


def parse_endpoint(text: str) -> tuple[str, int]:
    """``[tcp:]HOST:PORT`` -> (host, port); the host must be an IPv4 loopback address (``localhost`` is
    127.0.0.1), the port 0..65535 (0: any free one). ValueError names what is wrong."""
    t = text[4:] if text.startswith("tcp:") else text
    host, _, port = t.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if host == "localhost":
        host = "127.0.0.1"
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        raise ValueError(f"--tcp {text!r}: the SIL serves on loopback addresses only (e.g. tcp:127.0.0.1:5760), "
                         f"got {host!r}") from None
    if addr.version != 4:
        raise ValueError(f"--tcp {text!r}: IPv6 is not served; use tcp:127.0.0.1:PORT")
    if not addr.is_loopback:
        raise ValueError(f"--tcp {text!r}: the SIL serves on loopback addresses only, got {host!r}")
    try:
        n = int(port)
    except ValueError:
        n = -1
    if not 0 <= n <= 65535:
        raise ValueError(f"--tcp {text!r}: the port must be a number 0-65535, got {port!r}")
    return host, n


@dataclass(frozen=True)
class ServeResult:
    """Where a served run stopped: simulated time since boot (s) and the robot's true pose."""

    t_s: float
    pose: Pose2D


@dataclass
class ServeOptions:
    tcp: tuple[str, int] | None = ("127.0.0.1", 5760)
    pty: bool = False
    speedup: float = 1.0
    duration_s: float | None = None  # None: until interrupted
    seed: int = 0
    tlog_path: str | None = None
    config: SilConfig | None = None


def serve(sc: Scenario, opt: ServeOptions, log: Callable[[str], None] = lambda m: print(m, file=sys.stderr),
          ready: Callable[[tuple[str, int] | None, str | None], None] | None = None) -> ServeResult:
    """Run until ``duration_s`` of simulated time, Ctrl-C or SIGTERM (the tlog is then complete up to
    the stop); returns where it stopped. The listening socket and the pty are made before the firmware
    is loaded, and everything is released on every way out."""
    if not opt.speedup > 0:
        raise ValueError("speedup must be > 0")
    lsock = None
    bound = None
    if opt.tcp is not None:
        lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            lsock.bind(opt.tcp)
        except (OSError, OverflowError) as e:
            lsock.close()
            en = getattr(e, "errno", None)
            raise OSError(en, f"cannot listen on tcp:{opt.tcp[0]}:{opt.tcp[1]}: {getattr(e, 'strerror', None) or e}"
                          + (" (another agnav sil or ground station is using it; pick another --tcp port)"
                             if en == errno.EADDRINUSE else "")) from None
        lsock.listen(1)
        lsock.setblocking(False)
        bound = lsock.getsockname()
    master = slave = None
    slave_name = None
    if opt.pty:
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        slave_name = os.ttyname(slave)
    main = threading.current_thread() is threading.main_thread()
    old_term = signal.signal(signal.SIGTERM, _raise_interrupt) if main else None
    s = None
    tlog = None
    client: socket.socket | None = None
    try:
        s = SilSession(sc, opt.seed, opt.config)
        tlog = Tlog(opt.tlog_path) if opt.tlog_path else None
        if tlog is not None:
            s.up._tlog = s.down._tlog = tlog
        s.provision()
        if bound is not None:
            log(f"agnav sil: {sc.name}: MAVLink on tcp:{bound[0]}:{bound[1]} (speedup {opt.speedup:g})")
        if slave_name is not None:
            log(f"agnav sil: MAVLink on pty {slave_name}")
        if ready is not None:
            ready(bound, slave_name)

        def drop_client(why: str) -> None:
            nonlocal client
            if client is not None:
                client.close()
                client = None
                log(f"agnav sil: client {why}")
            s.up.reset_framer()  # a frame the client left half-sent must not swallow the next one's start

        def to_clients(t_us: int, data: bytes) -> None:
            if client is not None:
                try:
                    client.sendall(data)
                except OSError:
                    drop_client("gone (send failed)")
            if master is not None:
                try:
                    os.write(master, data)
                except (BlockingIOError, OSError):
                    pass  # nobody reading the pty: the bytes are lost, like on a radio

        s.on_downlink = to_clients
        wall0 = time.monotonic()
        t0 = s.t_us
        end_us = None if opt.duration_s is None else t0 + int(opt.duration_s * 1e6)
        try:
            while end_us is None or s.t_us < end_us:
                if lsock is not None:
                    try:
                        conn, addr = lsock.accept()
                        conn.setblocking(False)
                        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                        if client is not None:
                            drop_client("replaced by a new connection")
                        s.up.reset_framer()
                        client = conn
                        log(f"agnav sil: client {addr[0]}:{addr[1]} connected")
                    except BlockingIOError:
                        pass
                rd = [x for x in (client, master) if x is not None]
                if rd:
                    ready_r, _, _ = select.select(rd, [], [], 0)
                    for x in ready_r:
                        try:
                            data = x.recv(4096) if isinstance(x, socket.socket) else os.read(x, 4096)
                        except (BlockingIOError, InterruptedError):
                            continue
                        except OSError as e:
                            if x is client:
                                drop_client(f"disconnected ({e.strerror or e})")
                            continue
                        if x is client and data == b"":
                            drop_client("disconnected")
                        elif data:
                            s.up.send(s.t_us, data)
                s.step()
                lag = (s.t_us - t0) * 1e-6 / opt.speedup - (time.monotonic() - wall0)
                if lag > 0:
                    time.sleep(lag)
        except KeyboardInterrupt:
            pass
        return ServeResult(s.t_s, s.pose)
    finally:
        if main:  # a second Ctrl-C (or SIGTERM) while cleaning up must not cut the cleanup short
            old_int = signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if client is not None:
            client.close()
        if lsock is not None:
            lsock.close()
        for fd in (master, slave):
            if fd is not None:
                os.close(fd)
        if tlog is not None:
            tlog.close()
        if s is not None:
            s.close()
        if main:
            signal.signal(signal.SIGINT, old_int)
            signal.signal(signal.SIGTERM, old_term)


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM (systemd, docker stop, kill) ends a served run like Ctrl-C
