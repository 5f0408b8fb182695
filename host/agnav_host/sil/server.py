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
import socket
import sys
import time
from dataclasses import dataclass
from typing import Callable

from ..sim.scenario import Scenario
from .link import Tlog
from .session import SilConfig, SilSession

__all__ = ["ServeOptions", "serve", "parse_endpoint"]


def parse_endpoint(text: str) -> tuple[str, int]:
    """``[tcp:]HOST:PORT`` -> (host, port); the host must be a loopback address."""
    t = text[4:] if text.startswith("tcp:") else text
    host, _, port = t.rpartition(":")
    host = host or "127.0.0.1"
    if host == "localhost":
        host = "127.0.0.1"
    try:
        ok = ipaddress.ip_address(host).is_loopback
    except ValueError:
        ok = False
    if not ok:
        raise ValueError(f"SIL serves on loopback addresses only, got {host!r}")
    return host, int(port)


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
          ready: Callable[[tuple[str, int] | None, str | None], None] | None = None) -> SilSession:
    """Run until ``duration_s`` of simulated time (or KeyboardInterrupt); returns the session."""
    if not opt.speedup > 0:
        raise ValueError("speedup must be > 0")
    s = SilSession(sc, opt.seed, opt.config)
    tlog = Tlog(opt.tlog_path) if opt.tlog_path else None
    if tlog is not None:
        s.up._tlog = s.down._tlog = tlog
    s.provision()
    lsock = None
    bound = None
    if opt.tcp is not None:
        lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            lsock.bind(opt.tcp)
        except OSError as e:
            lsock.close()
            raise OSError(e.errno, f"cannot listen on tcp:{opt.tcp[0]}:{opt.tcp[1]}: {e.strerror}"
                          + (" (another agnav sil or ground station is using it; pick another --tcp port)"
                             if e.errno == errno.EADDRINUSE else "")) from None
        lsock.listen(1)
        lsock.setblocking(False)
        bound = lsock.getsockname()
        log(f"agnav sil: {sc.name}: MAVLink on tcp:{bound[0]}:{bound[1]} (speedup {opt.speedup:g})")
    master = None
    slave_name = None
    if opt.pty:
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        slave_name = os.ttyname(slave)
        log(f"agnav sil: MAVLink on pty {slave_name}")
    if ready is not None:
        ready(bound, slave_name)
    client: socket.socket | None = None

    def to_clients(t_us: int, data: bytes) -> None:
        nonlocal client
        if client is not None:
            try:
                client.sendall(data)
            except OSError:
                client.close()
                client = None
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
                        client.close()
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
                    except (BlockingIOError, OSError):
                        data = b""
                        if x is client:
                            client = None
                    if x is client and data == b"":
                        client.close()
                        client = None
                        log("agnav sil: client disconnected")
                    elif data:
                        s.up.send(s.t_us, data)
            s.step()
            lag = (s.t_us - t0) * 1e-6 / opt.speedup - (time.monotonic() - wall0)
            if lag > 0:
                time.sleep(lag)
    except KeyboardInterrupt:
        pass
    finally:
        if client is not None:
            client.close()
        if lsock is not None:
            lsock.close()
        if master is not None:
            os.close(master)
        if tlog is not None:
            tlog.close()
        s.close()
    return s
