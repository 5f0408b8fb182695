"""Scanner emulators: the SIL's simulated laser served over the device's own wire protocol.

An emulator is fed one scan at a time by whoever owns the world (:meth:`ScannerEmulator.publish`, with the
scan's ranges in the sensor frame and the simulated time it was measured at, which is the device's clock) and
answers clients exactly as the device does: polled requests get the newest scan, subscribed clients get every
published scan. Where it listens (:meth:`ScannerEmulator.start`) is the device's own port on a loopback address,
or a pseudo-terminal for serial devices.

:class:`Transport` holds the serving machinery every emulator shares: a TCP listener on loopback that takes
several clients at once (each in its own thread), or one pty; a per-client handler reads requests and writes
replies through a :class:`Stream`.
"""

from __future__ import annotations

import math
import os
import select
import socket
import threading
import tty
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

__all__ = ["ScanGeometry", "ScannerEmulator", "Stream", "Transport", "PublishedScan", "ScanBoard"]


@dataclass(frozen=True)
class ScanGeometry:
    """What the emulated device scans: beam 0 at ``angle_min_rad`` (sensor frame, 0 = forward, CCW positive),
    ``n_beams`` beams ``angle_increment_rad`` apart, valid ranges ``range_min_m``-``range_max_m``, ``scan_hz``."""

    angle_min_rad: float
    angle_increment_rad: float
    n_beams: int
    range_min_m: float = 0.05
    range_max_m: float = 10.0
    scan_hz: float = 15.0

    def __post_init__(self) -> None:
        if self.n_beams < 2 or not self.angle_increment_rad > 0 or not self.scan_hz > 0:
            raise ValueError(f"scan geometry: need >= 2 beams, a positive step and rate, got {self}")
        if not 0 <= self.range_min_m < self.range_max_m or not math.isfinite(self.range_max_m):
            raise ValueError(f"scan geometry: need 0 <= range_min_m < range_max_m < inf, got {self}")

    @property
    def angle_max_rad(self) -> float:
        return self.angle_min_rad + (self.n_beams - 1) * self.angle_increment_rad


@dataclass(frozen=True)
class PublishedScan:
    seq: int  # 0, 1, 2, ... in publishing order
    t_s: float  # simulated time of the scan (the device's clock), s
    ranges_m: np.ndarray  # (n_beams,), NaN / inf = no return


class ScanBoard:
    """The newest published scan and a condition to wait for the next one (shared by an emulator's clients)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._scan: PublishedScan | None = None
        self._closed = False

    def publish(self, ranges_m: np.ndarray, t_s: float) -> None:
        with self._cond:
            seq = 0 if self._scan is None else self._scan.seq + 1
            self._scan = PublishedScan(seq, float(t_s), np.asarray(ranges_m, dtype=float).copy())
            self._cond.notify_all()

    def newest(self) -> PublishedScan | None:
        with self._cond:
            return self._scan

    def next_after(self, seq: int, timeout_s: float) -> PublishedScan | None:
        """The first scan with a sequence number above ``seq`` (None on time-out or close)."""
        with self._cond:
            self._cond.wait_for(lambda: self._closed or (self._scan is not None and self._scan.seq > seq), timeout_s)
            if self._closed or self._scan is None or self._scan.seq <= seq:
                return None
            return self._scan

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed


class ScannerEmulator(Protocol):
    kind: str

    def start(self) -> str:
        """Begin serving; returns where: ``tcp:127.0.0.1:PORT`` (one per port for multi-port devices, joined
        with ``,``) or the pty's path."""
        ...

    def publish(self, ranges_m: np.ndarray, t_s: float) -> None:
        """A new scan, measured at simulated time ``t_s`` (s), in the sensor frame of the geometry."""
        ...

    def close(self) -> None: ...


class Stream:
    """One client connection: blocking reads with a time-out, whole writes; ``closed`` once the peer left."""

    def __init__(self, read: Callable[[int], bytes], write: Callable[[bytes], None], wait: Callable[[float], bool]) -> None:
        self._read, self._write, self._wait = read, write, wait
        self.closed = False

    def read(self, n: int = 4096, timeout_s: float = 0.1) -> bytes:
        """Up to ``n`` bytes, b"" on time-out; sets ``closed`` (and returns b"") when the peer has gone."""
        if self.closed:
            return b""
        try:
            if not self._wait(timeout_s):
                return b""
            data = self._read(n)
        except OSError:
            data = b""
        if not data:
            self.closed = True
        return data

    def write(self, data: bytes) -> None:
        if self.closed:
            return
        try:
            self._write(data)
        except OSError:
            self.closed = True


Handler = Callable[[Stream, threading.Event], None]


class Transport:
    """Serve ``handler(stream, stop)`` to TCP clients on a loopback port (each client a thread) or on one pty."""

    def __init__(self, handler: Handler) -> None:
        self.handler = handler
        self.stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._socks: list[socket.socket] = []
        self._fds: list[int] = []
        self.pty_path = ""

    def listen_tcp(self, host: str = "127.0.0.1", port: int = 0) -> int:
        """Listen on ``host:port`` (0: any free port); returns the port. OSError when it is taken."""
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        srv.bind((host, port))
        srv.listen(4)
        srv.settimeout(0.2)
        self._socks.append(srv)
        self._spawn(self._accept_loop, srv)
        return int(srv.getsockname()[1])

    def open_pty(self) -> str:
        """Open a pseudo-terminal in raw mode and serve it; returns the path a driver opens (``/dev/pts/N``)."""
        master, slave = os.openpty()
        tty.setraw(slave)
        self._fds += [master, slave]
        self.pty_path = os.ttyname(slave)

        def read(n: int) -> bytes:
            return os.read(master, n)  # the slave stays open here, so a client closing the port is no EOF

        def wait(t: float) -> bool:
            return bool(select.select([master], [], [], t)[0])

        def write(data: bytes) -> None:
            view = memoryview(data)
            while view:
                select.select([], [master], [], 1.0)
                n = os.write(master, view)
                view = view[n:]

        self._spawn(self._serve_pty, Stream(read, write, wait))
        return self.pty_path

    def _serve_pty(self, stream: Stream) -> None:
        self.handler(stream, self.stop)  # returns when stopped: a pty outlives the clients that open it

    def _accept_loop(self, srv: socket.socket) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = srv.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

            def wait(t: float, c: socket.socket = conn) -> bool:
                return bool(select.select([c], [], [], t)[0])

            stream = Stream(conn.recv, conn.sendall, wait)
            self._spawn(self._serve_client, conn, stream)

    def _serve_client(self, conn: socket.socket, stream: Stream) -> None:
        try:
            self.handler(stream, self.stop)
        finally:
            conn.close()

    def _spawn(self, fn: Callable[..., None], *args: object) -> None:
        t = threading.Thread(target=fn, args=args, daemon=True)
        t.start()
        self._threads.append(t)

    def close(self) -> None:
        self.stop.set()
        for s in self._socks:
            s.close()
        for t in self._threads:
            t.join(timeout=2.0)
        for fd in self._fds:
            try:
                os.close(fd)
            except OSError:
                pass
        self._socks, self._fds, self._threads = [], [], []
