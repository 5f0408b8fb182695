"""The native SIL library and its Python plumbing: build, boot, timed encoder/echo injection,
parameters in EEPROM, the link model and the telemetry log."""

from __future__ import annotations

import math

import numpy as np
import pytest

from _sil_logic import decode, run

from agnav_host.protocol import dialect

from agnav_host.protocol import new_codec
from agnav_host.sil import Firmware, LinkChannel, LinkParams, MavFramer, Tlog, build_library
from agnav_host.sil.plant import FastSonarRing
from agnav_host.sim import load_scenario
from agnav_host.sim.sensors import EncoderSpec, SonarRing, WheelEncoder
from agnav_host.types import Pose2D


@pytest.fixture(scope="module", autouse=True)
def lib():
    return build_library()


def test_behaviour_status_reports_a_change_in_the_tick_it_happens():
    d = dialect()
    host = d.MAVLink(None, srcSystem=255, srcComponent=190)
    with Firmware() as fw:
        run(fw, 1_000_000)
        t_cmd_ms = fw.time_us // 1000
        fw.uart_write(d.MAVLink_command_long_message(1, 1, d.MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0).pack(host))
        msgs = decode(run(fw, 300_000))
        st = [m for m in msgs if m.get_type() == "AGNAV_BEHAVIOUR_STATUS" and m.failsafe_flags & d.AGNAV_FAILSAFE_ESTOP]
        assert st, "no status with the e-stop flag within 300 ms"
        # the frame needs ~6 ms on the 57600-baud wire, then at most one 20 ms control tick
        assert st[0].time_boot_ms - t_cmd_ms <= 30, f"e-stop reported {st[0].time_boot_ms - t_cmd_ms} ms after the command"


def test_boot_heartbeat_and_neutral_outputs():
    with Firmware() as fw:
        msgs = decode(run(fw, 2_100_000))
        hb = [m for m in msgs if m.get_type() == "HEARTBEAT"]
        assert len(hb) == 3, f"{len(hb)} heartbeats in 2.1 s (1 Hz from t = 0 expected)"
        st = [m for m in msgs if m.get_type() == "AGNAV_BEHAVIOUR_STATUS"]
        # Sent on every change and as a 5 Hz keep-alive (radio budget): a steady 2.1 s gives ~11.
        assert 10 <= len(st) <= 16, f"{len(st)} BEHAVIOUR_STATUS in 2.1 s (5 Hz keep-alive expected)"
        gaps = [b.time_boot_ms - a.time_boot_ms for a, b in zip(st, st[1:])]
        assert max(gaps) <= 200, f"status gap {max(gaps)} ms > 200 ms keep-alive"
        o = fw.outputs()
        assert o.throttle_us == 1500 and o.duty_left == 0, o
        assert fw.loop_passes >= 21_000, f"only {fw.loop_passes} loop passes in 2.1 s (tick 100 us)"


def test_instances_are_independent_power_ons():
    a, b = Firmware(), Firmware({"SYSID_THISMAV": 7})
    try:
        run(a, 1_000_000)
        assert b.time_us == 0 and a.time_us == 1_000_000
        assert b.param_get("SYSID_THISMAV") == 7 and a.param_get("SYSID_THISMAV") == 1
        assert {m.get_srcSystem() for m in decode(run(b, 1_000_000))} == {7}
    finally:
        a.close()
        b.close()


def test_encoder_edges_become_odometry():
    """1 m of straight travel on two quadrature encoders (diff profile) -> AGNAV_ODOMETRY x = 1000 mm."""
    r = 0.127
    enc = WheelEncoder(EncoderSpec("quadrature", 360))
    nm = round(2 * math.pi * r / 1440 * 1e9)
    with Firmware({"DRIVE_KIND": 1, "ENC_COUNT": 2, "ENC_MODE": 0, "ENC_NM_PER_CNT": nm, "TRACK_MM": 400}) as fw:
        run(fw, 100_000)
        ang = 1.0 / r  # 1 m of wheel travel over 2 s
        e = enc.edges(0.0, ang, 0.1, 2.1)
        t = np.round(e.times_s * 1e6).astype(np.uint64)
        for i in (0, 1):
            fw.queue_encoder_edges(i, t, e.ab)
        data = run(fw, 2_500_000)
        assert fw.late_events == 0
        odo = [m for m in decode(data) if m.get_type() == "AGNAV_ODOMETRY"]
        assert abs(odo[-1].x_mm - 1000) <= 5, f"odometry x = {odo[-1].x_mm} mm after 1000 mm of wheel travel"
        assert abs(odo[-1].y_mm) <= 2 and abs(odo[-1].yaw_cdeg) <= 10, odo[-1]
        moving = [m for m in odo if 0.6e3 < m.time_boot_ms < 2.0e3]
        assert all(abs(m.speed_mm_s - 500) <= 25 for m in moving), [m.speed_mm_s for m in moving]


def test_sonar_echo_width_becomes_range():
    """Every trigger answered with a 1.5 m echo (rise 450 us later): the ring reports 1500 mm VALID."""
    with Firmware() as fw:
        width = round(2 * 1.5 / 343.0 * 1e6)
        end = fw.time_us + 600_000
        n = 0
        while fw.time_us < end:
            fw.step_to(end)
            for idx, t in fw.take_triggers():
                fw.queue_echo(idx, t + 450, 1)
                fw.queue_echo(idx, t + 450 + width, 0)
                n += 1
        assert n >= 12 * 5, f"{n} triggers in 0.6 s"
        ring = [m for m in decode(fw.uart_read()) if m.get_type() == "AGNAV_SONAR_RING"]
        assert ring, "no AGNAV_SONAR_RING"
        last = ring[-1]
        assert list(last.status) == [0] * 12, last.status
        assert all(abs(r - 1500) <= 2 for r in last.ranges_mm), last.ranges_mm


def test_fast_sonar_matches_the_world_model():
    sc = load_scenario("corridor_obstacles")
    slow, fast = SonarRing(sc.sonar.spec), FastSonarRing(sc.sonar.spec)
    rng = np.random.default_rng(0)
    for _ in range(200):
        p = Pose2D(*rng.uniform([0, 0.2, -3], [9, 2.8, 3]))
        a, b = slow.exact_ranges(sc.world, p), fast.exact_ranges(sc.world, p)
        assert np.array_equal(np.isfinite(a), np.isfinite(b))
        assert np.allclose(a[np.isfinite(a)], b[np.isfinite(b)], atol=1e-9)


def test_link_bandwidth_latency_and_loss():
    codec = new_codec()
    frame = codec.heartbeat_encode(6, 8, 0, 0, 4).pack(codec)
    ch = LinkChannel(LinkParams(baud=57600, latency_s=0.01, loss=0.0, buffer_bytes=1 << 20), np.random.default_rng(0))
    ch.send(0, frame * 100)
    n = len(frame) * 100
    t_last = int(round(n * 1e6 / 5760)) + 10_000
    early = ch.receive(t_last - 1_000)
    assert 0 < len(early) < n, f"{len(early)} of {n} bytes delivered 1 ms before the last byte can arrive"
    assert early + ch.receive(t_last + 100) == frame * 100 and ch.frames_sent == 100
    lossy = LinkChannel(LinkParams(loss=0.3, buffer_bytes=1 << 20), np.random.default_rng(1))
    lossy.send(0, frame * 1000)
    assert 250 <= lossy.frames_lost <= 350, lossy.frames_lost
    small = LinkChannel(LinkParams(buffer_bytes=100), np.random.default_rng(0))
    small.send(0, frame * 20)
    assert small.frames_dropped == 20 - 100 // len(frame), small.frames_dropped


def test_framer_keeps_partial_frames():
    codec = new_codec()
    data = b"".join(codec.heartbeat_encode(6, 8, 0, 0, 4).pack(codec) for _ in range(3))
    f = MavFramer()
    got = f.feed(data[:10]) + f.feed(data[10:25]) + f.feed(data[25:])
    assert b"".join(got) == data and len(got) == 3


def test_tlog_reads_back_with_pymavlink(tmp_path):
    from pymavlink import mavutil



    codec = new_codec()
    tl = Tlog(tmp_path / "x.tlog")
    for k in range(5):
        tl.write(1_000_000 * (k + 1), codec.heartbeat_encode(6, 8, 0, 0, 4).pack(codec))
    tl.close()

    mlog = mavutil.mavlink_connection(str(tmp_path / "x.tlog"), dialect="common")
    ts = []
    while (m := mlog.recv_match(type="HEARTBEAT")) is not None:
        ts.append(m._timestamp)
    assert ts == [1.0, 2.0, 3.0, 4.0, 5.0], ts


def test_tcp_server_serves_a_ground_station():
    """`agnav sil` core: a TCP client gets the firmware's stream and its PARAM_REQUEST_READ is answered."""
    import socket
    import threading

    from agnav_host.sil.server import ServeOptions, parse_endpoint, serve

    with pytest.raises(ValueError):
        parse_endpoint("tcp:0.0.0.0:5760")
    assert parse_endpoint("tcp:localhost:5761") == ("127.0.0.1", 5761)
    sc = load_scenario("corridor_obstacles")
    box: dict[str, object] = {}
    up = threading.Event()

    def ready(addr, pty):
        box["addr"] = addr
        up.set()

    th = threading.Thread(target=lambda: box.setdefault("s", serve(sc, ServeOptions(tcp=("127.0.0.1", 0), speedup=4.0,
                                                                                    duration_s=3.0), log=lambda m: None,
                                                                   ready=ready)))
    th.start()
    assert up.wait(30)
    codec = new_codec()
    with socket.create_connection(box["addr"], timeout=10) as c:
        c.sendall(codec.param_request_read_encode(1, 1, b"DRIVE_KIND", -1).pack(codec))
        data = b""
        c.settimeout(0.5)
        while True:
            try:
                chunk = c.recv(65536)
            except socket.timeout:
                continue
            if not chunk:
                break
            data += chunk
    th.join(30)
    msgs = decode(data)
    kinds = {m.get_type() for m in msgs}
    assert {"HEARTBEAT", "AGNAV_BEHAVIOUR_STATUS", "AGNAV_ODOMETRY"} <= kinds, kinds
    pv = [m for m in msgs if m.get_type() == "PARAM_VALUE"]
    assert pv and pv[0].param_id == "DRIVE_KIND" and pv[0].param_value == 1.0, pv


def test_tcp_server_on_a_busy_port_says_so():
    """A second `agnav sil` on the same port: the address, the reason and what to do, no traceback."""
    import socket

    from agnav_host.sil.server import ServeOptions, serve

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        with pytest.raises(OSError) as e:
            serve(load_scenario("corridor_obstacles"), ServeOptions(tcp=("127.0.0.1", port), duration_s=1.0),
                  log=lambda m: None)
    assert f"cannot listen on tcp:127.0.0.1:{port}: Address already in use" in e.value.strerror
    assert "pick another --tcp port" in e.value.strerror
