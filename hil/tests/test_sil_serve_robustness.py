"""`agnav sil` as a long-running service: bad --tcp values, a pty per run, SIGTERM from a service
manager, a port already taken, ground stations that reset or reconnect mid-frame, a link faster than
the firmware's serial buffer."""

from __future__ import annotations

import gc
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agnav_host.sil.server import ServeOptions, ServeResult, parse_endpoint, serve
from agnav_host.sim import load_scenario

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("text, why", [
    ("tcp:127.0.0.1:70000", "the port must be a number 0-65535"),
    ("tcp:127.0.0.1:abc", "the port must be a number 0-65535"),
    ("tcp:127.0.0.1:", "the port must be a number 0-65535"),
    ("tcp:[::1]:5760", "IPv6 is not served"),
    ("tcp:::1:5760", "IPv6 is not served"),
    ("tcp:10.0.0.1:5760", "loopback addresses only"),
    ("tcp:robot.local:5760", "loopback addresses only"),
])
def test_bad_tcp_endpoints_are_named(text, why):
    with pytest.raises(ValueError, match=why):
        parse_endpoint(text)


def test_good_tcp_endpoints():
    assert parse_endpoint("tcp:localhost:5760") == ("127.0.0.1", 5760)
    assert parse_endpoint("127.0.0.2:0") == ("127.0.0.2", 0)


def _fds() -> int:
    """Open descriptors of this process, after a collection (another test's objects may still hold some)."""
    gc.collect()
    return len(os.listdir("/proc/self/fd"))


def _mapped_firmware_copies() -> int:
    return sum("agnav_sil" in line for line in Path("/proc/self/maps").read_text().splitlines() if "r-xp" in line)


def test_each_served_run_gives_back_its_pty_and_firmware():
    sc = load_scenario("fault_yard")
    serve(sc, ServeOptions(tcp=None, pty=True, speedup=50, duration_s=0.2), log=lambda m: None)  # warm up
    fds, copies = _fds(), _mapped_firmware_copies()
    for _ in range(3):
        res = serve(sc, ServeOptions(tcp=None, pty=True, speedup=50, duration_s=0.3), log=lambda m: None)
        assert isinstance(res, ServeResult) and res.t_s > 0.3
    assert _fds() <= fds, "a served run kept a descriptor (its pty or socket)"
    assert _mapped_firmware_copies() == copies


def test_a_taken_port_is_refused_before_the_firmware_is_loaded():
    sc = load_scenario("fault_yard")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        copies = _mapped_firmware_copies()
        for _ in range(2):
            with pytest.raises(OSError, match="cannot listen on"):
                serve(sc, ServeOptions(tcp=busy.getsockname(), speedup=50, duration_s=0.2), log=lambda m: None)
        assert _mapped_firmware_copies() == copies


def _tlog_records(path: Path) -> tuple[int, int | None]:
    """(records, last stamp in us) of a tlog written by the SIL (8-byte big-endian us + frame)."""
    b = path.read_bytes()
    i, n, last = 0, 0, None
    while i + 11 <= len(b):
        t = struct.unpack(">Q", b[i:i + 8])[0]
        j = i + 8
        ln = 12 + b[j + 1] + (13 if b[j + 2] & 1 else 0) if b[j] == 0xFD else (8 + b[j + 1] if b[j] == 0xFE else None)
        if ln is None or j + ln > len(b):
            break
        n, last, i = n + 1, t, j + ln
    return n, last


def test_sigterm_stops_a_served_run_cleanly_with_its_tlog_complete(tmp_path):
    tlog = tmp_path / "sil.tlog"
    p = subprocess.Popen([str(REPO / ".venv/bin/agnav") if (REPO / ".venv/bin/agnav").exists() else sys.executable,
                          *([] if (REPO / ".venv/bin/agnav").exists() else ["-m", "agnav_host.cli"]),
                          "sil", "fault_yard", "--tcp", "tcp:127.0.0.1:0", "--tlog", str(tlog), "--speedup", "4"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    time.sleep(4.0)
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 0, err
    m = out.strip().split("stopped at t = ")
    assert len(m) == 2, out
    stopped_s = float(m[1].split(" s")[0])
    n, last = _tlog_records(tlog)
    assert n > 50 and last is not None
    assert last / 1e6 > stopped_s - 0.5  # the log runs to the stop, not to the last full write buffer


def test_a_reconnecting_client_s_first_frame_is_whole():
    from agnav_host.sil import SilSession
    from agnav_host.sil.host import new_codec
    from agnav_host.sil.link import split_frames

    s = SilSession(load_scenario("fault_yard"), 0)
    try:
        s.provision()
        gcs = new_codec(255, 190)
        hb = gcs.heartbeat_encode(6, 8, 0, 0, 0).pack(gcs)
        sent0 = s.up.frames_sent
        s.up.send(s.t_us, hb[:5])  # a client dies mid-frame
        s.up.reset_framer()  # what the server does when a client goes or comes
        s.up.send(s.t_us, hb * 3)
        assert s.up.frames_sent - sent0 == 3
        assert split_frames(hb * 3) == [hb] * 3
    finally:
        s.close()


def test_a_burst_beyond_the_firmware_serial_buffer_is_delivered_not_dropped():
    from agnav_host.sil import LinkParams, SilConfig, SilSession

    cfg = SilConfig(uplink=LinkParams(baud=0), downlink=LinkParams(baud=0))  # unlimited: all at once
    s = SilSession(load_scenario("fault_yard"), 0, cfg)
    try:
        s.provision()
        took = []
        orig = s.fw.uart_write

        def counting(data: bytes) -> int:
            n = orig(data)
            took.append(n)
            return n

        s.fw.uart_write = counting  # type: ignore[method-assign]
        acks0 = len(s.host.acks)
        for _ in range(200):
            s.host.command_long(512, 245)
        burst = s.host.take_tx()
        s.up.send(s.t_us, burst)
        for _ in range(100):
            s.step()
        assert sum(took) == len(burst)  # every byte reached the firmware
        assert s.uart_deferred_bytes > 0  # some had to wait for room
        assert len(s.host.acks) - acks0 >= 150
    finally:
        s.close()


def test_the_parameter_record_fault_case_fails_when_nothing_was_corrupted(monkeypatch):
    # the case's verdict rests on the stored profile giving way to the defaults, not on a fixed text
    from agnav_host.faults import firmware_faults as ff
    from agnav_host.sil.binding import Firmware

    real = ff._eeprom_case("params")
    assert real.passed and "stored values replaced by defaults" in real.measured
    monkeypatch.setattr(Firmware, "corrupt_record", lambda self, *a, **k: None)
    fake = ff._eeprom_case("params")
    assert not fake.passed and "still in use" in fake.measured
