"""Requests and frame counts on a link a field robot gives: parameter names too long for MAVLink, a slow radio
whose late answers cross the next request, duplicated frames and robot reboots in the sequence count, a link
closed while a request waits, frames dropped on a dead link."""

from __future__ import annotations

import threading
import time

import pytest

from agnav_host.link.endpoint import Endpoint, LinkTimeout
from agnav_host.link.fake import FakeRobot
from agnav_host.link.replay import summarize_tlog
from agnav_host.link.robot import AgnavRobot
from agnav_host.protocol import dialect


def test_a_parameter_name_longer_than_mavlink_carries_is_refused_before_sending():
    with FakeRobot() as fr, Endpoint(fr.device) as ep:
        ep.wait_heartbeat(3.0)
        r = AgnavRobot(ep, timeout_s=0.3, retries=1)
        before = fr.params["AVOID_BACKOFF_MM"]
        for bad in ("AVOID_BACKOFF_MM_X", "AVOID_BACKOFF_MM_TYPO", "", "MAX_SPEED_\u00e9"):
            with pytest.raises(ValueError):
                r.param_set(bad, 9999)
            with pytest.raises(ValueError):
                r.param_get(bad)
        time.sleep(0.3)
        assert fr.params["AVOID_BACKOFF_MM"] == before  # the 16-character prefix was not touched
        assert not fr.received_of("PARAM_SET") and not fr.received_of("PARAM_REQUEST_READ")


class _SlowRobot(FakeRobot):
    """Answers parameter requests 0.45 s late."""

    def _handle(self, m):  # type: ignore[no-untyped-def]
        if m.get_type() in ("PARAM_REQUEST_READ", "PARAM_SET"):
            threading.Timer(0.45, FakeRobot._handle, (self, m)).start()
        else:
            super()._handle(m)


def test_a_late_answer_to_an_earlier_request_does_not_decide_a_parameter_set():
    with _SlowRobot() as fr, Endpoint(fr.device) as ep:
        ep.wait_heartbeat(3.0)
        r = AgnavRobot(ep, timeout_s=0.3, retries=3)  # the first try times out, the second gets it
        assert r.param_get("MAX_SPEED_MM_S") == 1000
        # the get's second, late answer (1000) arrives while the set waits: not a refusal of 800
        assert r.param_set("MAX_SPEED_MM_S", 800) == 800
        time.sleep(0.6)
        assert fr.params["MAX_SPEED_MM_S"] == 800


def _heartbeat_frame(ep: Endpoint, mav, seq: int):  # type: ignore[no-untyped-def]
    d = dialect()
    mav.seq = seq
    buf = mav.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, d.MAV_AUTOPILOT_GENERIC, 0, 0, 0).pack(mav)
    return ep.mav.parse_buffer(buf)[0]


def test_lost_frame_count_ignores_duplicates_and_a_robot_reboot():
    d = dialect()
    ep = Endpoint("tcp:127.0.0.1:9")  # never started: frames go straight into the receive path
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    for s in (250, 251, 252, 253, 254, 255, 0, 1, 2):
        ep._handle(_heartbeat_frame(ep, robot, s), 0.0)
    assert ep.stats.rx_seq_lost == 0  # the wrap is not a loss
    ep._handle(_heartbeat_frame(ep, robot, 2), 0.0)  # the same frame again
    ep._handle(_heartbeat_frame(ep, robot, 0), 0.0)  # the robot rebooted
    assert ep.stats.rx_seq_lost == 0
    ep._handle(_heartbeat_frame(ep, robot, 4), 0.0)  # 1..3 missing
    assert ep.stats.rx_seq_lost == 3




def test_closing_the_link_ends_a_waiting_request_at_once():
    with FakeRobot() as fr:
        ep = Endpoint(fr.device).start(wait_heartbeat_s=3.0)
        fr.mute = True  # the robot answers nothing
        r = AgnavRobot(ep, timeout_s=2.0, retries=3)
        box: dict[str, object] = {}

        def wait() -> None:
            t = time.monotonic()
            try:
                r.estop(True)
            except LinkTimeout as e:
                box["err"] = str(e)
            box["dt"] = time.monotonic() - t

        th = threading.Thread(target=wait)
        th.start()
        time.sleep(0.2)
        ep.close()
        th.join(3.0)
        assert not th.is_alive()
        assert "was closed" in str(box["err"]) and float(box["dt"]) < 1.0  # type: ignore[arg-type]


def test_frames_dropped_on_a_dead_link_are_not_logged_as_sent(tmp_path):
    tlog = tmp_path / "t.tlog"
    with FakeRobot() as fr:
        ep = Endpoint(fr.device, tlog=tlog).start(wait_heartbeat_s=3.0)
        r = AgnavRobot(ep)
        # The transport has failed and the I/O thread will not reopen it during the test.
        ep.reconnect_delay_s = 60.0
        ep._next_open = time.monotonic() + 60.0
        ep._broken = True
        ep._conn = None
        sent = [r.drive(0.0, 0.3) for _ in range(20)]
        ep.close()
    assert not any(sent) and ep.stats.tx_dropped >= 20
    assert summarize_tlog(tlog).tx_msgs["AGNAV_DRIVE_SETPOINT"] == 0
