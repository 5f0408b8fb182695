"""Endpoint against an in-process fake robot on 127.0.0.1 (ephemeral port), and tlog bytes."""

from __future__ import annotations

import math
import struct
import time

import pytest

from agnav_host.link import AgnavRobot, CommandFailed, Endpoint, LinkTimeout, parse_device
from agnav_host.link.endpoint import RateMeter
from agnav_host.link.fake import FakeRobot


def wait_until(pred, timeout=3.0, step=0.02):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(step)
    return False


@pytest.fixture
def fake():
    with FakeRobot() as fr:
        yield fr


@pytest.fixture
def ep(fake, tmp_path):
    e = Endpoint(fake.device, tlog=tmp_path / "s.tlog", reconnect_delay_s=0.1, link_timeout_s=0.6)
    e.start(wait_heartbeat_s=3.0)
    yield e
    e.close()


def test_parse_device():
    assert parse_device("serial:/dev/ttyUSB0:57600").address == "/dev/ttyUSB0"
    assert parse_device("serial:/dev/ttyUSB0:57600").baud == 57600
    assert parse_device("/dev/ttyACM0", 115200).kind == "serial"
    assert parse_device("/dev/ttyACM0", 115200).baud == 115200
    assert parse_device("tcp:127.0.0.1:5760").kind == "tcp"
    assert parse_device("udp:0.0.0.0:14550").kind == "udp"
    for bad in ("", "tcp:127.0.0.1", "tcp:host:notaport", "bluetooth:xx"):
        with pytest.raises(ValueError):
            parse_device(bad)


def test_rate_meter_window():
    m = RateMeter(window_s=2.0)
    for i in range(40):
        m.add(i * 0.1, 100)  # 1000 B/s for 4 s
    assert m.full(3.9)
    assert m.rate(3.9) == pytest.approx(1000.0, rel=0.1)
    assert m.rate(10.0) == 0.0  # all aged out


def test_heartbeats_both_ways_and_typed_state(fake, ep):
    assert ep.target_system == 1 and ep.target_component == 1
    assert wait_until(lambda: any(m.type == 6 for m in fake.received_of("HEARTBEAT")))  # MAV_TYPE_GCS from us
    assert wait_until(lambda: ep.state.sonar is not None and ep.state.encoders is not None and ep.state.pose is not None)
    st = ep.state.copy()
    assert st.behaviour.layer_name in ("IDLE", "FAILSAFE")
    assert "CALIB_DEFAULTED" in st.behaviour.flag_names
    assert st.sonar.count == 12 and st.sonar.ranges_m[0] == pytest.approx(2.0)
    assert st.encoders.wheels == 2
    assert st.heartbeat.type == 10  # MAV_TYPE_GROUND_ROVER


def test_drive_setpoint_units_and_pose(fake, ep):
    r = AgnavRobot(ep)
    for _ in range(15):
        r.drive(math.radians(10.0), 0.6)
        time.sleep(0.05)
    sps = fake.received_of("AGNAV_DRIVE_SETPOINT")
    assert sps[-1].steer_cdeg == 1000 and sps[-1].speed_mm_s == 600 and sps[-1].mode == 0
    assert sps[-1].seq != sps[0].seq
    assert wait_until(lambda: ep.state.pose is not None and ep.state.pose.x_m > 0.05)
    assert ep.state.behaviour.layer_name == "HOST_COMMAND"
    assert ep.state.pose.yaw_rate_rad_s > 0  # left turn is CCW positive
    r.drive_raw(140, 40, reverse=True)
    assert wait_until(lambda: fake.received_of("AGNAV_DRIVE_SETPOINT")[-1].mode == 1)
    raw = fake.received_of("AGNAV_DRIVE_SETPOINT")[-1]
    assert (raw.steer_pwm, raw.speed_pwm, raw.speed_mm_s) == (140, 40, -1)


def test_commands_estop_arm_behaviours_goal(fake, ep):
    r = AgnavRobot(ep)
    assert r.estop() == 0
    assert fake.estop
    assert wait_until(lambda: ep.state.behaviour.reason_name == "ESTOP")
    r.release()
    assert not fake.estop
    r.arm()
    r.set_behaviours(follow_wall=True, goal_seek=True, avoid=False)
    assert fake.behaviours == 0b011
    r.set_goal(3.0, -1.5)
    assert wait_until(lambda: fake.goal is not None)
    assert fake.goal == pytest.approx((3.0, -1.5))  # REP-103 y survives the NED round trip
    with pytest.raises(CommandFailed, match="UNSUPPORTED"):
        r.command(12345)


def test_params_list_fills_gaps_and_set_refused(fake, ep):
    r = AgnavRobot(ep, timeout_s=0.5)
    fake.drop_param_indices = {3, 11}  # lost on air once
    params = r.param_list(timeout_s=8.0)
    assert len(params) == 20
    assert params["ENC_MODE"] == 1 and params["MAX_STEER_CDEG"] == 2460
    reads = fake.received_of("PARAM_REQUEST_READ")
    assert {m.param_index for m in reads} >= {3, 11}
    assert r.param_set("MAX_SPEED_MM_S", 800) == 800
    assert fake.params["MAX_SPEED_MM_S"] == 800
    assert r.param_get("MAX_SPEED_MM_S") == 800
    with pytest.raises(CommandFailed, match="kept 800"):
        r.param_set("MAX_SPEED_MM_S", 5000)  # beyond the firmware's 0..3000
    assert ep.state.params["MAX_SPEED_MM_S"] == 800
    assert any("out of range" in s.text for s in ep.state.statustexts)
    with pytest.raises(LinkTimeout):
        r.param_get("NO_SUCH_PARAM")


def test_reconnect_after_cable_pull_keeps_session(fake, ep, tmp_path):
    assert wait_until(lambda: ep.stats.rx_msgs > 20)
    AgnavRobot(ep).param_set("TRACK_MM", 200)
    before = ep.stats.rx_msgs
    fake.drop_client()
    assert wait_until(lambda: ep.stats.reconnects >= 1, 5.0)
    assert wait_until(lambda: fake.connected and ep.stats.rx_msgs > before + 20, 5.0)
    assert ep.state.params["TRACK_MM"] == 200  # state kept
    assert AgnavRobot(ep).param_get("TRACK_MM") == 200  # commands work on the new transport
    # peer gone for a while, then back on the same port
    fake.stop_listening()
    n = ep.stats.reconnects
    t0 = time.monotonic()
    assert wait_until(lambda: not ep.stats.link_up, 3.0)
    assert ep.stats.link_losses >= 1
    assert time.monotonic() - t0 < 1.5, "link loss reported late"  # link_timeout_s 0.6 + a loop pass (slack: a loaded CI)
    fake.start_listening()
    assert wait_until(lambda: ep.stats.reconnects > n and ep.stats.link_up, 5.0)
    ep.close()
    from agnav_host.link.tlog import read_tlog

    types = [m.get_type() for _, m in read_tlog(tmp_path / "s.tlog")]
    assert types.count("PARAM_VALUE") >= 2 and types.count("HEARTBEAT") > 3  # one log across reconnects


def test_radio_silence_marks_link_down_then_up(fake, ep):
    assert wait_until(lambda: ep.stats.link_up)
    fake.mute = True
    assert wait_until(lambda: not ep.stats.link_up, 3.0)
    assert ep.stats.reconnects == 0 and ep.stats.link_losses == 1
    fake.mute = False
    assert wait_until(lambda: ep.stats.link_up, 3.0)


def test_tlog_readable_by_pymavlink(fake, tmp_path):
    path = tmp_path / "t.tlog"
    with Endpoint(fake.device, tlog=path) as e:
        e.wait_heartbeat(3.0)
        AgnavRobot(e).estop()
        time.sleep(0.3)
    raw = path.read_bytes()
    usec = struct.unpack(">Q", raw[:8])[0]
    assert abs(usec / 1e6 - time.time()) < 60  # wall-clock microseconds, big-endian
    assert raw[8] == 0xFD  # a MAVLink 2 frame follows the stamp
    from pymavlink import mavutil

    from agnav_host.protocol import dialect

    log = mavutil.mavlogfile(str(path))
    log.mav = dialect().MAVLink(log)  # plain pymavlink reader with the AgNav dialect
    log.first_byte = False
    seen = set()
    while (m := log.recv_msg()) is not None:
        seen.add(m.get_type())
    assert {"HEARTBEAT", "COMMAND_LONG", "COMMAND_ACK", "AGNAV_BEHAVIOUR_STATUS"} <= seen


def test_budget_warning(fake):
    events = []
    with Endpoint(fake.device, budget_bytes_s=500.0, budget_window_s=1.0, on_event=events.append) as e:
        assert wait_until(lambda: e.stats.budget_warnings >= 1, 4.0)
        # the fake sends at the firmware's rates: ~2.4 kB/s, well over a 500 B/s budget
        assert e.stats.peak_rx_rate_bytes_s > 1500
    assert any("over budget" in x for x in events)
    with Endpoint(fake.device, budget_bytes_s=50_000.0, budget_window_s=1.0) as e:
        time.sleep(1.6)
        assert e.stats.budget_warnings == 0 and e.stats.peak_rx_rate_bytes_s > 0


def test_signing_accepted_only_with_the_key(tmp_path):
    from agnav_host.link.keys import load_key, new_key

    _, key = new_key(tmp_path / "k")
    assert load_key(tmp_path / "k") == key
    with FakeRobot(key=key) as fr:
        with Endpoint(fr.device, key=key) as e:
            e.wait_heartbeat(3.0)
            AgnavRobot(e).arm()  # would time out if the robot rejected our frames
            assert e.signing
        assert fr.mav.signing.goodsig_count > 0
        rejected = fr.rejected
        with Endpoint(fr.device, key=bytes(32)) as e:  # wrong key
            with pytest.raises(LinkTimeout):
                AgnavRobot(e, timeout_s=0.3, retries=2).arm()
        assert fr.rejected > rejected
