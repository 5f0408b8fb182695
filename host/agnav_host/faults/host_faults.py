"""Host faults: the serial cable pulled mid-run, corrupt scenario and log files, a full disk while
recording. The host must say what went wrong in one plain line (no traceback) and keep the data it
had before the fault.

The robot on the other end is :class:`~agnav_host.link.fake.FakeRobot` (the firmware's wire
behaviour, over TCP); a serial port is a pseudo-terminal bridged to it, and "unplugging" closes the
pty master, which is what the kernel does to /dev/ttyACM0 when the USB cable goes. A full disk is
a 64 KiB tmpfs where the machine allows mounting one, else a file-size limit (RLIMIT_FSIZE: the
write fails with EFBIG instead of ENOSPC, the same code path).
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import select
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable, Iterator

from ._core import FaultCase, FaultOutcome

__all__ = ["HOST_CASES", "full_disk"]


def _agnav(*args: str, timeout: float = 300.0,
           preexec: Callable[[], None] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "agnav_host.cli", *args], capture_output=True, text=True,
                          timeout=timeout, preexec_fn=preexec)


@contextlib.contextmanager
def full_disk(size_kib: int = 64) -> Iterator[tuple[Path, str]]:
    """A folder on a tiny disk: (path, how) with how = "tmpfs" or "rlimit". With "rlimit" the
    caller must apply :func:`_fsize_limit` to the writing process."""
    d = Path(tempfile.mkdtemp(prefix="agnav-full-"))
    mounted = False
    if os.geteuid() == 0:
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(d)],
                           capture_output=True, text=True)
        mounted = r.returncode == 0
    try:
        yield d, "tmpfs" if mounted else "rlimit"
    finally:
        if mounted:
            subprocess.run(["umount", str(d)], capture_output=True)
        import shutil

        shutil.rmtree(d, ignore_errors=True)


def _fsize_limit(limit_bytes: int) -> Callable[[], None]:
    def apply() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, resource.RLIM_INFINITY))
    return apply


def _clean_error(p: subprocess.CompletedProcess[str]) -> tuple[bool, str]:
    err = p.stderr.strip()
    lines = [ln for ln in err.splitlines() if ln.startswith("agnav")]
    return "Traceback" not in err, (lines[0] if lines else err.splitlines()[-1] if err else "(no message)")


# ---- corrupt scenario files -------------------------------------------------------------------------
_BAD_SCENARIOS = {
    "TOML syntax error": ("[scenario]\nname = \"x\"\n[robot\nmodel = \"diff_drive\"\n", "syntax"),
    "binary garbage": ("\x00\x17\xff garbage \x01\n" * 4, "syntax"),
    "not UTF-8 (Latin-1)": ("[scenario]\nname = \"caf\udce9\"\n", "not UTF-8"),  # \udce9: byte 0xe9 as written
    "NaN start pose": ("[scenario]\nname = \"x\"\n[robot]\nmodel = \"diff_drive\"\n"
                       "start = { x_m = nan, y_m = 0.0, yaw_deg = 0.0 }\n[[goals]]\nx_m = 1.0\ny_m = 0.0\n", "x_m"),
    "unknown robot model": ("[scenario]\nname = \"x\"\n[robot]\nmodel = \"hovercraft\"\n[[goals]]\nx_m = 1.0\ny_m = 0.0\n",
                            "hovercraft"),
    "truncated file": ("[scenario]\nname = \"x\"\n[robot]\nmodel = \"diff_drive\"\nstart = { x_m = 0.0, y_", "syntax"),
}


def _case_corrupt_scenarios() -> FaultOutcome:
    res = []
    ok_all = True
    with tempfile.TemporaryDirectory() as d:
        for label, (text, must) in _BAD_SCENARIOS.items():
            f = Path(d) / "bad.toml"
            f.write_bytes(text.encode("utf-8", "surrogateescape"))
            p = _agnav("sim", str(f), "--out", str(Path(d) / "out"), "--quiet", "--no-rrd", "--no-plot", timeout=120)
            clean, line = _clean_error(p)
            import re

            names_line = re.search(r"\.toml:\d+:", line) is not None
            ok = p.returncode == 2 and clean and names_line and must.lower() in line.lower()
            ok_all &= ok
            res.append(f"{label}: exit {p.returncode}, \"{line[:90]}\"" + ("" if ok else " [unexpected]"))
    return FaultOutcome("; ".join(res), ok_all)


# ---- corrupt telemetry log -------------------------------------------------------------------------
def _sample_tlog(path: Path, seconds: float = 2.0) -> int:
    """Record a short tlog from the fake robot; returns the number of frames written."""
    from ..link.endpoint import Endpoint
    from ..link.fake import FakeRobot

    with FakeRobot() as robot:
        ep = Endpoint(robot.device, tlog=path)
        ep.start(wait_heartbeat_s=5.0)
        time.sleep(seconds)
        ep.close()
        return ep.tlog.frames if ep.tlog else 0


def _case_corrupt_tlog() -> FaultOutcome:
    from ..link.tlog import read_tlog

    with tempfile.TemporaryDirectory() as d:
        good = Path(d) / "good.tlog"
        n = _sample_tlog(good)
        raw = good.read_bytes()
        n_good = sum(1 for _ in read_tlog(good))
        variants = {
            "truncated mid-frame": raw[: len(raw) * 2 // 3 + 5],
            "garbage inserted": raw[: len(raw) // 2] + os.urandom(333) + raw[len(raw) // 2:],
            "bytes flipped": bytes(b ^ 0x5A if i % 97 == 13 else b for i, b in enumerate(raw)),
            "not a tlog": b"id,x_m,y_m\n1,0.5,0.25\n" * 200,  # a CSV given by mistake
            "empty": b"",
        }
        parts = [f"{n} frames recorded, {n_good} read back"]
        ok_all = n_good >= n * 0.95
        for label, data in variants.items():
            f = Path(d) / "bad.tlog"
            f.write_bytes(data)
            p = _agnav("replay", str(f), timeout=120)
            clean, line = _clean_error(p)
            try:
                kept = sum(1 for _ in read_tlog(f))
            except Exception as e:  # reading must not raise either
                kept, clean = -1, False
                line = f"read_tlog raised {type(e).__name__}"
            frac = kept / max(1, n_good)
            expect_frac = {"truncated mid-frame": 0.6, "garbage inserted": 0.95, "bytes flipped": 0.3}.get(label, 0.0)
            want_rc = 2 if label in ("not a tlog", "empty") else 0  # nothing readable: say so
            ok = clean and p.returncode == want_rc and frac >= expect_frac
            ok_all &= ok
            parts.append(f"{label}: exit {p.returncode}, {kept} frames recovered" + ("" if ok else f" [unexpected: {line[:80]}]")
                         + (f" (\"{line[:60]}\")" if want_rc == 2 and ok else ""))
    return FaultOutcome("; ".join(parts), ok_all)


# ---- disk full -----------------------------------------------------------------------------------------
def _case_disk_full_sim() -> FaultOutcome:
    with full_disk(96) as (d, how):
        out = d / "run"
        pre = _fsize_limit(96 * 1024) if how == "rlimit" else None
        # 60 s: the run itself takes 2 s; rerun's own file sink once hung the process at exit here
        p = _agnav("sim", "corridor_obstacles", "--out", str(out), "--quiet", preexec=pre, timeout=60.0)
        clean, line = _clean_error(p)
        summary_ok = False
        try:
            summary_ok = "success" in json.loads((out / "summary.json").read_text())
        except (OSError, ValueError):
            pass
        kept = sorted(f.name for f in out.glob("*") if f.stat().st_size > 0) if out.is_dir() else []
        # every line of the message is agnav's (rerun's logger once wrote its own errors around it), and
        # no truncated recording is left behind as if it were one
        foreign = [ln for ln in p.stderr.splitlines() if ln.strip() and not ln.startswith("agnav")]
        ok = (p.returncode == 1 and clean and summary_ok and "full" in p.stderr + line and not foreign
              and not any(k.endswith(".rrd") for k in kept))
        return FaultOutcome(f"({how}) exit {p.returncode}, \"{line[:80]}\"; kept {', '.join(kept) or 'nothing'}; "
                            f"summary.json {'valid' if summary_ok else 'MISSING'}"
                            + (f"; {len(foreign)} line(s) not from agnav" if foreign else ""), ok)


def _case_disk_full_tlog() -> FaultOutcome:
    from ..link.endpoint import Endpoint
    from ..link.fake import FakeRobot
    from ..link.tlog import read_tlog

    with full_disk(64) as (d, how), FakeRobot() as robot:
        old = resource.getrlimit(resource.RLIMIT_FSIZE)
        old_sig = signal.getsignal(signal.SIGXFSZ)
        if how == "rlimit":
            _fsize_limit(24 * 1024)()
        else:  # fill the disk but ~24 KiB: a few seconds of telemetry
            import shutil

            room = shutil.disk_usage(d).free - 24 * 1024
            if room > 0:
                (d / "filler").write_bytes(b"\0" * room)
        try:
            ep = Endpoint(robot.device, tlog=d / "run.tlog")
            ep.start(wait_heartbeat_s=5.0)
            t_end = time.monotonic() + 15.0
            while time.monotonic() < t_end and (ep.tlog is None or ep.tlog.error is None):
                time.sleep(0.1)
            rx_at_fill = ep.stats.rx_msgs
            time.sleep(1.5)
            rx_after = ep.stats.rx_msgs - rx_at_fill
            events = [e for _, e in ep.events if "telemetry log stopped" in e]
            alive = ep.stats.link_up
            ep.close()
        finally:
            if how == "rlimit":
                resource.setrlimit(resource.RLIMIT_FSIZE, old)
                signal.signal(signal.SIGXFSZ, old_sig)
        tl = ep.tlog
        kept = sum(1 for _ in read_tlog(d / "run.tlog"))
        ok = tl is not None and tl.error is not None and rx_after > 20 and alive and bool(events) and kept > 100
        return FaultOutcome(f"({how}) disk full after {tl.frames if tl else 0} frames: reported once "
                            f"(\"{events[0][:60] if events else 'NO EVENT'}\"); link kept running ({rx_after} msgs "
                            f"in the next 1.5 s); {kept} frames readable in the file", ok)


def _case_disk_full_run() -> FaultOutcome:
    """`agnav run --out` on a full disk while it streams the trajectory, the localisation, the laser log and the
    recording: the run drives to its end, each file left ends on a whole record, a cut one is listed as partial
    with its size, none is empty."""
    import re

    import numpy as np

    from ..lasers.base import LaserMount
    from ..lasers.log import LaserLogWriter, laser_log_info
    from ..link.fake import FakeRobot
    from ..types import LaserScan

    with tempfile.TemporaryDirectory(prefix="agnav-scans-") as sd:
        log = Path(sd) / "scans.alog"
        rng = np.random.default_rng(0)
        with LaserLogWriter(log) as w:  # open ground, a wall 8 m off, 15 scans a second
            first = LaserScan(-1.0, 0.01, 8.0 + 0.01 * rng.standard_normal(201), 10.0, 0.0)
            w.declare(0, "tim5xx://fault", "tim5xx", "TiM561", LaserMount(0.2), first, "device", 0.0)
            for k in range(60):
                w.write(0, LaserScan(-1.0, 0.01, 8.0 + 0.01 * rng.standard_normal(201), 10.0, k / 15.0), k / 15.0, None)
        with full_disk(64) as (d, how), FakeRobot() as robot:
            out = d / "run"
            pre = _fsize_limit(24 * 1024) if how == "rlimit" else None
            p = _agnav("run", "--device", robot.device, "--laser", f"replay:{log}?x=0.2", "--planner", "him",
                       "--localise", "scan", "--goal", "3,0", "--duration", "2", "--out", str(out), "--no-plot",
                       preexec=pre, timeout=90.0)
            sps = robot.received_of("AGNAV_DRIVE_SETPOINT")
            partial = {Path(k).name: int(v) for k, v in re.findall(r"wrote (\S+) partial \((\d+) B\)", p.stdout)}
            files = {f.name: f.stat().st_size for f in out.glob("*")} if out.is_dir() else {}
            bad = [n for n, size in files.items() if size == 0]
            bad += [n for n, size in partial.items() if files.get(n) != size]
            for name in ("trajectory.csv", "localisation.csv"):
                if name in files and not (out / name).read_bytes().endswith(b"\n"):
                    bad.append(f"{name} cut mid-line")
            if "laser.alog" in files and laser_log_info(out / "laser.alog").truncated_bytes:
                bad.append("laser.alog cut mid-record")
            clean = "Traceback" not in p.stderr
            ended = "duration reached" in p.stdout and bool(sps) and sps[-1].speed_mm_s == 0
            ok = clean and ended and bool(partial) and not bad
            cut = ", ".join(f"{n} {v} B" for n, v in sorted(partial.items())) or "none"
            return FaultOutcome(f"({how}) exit {p.returncode}, {'drove to its end, stopped' if ended else 'DID NOT END'}; "
                                f"partial: {cut}; {len(files)} files, {len(bad)} bad" + (f" ({', '.join(bad)})" if bad else ""),
                                ok)


# ---- serial cable pulled -----------------------------------------------------------------------------
class _PtyBridge:
    """/dev/pts/N <-> TCP: a serial port whose far end is the fake robot."""

    def __init__(self, tcp_port: int) -> None:
        self.master, self.slave = os.openpty()
        import tty

        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)  # the endpoint opens it by name, as it would /dev/ttyACM0
        # (the bridge holds the slave open too: a pty whose slave side nobody holds reads EIO)
        self.sock = socket.create_connection(("127.0.0.1", tcp_port))
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                watched: list[int | socket.socket] = [self.master, self.sock]
                r, _, _ = select.select(watched, [], [], 0.05)
                if self.master in r:
                    data = os.read(self.master, 4096)
                    if data:
                        self.sock.sendall(data)
                if self.sock in r:
                    data = self.sock.recv(4096)
                    if not data:
                        return
                    os.write(self.master, data)
            except OSError:
                return

    def unplug(self) -> None:
        self._stop.set()
        self._t.join(1.0)
        os.close(self.master)
        os.close(self.slave)
        self.sock.close()


def _case_serial_unplugged() -> FaultOutcome:
    from ..link.endpoint import Endpoint
    from ..link.fake import FakeRobot
    from ..link.tlog import read_tlog

    with tempfile.TemporaryDirectory() as d, FakeRobot() as robot:
        port = int(robot.device.rsplit(":", 1)[1])
        br = _PtyBridge(port)
        log = Path(d) / "run.tlog"
        ep = Endpoint(f"serial:{br.path}:57600", tlog=log, link_timeout_s=1.0)
        ep.start(wait_heartbeat_s=5.0)
        time.sleep(2.0)
        rx_before = ep.stats.rx_msgs
        t_unplug = time.monotonic()
        br.unplug()
        t_fail = t_down = None
        while time.monotonic() - t_unplug < 4.0:
            if t_fail is None and any("transport failed" in e for _, e in ep.events):
                t_fail = time.monotonic() - t_unplug
            if t_down is None and not ep.stats.link_up:
                t_down = time.monotonic() - t_unplug
            if t_fail is not None and t_down is not None:
                break
            time.sleep(0.02)
        io_thread = ep._thread  # noqa: SLF001
        thread_alive = io_thread is not None and io_thread.is_alive()
        ev = next((e for _, e in ep.events if "transport failed" in e), "NO EVENT")
        ep.close()
        host = ep.mav.srcSystem
        kept = sum(1 for _, m in read_tlog(log) if m.get_srcSystem() != host)  # the robot's frames in the log
    ok = t_fail is not None and t_down is not None and kept >= rx_before * 0.9 and rx_before > 50 and thread_alive
    return FaultOutcome(f"\"{ev[:70]}\" after {1000 * (t_fail or 0):.0f} ms, link marked down after "
                        f"{1000 * (t_down or 0):.0f} ms; I/O thread kept retrying; the tlog holds {kept} robot frames ({rx_before} "
                        f"had been received when the cable was pulled)", ok)


def _case_dead_downlink() -> FaultOutcome:
    """`agnav run --planner subsumption` (sonar ring) drives the fake robot; 2 s into the drive its telemetry goes
    silent for 2 s (commands still reach it): the host must stop commanding motion while it is blind."""
    from ..link.fake import FakeRobot
    from ..robot import POSE_STALE_S

    with FakeRobot() as fr:
        p = subprocess.Popen([sys.executable, "-m", "agnav_host.cli", "run", "--device", fr.device, "--planner",
                              "subsumption", "--goal", "20,0", "--duration", "7", "--no-tlog"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        samples: list[tuple[float, int]] = []  # (s since mute, speed of the newest setpoint)
        t_start = time.monotonic()
        t_mute: float | None = None  # 2 s after the first setpoint that moves the robot
        while p.poll() is None and time.monotonic() - t_start < 30.0:
            now = time.monotonic()
            sp = fr.received_of("AGNAV_DRIVE_SETPOINT")
            if t_mute is None and sp and sp[-1].speed_mm_s > 0:
                t_mute = now + 2.0
            if t_mute is not None:
                if not fr.mute and t_mute <= now < t_mute + 2.0:
                    fr.mute = True
                elif fr.mute and now >= t_mute + 2.0:
                    fr.mute = False
                if sp:
                    samples.append((now - t_mute, sp[-1].speed_mm_s))
            time.sleep(0.02)
        try:
            rc = p.wait(5.0)
        except subprocess.TimeoutExpired:
            p.kill()
            rc = None
        err = p.stderr.read() if p.stderr else ""
    before = [v for ts, v in samples if -1.0 < ts < 0.0]
    during = [(ts, v) for ts, v in samples if 0.0 <= ts < 2.0]
    held = next((ts for ts, v in during if v == 0 and all(w == 0 for t2, w in during if t2 >= ts)), None)
    after = [v for ts, v in samples if 2.8 <= ts < 3.8]
    ok = (bool(before) and all(v > 0 for v in before) and held is not None and held <= POSE_STALE_S + 0.3
          and any(v > 0 for v in after) and rc == 0 and "Traceback" not in err)
    return FaultOutcome(f"driving at {max(before, default=0)} mm/s; telemetry silent -> zero setpoints "
                        f"{'after %.0f ms' % (held * 1000) if held is not None else 'NEVER'} and held; "
                        f"telemetry back -> driving again ({max(after, default=0)} mm/s); "
                        f"exit {rc if rc is not None else 'hung'}", ok)


HOST_CASES = (
    FaultCase("serial cable pulled mid-run (pty)", "host",
              "transport failure reported, link marked down within link_timeout (1 s), reopen retried, tlog kept",
              _case_serial_unplugged),
    FaultCase("telemetry lost during a host-planner run (downlink dead, uplink alive)", "host",
              "the host stops commanding motion within 0.5 s (stale odometry) + 0.3 s, holds it, and plans again "
              "when odometry returns", _case_dead_downlink),
    FaultCase("corrupt scenario files", "host",
              "exit 2 with one line naming the line/field, no traceback", _case_corrupt_scenarios),
    FaultCase("corrupt telemetry logs", "host",
              "replay summarises what is readable (exit 0), valid frames around the damage recovered; a file "
              "with no frame at all: exit 2 and says so; never a traceback",
              _case_corrupt_tlog),
    FaultCase("disk full while writing `agnav sim` results", "host",
              "exit 1, says the disk is full (only agnav's own lines), lists the files kept; summary.json intact, no truncated recording", _case_disk_full_sim),
    FaultCase("disk full while recording the telemetry log", "host",
              "error reported once, the link keeps running, the log keeps what was flushed before the disk filled "
              "(at most the last 1 s buffer is lost)",
              _case_disk_full_tlog),
    FaultCase("disk full while `agnav run --out` streams its files", "host",
              "the run drives to its end and stops the robot; each file left ends on a whole record, a cut one listed as "
              "partial with its size, no empty file", _case_disk_full_run),
)
