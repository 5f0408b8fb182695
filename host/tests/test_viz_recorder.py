"""rerun recordings (.rrd) and the clear failure when rerun-sdk is absent; run plots."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from agnav_host.link.state import BehaviourState, PoseState, SonarState


def test_small_rrd_is_written(tmp_path):
    pytest.importorskip("rerun")
    from agnav_host.viz import Recorder

    path = tmp_path / "run.rrd"
    rec = Recorder.to_file(path)
    for i in range(20):
        t = i * 0.1
        pose = PoseState(t, 0.1 * i, 0.02 * i, 0.05 * i, 0.5, 0.1, t)
        rec.set_time(t)
        rec.log_pose(pose)
        rec.log_sonar(SonarState(t, tuple([1.5] * 12), tuple([0] * 11 + [3]), 12, i, t), pose)
        rec.log_behaviour(BehaviourState(t, 5 if i < 10 else 2, 12 if i < 10 else 5, 0, 0.1, 0.5, t))
        rec.log_scan([[1.0 + i * 0.01, 0.5], [1.2, -0.4]])
        rec.log_plan([[0, 0], [1, 0.5], [2, 1.0]])
    rec.log_goal(2.0, 1.0)
    rec.log_text("done")
    rec.close()
    data = path.read_bytes()
    assert len(data) > 1000
    assert data[:4] == b"RRF2"  # rerun file magic
    rerun_cli = Path(sys.executable).parent / "rerun"  # the viewer's CLI, installed with rerun-sdk
    if rerun_cli.exists():  # the file loads (the pieces of a binary stream written one after another did not)
        r = subprocess.run([str(rerun_cli), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stdout + r.stderr


def test_a_recording_that_cannot_be_written_raises_and_leaves_no_file(tmp_path, monkeypatch):
    pytest.importorskip("rerun")
    from agnav_host.viz import Recorder
    from agnav_host.viz import recorder as R

    path = tmp_path / "run.rrd"
    rec = Recorder.to_file(path)
    rec.set_time(0.0)
    rec.log_goal(2.0, 1.0)

    class FullDisk:
        def __init__(self, *a, **k):
            self.f = open(*a, **k)

        def write(self, data):
            self.f.write(data[: len(data) // 2])
            raise OSError(28, "No space left on device")

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    monkeypatch.setattr(R, "open", FullDisk, raising=False)
    with pytest.raises(OSError, match="No space"):
        rec.close()
    assert not path.exists()  # no truncated recording left behind as if it were one


def test_missing_rerun_gives_a_clear_message(monkeypatch, tmp_path):
    from agnav_host.viz import Recorder, VizUnavailable, require_rerun

    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun -> ImportError
    with pytest.raises(VizUnavailable, match=r"pip install rerun-sdk==0\.41\.0"):
        require_rerun()
    with pytest.raises(VizUnavailable):
        Recorder.to_file(tmp_path / "x.rrd")
    assert not (tmp_path / "x.rrd").exists()


def test_tlog_to_rrd_and_png(tmp_path):
    pytest.importorskip("rerun")
    pytest.importorskip("matplotlib")
    from agnav_host.link import AgnavRobot, Endpoint
    from agnav_host.link.fake import FakeRobot
    from agnav_host.link.replay import summarize_tlog
    from agnav_host.viz import record_tlog
    from agnav_host.viz.plots import plot_run

    tlog = tmp_path / "s.tlog"
    with FakeRobot() as fr, Endpoint(fr.device, tlog=tlog) as ep:
        ep.wait_heartbeat(3.0)
        r = AgnavRobot(ep)
        for _ in range(12):
            r.drive(0.2, 0.7)
            time.sleep(0.05)
        r.stop()
    s = summarize_tlog(tlog)
    assert s.rx_msgs["AGNAV_BEHAVIOUR_STATUS"] > 10 and s.tx_msgs["AGNAV_DRIVE_SETPOINT"] >= 12
    assert "HOST_COMMAND" in s.layer_time_s and s.path_length_m > 0.1
    out = record_tlog(tlog, tmp_path / "s.rrd")
    assert out.stat().st_size > 1000
    png = plot_run(s, tmp_path / "s.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_a_long_runs_recording_grows_with_its_length_not_its_square(tmp_path):
    pytest.importorskip("rerun")
    from agnav_host.viz import Recorder

    def size(n: int) -> int:
        path = tmp_path / f"run{n}.rrd"
        rec = Recorder.to_file(path)
        for i in range(n):
            t = i * 0.05
            rec.set_time(t)
            rec.log_pose(PoseState(t, 0.01 * i, 0.0, 0.0, 0.2, 0.0, t))
        rec.close()
        return path.stat().st_size

    small, large = size(400), size(1600)
    assert large / small < 6.0  # 4x the poses: about 4x the bytes (the whole path every pose gave ~12x)
