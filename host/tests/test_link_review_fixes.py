"""The link on the inputs a field robot gives it: parameter names too long for MAVLink, a slow radio
whose late answers cross the next request, duplicated frames and robot reboots in the sequence count,
telemetry logs from a machine whose clock was set (or runs appended to one file), a ground station that
is not system 255, a link closed while a request waits, frames dropped on a dead link."""

from __future__ import annotations

import threading
import time

import pytest

from agnav_host.link.config import ConfigError, HostConfig, validate_config
from agnav_host.link.endpoint import Endpoint, LinkTimeout
from agnav_host.link.fake import FakeRobot
from agnav_host.link.replay import summarize_tlog
from agnav_host.link.robot import AgnavRobot
from agnav_host.link.tlog import TlogWriter
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


def _odometry_log(path, stamps, robot):  # type: ignore[no-untyped-def]
    with TlogWriter(path) as w:
        for i, t in enumerate(stamps):
            w.write(robot.agnav_odometry_encode(i * 100, i, 0, 0, 0, 0).pack(robot), t)


def test_replay_times_leave_out_clock_steps_and_appended_runs(tmp_path):
    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    t0 = 1.79e9
    stepped = tmp_path / "stepped.tlog"  # 10 s at 10 Hz, the clock set back an hour half-way
    _odometry_log(stepped, [t0 + 0.1 * i for i in range(50)] + [t0 - 3600 + 0.1 * i for i in range(50, 100)], robot)
    s = summarize_tlog(stepped)
    assert s.duration_s == pytest.approx(9.8, abs=0.15) and s.breaks == 1
    assert s.rx_msgs["AGNAV_ODOMETRY"] / s.duration_s == pytest.approx(10.0, rel=0.05)
    appended = tmp_path / "appended.tlog"  # two 10 s runs an hour apart in one file
    for start in (t0, t0 + 3600):
        _odometry_log(appended, [start + 0.1 * i for i in range(100)], robot)
    s = summarize_tlog(appended)
    assert s.duration_s == pytest.approx(19.8, abs=0.15) and s.breaks == 1
    assert "break(s) in the time stamps" in s.text()


def test_replay_counts_the_ground_stations_own_frames_as_sent_whatever_its_system_id(tmp_path):
    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    host = d.MAVLink(None, srcSystem=200, srcComponent=190)
    log = tmp_path / "h200.tlog"
    with TlogWriter(log) as w:
        for i in range(20):
            w.write(robot.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, d.MAV_AUTOPILOT_GENERIC, 0, 0, 0).pack(robot), 1e9 + i)
            w.write(host.heartbeat_encode(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(host), 1e9 + i + 0.5)
    s = summarize_tlog(log)
    assert s.rx_msgs["HEARTBEAT"] == 20 and s.tx_msgs["HEARTBEAT"] == 20


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
        ep._broken = True  # the transport has failed; the I/O thread has not reopened it yet
        ep._conn = None
        sent = [r.drive(0.0, 0.3) for _ in range(20)]
        ep.close()
    assert not any(sent) and ep.stats.tx_dropped >= 20
    assert summarize_tlog(tlog).tx_msgs["AGNAV_DRIVE_SETPOINT"] == 0


def test_a_calibration_step_must_outlast_its_settling():
    cfg = HostConfig()
    cfg.calibration.settle_s, cfg.calibration.max_step_s = 2.0, 1.5
    with pytest.raises(ConfigError, match=r"\[calibration\] settle_s: must be < max_step_s"):
        validate_config(cfg)


def test_replay_reads_the_log_once_and_settles_the_senders_at_the_end(tmp_path, monkeypatch):
    """One pass over the file (it was read twice: once for the ground stations' ids); a ground station
    whose first heartbeat comes after its first frames still counts as the sender of all of them, and its
    status texts are not the robot's."""
    import agnav_host.link.replay as R
    import agnav_host.link.tlog as T

    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    host = d.MAVLink(None, srcSystem=200, srcComponent=190)
    log = tmp_path / "late_gcs.tlog"
    with TlogWriter(log) as w:
        w.write(host.statustext_encode(6, b"host says hi").pack(host), 1e9)
        w.write(host.statustext_encode(6, b"host again").pack(host), 1e9 + 0.1)
        for i in range(5):
            w.write(robot.statustext_encode(6, f"robot {i}".encode()).pack(robot), 1e9 + 0.2 + i)
        w.write(host.heartbeat_encode(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(host), 1e9 + 6)
    reads = []
    real = T.read_tlog

    def counting(path, progress=None):  # type: ignore[no-untyped-def]
        reads.append(path)
        return real(path, progress)

    monkeypatch.setattr(T, "read_tlog", counting)  # every reader of the module, host_systems too
    monkeypatch.setattr(R, "read_tlog", counting)
    s = R.summarize_tlog(log)
    assert len(reads) == 1
    assert sum(s.tx_msgs.values()) == 3 and s.rx_msgs["STATUSTEXT"] == 5
    assert [t for _, t in s.statustexts] == [f"robot {i}" for i in range(5)]


def test_replay_of_a_large_log_shows_its_progress(tmp_path, monkeypatch, capsys):
    from agnav_host import cli
    import agnav_host.link.commands as C
    import agnav_host.link.tlog as T

    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    log = tmp_path / "big.tlog"
    _odometry_log(log, [1.79e9 + 0.1 * i for i in range(300)], robot)
    monkeypatch.setattr(C, "REPLAY_PROGRESS_BYTES", 1000)
    monkeypatch.setattr(T, "PROGRESS_EVERY", 50)
    assert cli.main(["replay", str(log)]) == 0
    err = capsys.readouterr().err
    assert err.count("\rreading ") >= 6 and err.rstrip().endswith("(100 %)")
    monkeypatch.setattr(C, "REPLAY_PROGRESS_BYTES", 10**9)  # a small log: nothing on stderr
    assert cli.main(["replay", str(log)]) == 0
    assert capsys.readouterr().err == ""
