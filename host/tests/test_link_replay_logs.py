"""``replay`` of telemetry logs as field runs leave them: a machine whose clock was set (or runs appended to one
file), a ground station that is not system 255 or whose first heartbeat comes late, a log large enough for a
progress line; the log is read once."""

from __future__ import annotations

import pytest

from agnav_host.link.replay import summarize_tlog
from agnav_host.link.tlog import TlogWriter
from agnav_host.protocol import dialect


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
    import agnav_host.cli.link as C
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
