"""`agnav run --out` on a full disk: the run goes on to its end, each streamed file (trajectory.csv,
localisation.csv, laser.alog, recording.rrd) stops on its last whole record, is said once and listed as
"partial (N B)", and a file that never got a whole record is not left on the disk."""

from __future__ import annotations

import errno
import json
import logging
import os
import re
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from agnav_host import cli
from agnav_host.lasers import LaserMount
from agnav_host.lasers.log import LaserLogReplay, LaserLogWriter, laser_log_info
from agnav_host.link.fake import FakeRobot
from agnav_host.streamfile import StreamFile
from agnav_host.types import LaserScan

pytestmark = pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="the full disk is told apart by /proc/self/fd")

STREAMED = ("trajectory.csv", "localisation.csv", "laser.alog", "recording.rrd")


class FullDisk:
    """``os.write`` that takes ``budget[name]`` bytes for the files of those names, the last write cut short,
    then refuses with ENOSPC, as a disk that fills does; every other file descriptor writes as usual."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, budget: dict[str, int]) -> None:
        self.budget = budget
        self.used: dict[str, int] = {}
        self.refused: dict[str, int] = {}
        self._real = os.write
        monkeypatch.setattr(os, "write", self.write)

    def write(self, fd: int, data: bytes) -> int:
        try:
            name = os.path.basename(os.readlink(f"/proc/self/fd/{fd}"))
        except OSError:
            return self._real(fd, data)
        if name not in self.budget:
            return self._real(fd, data)
        left = self.budget[name] - self.used.get(name, 0)
        if left <= 0:
            self.refused[name] = self.refused.get(name, 0) + 1
            raise OSError(errno.ENOSPC, "No space left on device")
        n = self._real(fd, bytes(data[:left]))
        self.used[name] = self.used.get(name, 0) + n
        return n


def _scan(t: float, r: float = 8.0) -> LaserScan:
    rng = np.random.default_rng(int(t * 1000))
    return LaserScan(-1.0, 0.01, r + 0.01 * rng.standard_normal(201), 10.0, t)


@pytest.fixture
def scans(tmp_path: Path) -> Path:
    log = tmp_path / "scans.alog"
    with LaserLogWriter(log) as w:
        w.declare(0, "tim5xx://test", "tim5xx", "TiM561", LaserMount(0.2), _scan(0.0), "device", 0.0)
        for k in range(60):
            w.write(0, _scan(k / 15.0), k / 15.0, None)  # open ground, a wall 8 m off
    return log


def _run(scans: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str, list]:
    """`agnav run` for 2 s against the fake robot on the replayed scans, localising on them (localisation.csv)
    and recording (recording.rrd)."""
    pytest.importorskip("rerun")
    with FakeRobot() as fr:
        rc = cli.main(["run", "--device", fr.device, "--laser", f"replay:{scans}?x=0.2", "--planner", "him",
                       "--localise", "scan", "--goal", "3,0", "--duration", "2", "--out", str(out), "--no-plot"])
        sps = fr.received_of("AGNAV_DRIVE_SETPOINT")
    got = capsys.readouterr()
    return rc, got.out, got.err, sps


def _ran_to_its_end(rc: int, stdout: str, err: str, sps: list, out: Path) -> dict:
    assert rc == 0 and "Traceback" not in err, err
    assert "duration reached" in stdout, stdout
    assert any(s.speed_mm_s > 0 for s in sps) and sps[-1].speed_mm_s == 0, "driven, then stopped at the end"
    info = json.loads((out / "run_info.json").read_text())
    assert info["end_reason"] == "duration" and info["duration_s"] >= 2.0, info
    return info


def _whole_records(path: Path) -> None:
    """The file ends on a whole record of its kind, and reads back."""
    data = path.read_bytes()
    if path.suffix == ".csv":
        lines = data.decode("utf-8").split("\n")
        assert lines[-1] == "", "ends on a line end"
        width = lines[0].count(",")
        assert len(lines) >= 2 and all(ln.count(",") == width for ln in lines[:-1]), lines
    elif path.suffix == ".alog":
        info = laser_log_info(path)
        assert info.truncated_bytes == 0 and info.lasers, info
        replay = LaserLogReplay(f"replay:{path}?rate=0")
        replay.start()
        got = 0
        while replay.latest() is not None:
            got += 1
        assert got == info.scans[0] and replay.stats.malformed == 0 and not replay.stats.last_error
    else:
        assert data[:4] == b"RRF2"
        at = 12
        while at < len(data):  # one header, then whole messages (kind, length, payload) to the last byte
            kind, length = struct.unpack_from("<QQ", data, at)
            assert kind != 0, "a streamed recording that stopped has no End message"
            at += 16 + length
        assert at == len(data), (at, len(data))
        from rerun.chunk import RrdReader

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rerun: "no footer/manifest" (its index), read whole
            store = RrdReader(path).stream().collect()
        assert "/world/robot" in str(store.summary())


@pytest.mark.parametrize("name, budget", [("trajectory.csv", 700), ("localisation.csv", 300), ("laser.alog", 2000),
                                          ("recording.rrd", 40000)])
def test_agnav_run_on_a_full_disk_goes_on_and_lists_the_cut_file_as_partial(name, budget, scans, tmp_path, monkeypatch,
                                                                             capsys):
    disk = FullDisk(monkeypatch, {name: budget})
    out = tmp_path / "run"
    rc, stdout, err, sps = _run(scans, out, capsys)
    info = _ran_to_its_end(rc, stdout, err, sps, out)
    assert disk.refused.get(name), f"the disk never refused {name}: the test proves nothing"
    path = out / name
    assert err.count(f"{path}: No space left on device") == 1, err  # said once, though later writes kept coming
    assert len(info["output_errors"]) == 1 and str(path) in info["output_errors"][0], info["output_errors"]
    m = re.search(rf"wrote {re.escape(str(path))} partial \((\d+) B\)", stdout)
    assert m, stdout
    size = path.stat().st_size
    assert int(m.group(1)) == size and 0 < size <= budget, (m.group(1), size, budget)
    _whole_records(path)
    for other in STREAMED:  # the others are whole and listed as such
        if other != name:
            assert f"wrote {out / other}\n" in stdout, (other, stdout)
    assert "wrote " + str(out / "summary.json") in stdout and "wrote " + str(out / "run_info.json") in stdout


def test_agnav_run_on_a_disk_full_from_the_first_byte_leaves_no_empty_file(scans, tmp_path, monkeypatch, capsys):
    FullDisk(monkeypatch, {n: 0 for n in STREAMED})
    out = tmp_path / "run"
    rc, stdout, err, sps = _run(scans, out, capsys)
    info = _ran_to_its_end(rc, stdout, err, sps, out)
    for name in STREAMED:
        assert not (out / name).exists(), name
        assert str(out / name) not in stdout, stdout  # not listed as written
        assert err.count(f"{out / name}: No space left on device") == 1, err
    assert len(info["output_errors"]) == 4, info["output_errors"]
    assert all(p.stat().st_size > 0 for p in out.iterdir())


def test_a_stream_file_cuts_back_to_its_last_whole_record_says_so_once_and_drops_the_rest(tmp_path, monkeypatch,
                                                                                          caplog):
    path = tmp_path / "t.csv"
    said: list[str] = []
    f = StreamFile(path, "trajectory", buffer_bytes=100, flush_s=None, on_error=said.append)
    FullDisk(monkeypatch, {"t.csv": 250})  # the third buffer is cut in the middle of a line
    rows = [f"{k},{k * k}\n".encode() * 1 for k in range(200)]
    with caplog.at_level(logging.WARNING, logger="agnav_host"):
        results = [f.write(r) for r in rows]
    res = f.close()
    data = path.read_bytes()
    assert data == b"".join(rows)[: len(data)] and data.endswith(b"\n") and len(data) <= 250
    assert res.partial and res.size_bytes == len(data) and res.records == data.count(b"\n")
    assert res.listing() == f"{path} partial ({len(data)} B)"
    assert results[0] and not results[-1] and f.dropped == 200 - res.records
    assert len(said) == 1 and "No space left on device" in said[0] and f"partial ({len(data)} B)" in said[0]
    assert [r.getMessage() for r in caplog.records] == said


def test_a_stream_file_that_never_wrote_a_whole_record_is_removed(tmp_path, monkeypatch):
    path = tmp_path / "laser.alog"
    f = StreamFile(path, buffer_bytes=1 << 16, flush_s=None)
    FullDisk(monkeypatch, {"laser.alog": 30})
    f.write(b"x" * 20)
    f.write(b"y" * 20)  # the disk takes 30 B: one whole record
    f.flush()
    assert f.close().size_bytes == 20 and path.read_bytes() == b"x" * 20
    g = StreamFile(tmp_path / "laser.alog", flush_s=None)  # truncated, a fresh budget: nothing fits
    monkeypatch.setattr(os, "write", lambda fd, b: (_ for _ in ()).throw(OSError(errno.EIO, "Input/output error")))
    g.write(b"z" * 10)
    res = g.close()
    assert res.partial and not res.kept and not path.exists() and res.error == "Input/output error"


def test_a_whole_streamed_recording_carries_rerun_s_index(tmp_path):
    pytest.importorskip("rerun")
    from agnav_host.link.state import PoseState
    from agnav_host.viz.recorder import Recorder

    path = tmp_path / "r.rrd"
    rec = Recorder.streaming_to(path)
    for i in range(50):
        t = 0.1 * i
        rec.set_time(t)
        rec.log_pose(PoseState(t, 0.05 * i, 0.0, 0.0, 0.5, 0.0, t))
    rec.close()
    assert rec.result is not None and not rec.result.partial and rec.result.size_bytes == path.stat().st_size
    assert not list(tmp_path.glob(".*"))  # no temporary left
    rerun_cli = Path(sys.executable).parent / "rerun"
    if rerun_cli.exists():
        r = subprocess.run([str(rerun_cli), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stdout + r.stderr


def test_a_rerun_stream_in_an_unknown_layout_stops_the_recording_and_says_why(tmp_path, caplog):
    pytest.importorskip("rerun")
    from agnav_host.viz.recorder import Recorder, rrd_messages

    with pytest.raises(ValueError, match="RRF2"):
        rrd_messages(b"RRF9" + bytes(40))
    said: list[str] = []
    rec = Recorder.streaming_to(tmp_path / "r.rrd", on_error=said.append)
    rec._pump(b"RRF2" + bytes(8) + struct.pack("<QQ", 2, 10 ** 9))  # a message longer than the read
    rec.close()
    assert len(said) == 1 and "runs past the piece" in said[0] and "rerun-sdk" in said[0], said
    assert rec.result is not None and rec.result.partial and not (tmp_path / "r.rrd").exists()


def test_agnav_run_whose_summary_cannot_be_written_still_lists_its_streamed_files(scans, tmp_path, monkeypatch, capsys):
    from agnav_host import robot

    def full(path, data):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(robot, "write_atomic", full)
    out = tmp_path / "run"
    rc, stdout, err, sps = _run(scans, out, capsys)
    assert rc == 1 and "Traceback" not in err and "duration reached" in stdout, err
    assert sps[-1].speed_mm_s == 0
    assert "not written: summary.json: No space left on device; run_info.json: No space left on device" in err, err
    for name in STREAMED:  # whole, and listed before the failure is said
        assert f"wrote {out / name}\n" in stdout, stdout
    assert not (out / "summary.json").exists() and not (out / "run_info.json").exists()


def test_agnav_run_on_a_real_full_disk_ends_each_file_on_a_whole_record(scans, capsys):
    """A 64 KiB tmpfs (as root), else a 24 KiB file-size limit (EFBIG): whichever files the disk refuses, the run
    drives to its end and every file left is whole records, listed, partial ones with their size."""
    import resource
    import signal

    from agnav_host.faults.host_faults import full_disk

    with full_disk(64) as (d, how):
        old, old_sig = resource.getrlimit(resource.RLIMIT_FSIZE), signal.getsignal(signal.SIGXFSZ)
        if how == "rlimit":
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (24 * 1024, old[1]))
        try:
            rc, stdout, err, sps = _run(scans, d / "run", capsys)
        finally:
            if how == "rlimit":
                resource.setrlimit(resource.RLIMIT_FSIZE, old)
                signal.signal(signal.SIGXFSZ, old_sig)
        assert rc in (0, 1) and "Traceback" not in err and "duration reached" in stdout, (how, err)
        assert sps[-1].speed_mm_s == 0
        partial = dict(re.findall(r"wrote (\S+) partial \((\d+) B\)", stdout))
        assert partial, (how, stdout, err)  # the disk did refuse something
        for name in STREAMED:
            p = d / "run" / name
            if p.exists():
                assert p.stat().st_size > 0 and f"wrote {p}" in stdout, (name, stdout)
                if str(p) in partial:
                    assert int(partial[str(p)]) == p.stat().st_size
                _whole_records(p)
            else:
                assert f"wrote {p}" not in stdout
            assert err.count(f"{p}: ") <= 1, err  # said once at most
