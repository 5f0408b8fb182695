"""The laser log (.alog): writing, streaming reads, damage, replay as a laser source, and `agnav rows` on it."""

from __future__ import annotations

import json
import math
import struct
import time
import tracemalloc

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.lasers import (LaserAddressError, LaserMount, LaserSource, LaserUrlError, TelegramError,
                               WrongDeviceError, open_laser)
from agnav_host.lasers.log import (MAGIC, LaserLogError, LaserLogWriter, NotALaserLogError, laser_log_info,
                                   read_laser_log)
from agnav_host.scanio import save_scan_csv
from agnav_host.types import LaserScan, Pose2D

ROW_KEYS = {"lateral_offset_m", "heading_rad", "row_spacing_m", "confidence", "end_of_row"}
MOUNT0 = LaserMount(0.2, 0.0, 0.0)
MOUNT1 = LaserMount(-0.3, 0.1, math.pi, 0.3, 0.5)


def _scan(n: int, a0: float = -2.0, inc: float = 0.01, value: float = 1.5, rmax: float = 10.0) -> LaserScan:
    return LaserScan(a0, inc, np.full(n, value), rmax)


def _two_laser_log(path, n0: int = 5, n1: int = 4, dt: float = 0.1):
    """Laser 0 (TiM-like, 11 beams) at 0, dt, 2 dt, ... and laser 1 (tilted, 3 beams) between them."""
    with LaserLogWriter(path) as w:
        w.declare(0, "tim5xx://192.168.0.1", "tim5xx", "TiM561", MOUNT0, _scan(11), "device", 0.002)
        w.declare(1, "urg:/dev/ttyACM0", "urg", "URG-04LX", MOUNT1, _scan(3, -0.5, 0.5, rmax=math.inf), "arrival", 0.01)
        for k in range(max(n0, n1)):
            if k < n0:
                w.write(0, _scan(11, value=1.0 + k), 1.0 + k * dt, Pose2D(k, 0.5, 0.1))
            if k < n1:
                w.write(1, _scan(3, -0.5, 0.5, value=2.0 + k, rmax=math.inf), 1.0 + (k + 0.5) * dt)
    return path


# ---- writing and reading --------------------------------------------------------------------------------------


def test_round_trip_several_lasers_geometry_change_poses_and_no_returns(tmp_path):
    path = tmp_path / "run.alog"
    ranges = np.array([1.2344, math.nan, 0.0, math.inf, -1.0, 70.0, 65.5349, 65.534, 0.0004, 3.0])
    with LaserLogWriter(path) as w:
        w.declare(0, "tim5xx://10.0.0.1", "tim5xx", "TiM561", MOUNT0, _scan(10, -2.35, 0.0058), "device", 0.002)
        w.declare(1, "rplidar:/dev/ttyUSB0", "rplidar", "A2", MOUNT1, _scan(4, 0.0, math.pi / 2, rmax=math.inf))
        w.write(0, LaserScan(-2.35, 0.0058, ranges, 10.0), 0.25, Pose2D(1.0, 2.0, math.pi / 2))
        w.write(1, _scan(4, 0.0, math.pi / 2, 4.0, math.inf), 0.3, None)
        w.write(0, LaserScan(-2.35, 0.0058, ranges, 10.0), 0.35, Pose2D(math.nan, 0.0, 0.0))  # unknown pose
        w.write(0, _scan(5, -1.0, 0.5, 2.0, 8.0), 0.45, Pose2D(1.5, 2.0, 0.0))  # a new mode: re-declared
        w.declare(1, "rplidar:/dev/ttyUSB0", "rplidar", "A2", LaserMount(0.4), _scan(2, 0.0, 1.0))
        w.write(1, _scan(2, 0.0, 1.0, 3.0), 0.5, Pose2D(2.0, 2.0, 0.0))
        assert w.scans_written == 5
    recs = list(read_laser_log(path))
    assert [(r.laser_id, r.t_s) for r in recs] == [(0, 0.25), (1, 0.3), (0, 0.35), (0, 0.45), (1, 0.5)]
    first = recs[0]
    got = first.scan.ranges_m
    np.testing.assert_allclose(got[[0, 7, 9]], [1.234, 65.534, 3.0], atol=5e-4)
    assert np.isnan(got[[1, 2, 3, 4, 5, 6, 8]]).all()  # NaN, 0, inf, negative, >= 65.535 m, < 0.5 mm
    assert first.scan.stamp_s == 0.25 and first.scan.range_max_m == 10.0
    assert (first.scan.angle_min_rad, first.scan.angle_increment_rad) == (-2.35, 0.0058)
    assert first.pose == Pose2D(1.0, 2.0, math.pi / 2)
    assert first.scan.pose.x_m == pytest.approx(1.0) and first.scan.pose.y_m == pytest.approx(2.2)  # sensor pose
    assert first.laser.url == "tim5xx://10.0.0.1" and first.laser.stamps == "device" and first.laser.latency_s == 0.002
    assert first.laser.mount == MOUNT0
    assert recs[1].pose is None and recs[1].scan.pose is None and recs[1].laser.mount == MOUNT1
    assert recs[1].scan.range_max_m == math.inf and recs[1].laser.model == "A2"
    assert recs[2].pose is None  # a non-finite pose is written as unknown
    assert recs[3].laser.n_beams == 5 and recs[3].laser.range_max_m == 8.0 and recs[3].laser.mount == MOUNT0
    assert recs[3].laser.url == "tim5xx://10.0.0.1"  # the re-declaration keeps the laser's identity
    assert recs[4].laser.mount == LaserMount(0.4) and len(recs[4].scan.ranges_m) == 2
    info = laser_log_info(path)
    assert list(info.lasers) == [0, 1] and info.first_laser == 0
    assert info.scans == {0: 3, 1: 2} and len(info.declarations) == 4
    assert info.span_s == {0: (0.25, 0.45), 1: (0.3, 0.5)}
    assert (info.t_first_s, info.t_last_s, info.truncated_bytes) == (0.25, 0.5, 0)
    assert [r.t_s for r in read_laser_log(path, laser_id=1)] == [0.3, 0.5]


def test_the_file_starts_with_the_header_and_documented_records(tmp_path):
    path = _two_laser_log(tmp_path / "h.alog", 1, 0)
    data = path.read_bytes()
    assert data.startswith(b"# agnav-laserlog v1\n") and MAGIC == b"# agnav-laserlog v1\n"
    tag, length = struct.unpack_from("<4sI", data, len(MAGIC))
    assert tag == b"LASR"
    decl = json.loads(data[len(MAGIC) + 8:len(MAGIC) + 8 + length])
    assert set(decl) == {"id", "url", "kind", "model", "mount", "angle_min_rad", "angle_increment_rad", "n_beams",
                         "range_max_m", "stamps", "latency_s"}
    assert set(decl["mount"]) == {"x_m", "y_m", "yaw_rad", "pitch_rad", "height_m"}
    at = len(MAGIC) + 8 + length
    tag, length = struct.unpack_from("<4sI", data, at)
    assert tag == b"LASR"  # laser 1's declaration, then laser 0's scan
    at += 8 + length
    tag, length = struct.unpack_from("<4sI", data, at)
    assert tag == b"SCAN" and length == 14 + 2 * 11 + 1 + 24
    lid, t, n = struct.unpack_from("<HdI", data, at + 8)
    assert (lid, t, n) == (0, 1.0, 11)
    assert struct.unpack_from("<H", data, at + 8 + 14)[0] == 1000  # 1.0 m in mm
    assert data[at + 8 + 14 + 22] == 1 and struct.unpack_from("<ddd", data, at + 8 + 37) == (0.0, 0.5, 0.1)


def test_writer_flushes_within_half_a_second_of_scans(tmp_path):
    path = tmp_path / "live.alog"
    w = LaserLogWriter(path)
    w.declare(0, "ust://1.2.3.4", "ust", "UST-10LX", MOUNT0, _scan(100))
    for k in range(8):  # 0.0 .. 0.7 s of scans, the file left open
        w.write(0, _scan(100), 0.1 * k)
    seen = [r.t_s for r in read_laser_log(path)]
    assert len(seen) >= 6  # everything up to at least 0.5 s is on disk
    w.close()
    w.close()  # idempotent
    assert len(list(read_laser_log(path))) == 8
    with pytest.raises(ValueError, match="closed"):
        w.write(0, _scan(100), 1.0)


def test_writer_refuses_an_undeclared_laser_and_bad_values(tmp_path):
    with LaserLogWriter(tmp_path / "w.alog") as w:
        with pytest.raises(ValueError, match="before it was declared"):
            w.write(3, _scan(4), 0.0)
        with pytest.raises(ValueError, match="0..65535"):
            w.declare(70000, "x", "ust", "", MOUNT0, _scan(4))
        w.declare(0, "x", "ust", "", MOUNT0, _scan(4))
        with pytest.raises(ValueError, match="finite"):
            w.write(0, _scan(4), math.nan)


def test_writer_truncates_an_existing_file(tmp_path):
    path = _two_laser_log(tmp_path / "again.alog")
    with LaserLogWriter(path) as w:
        w.declare(7, "x", "ust", "", MOUNT0, _scan(4))
    info = laser_log_info(path)
    assert list(info.lasers) == [7] and info.scans == {7: 0}


def test_streaming_read_of_a_large_log_stays_bounded(tmp_path):
    path = tmp_path / "big.alog"
    n_scans, n_beams = 4000, 811
    base = np.linspace(0.5, 9.5, n_beams)
    tracemalloc.start()
    try:
        with LaserLogWriter(path) as w:
            w.declare(0, "tim5xx://10.0.0.1", "tim5xx", "TiM561", MOUNT0, LaserScan(-2.35, 0.0058, base, 10.0))
            for k in range(n_scans):
                w.write(0, LaserScan(-2.35, 0.0058, base, 10.0), k / 15.0, Pose2D(0.01 * k, 0.0, 0.0))
        _, write_peak = tracemalloc.get_traced_memory()
        assert path.stat().st_size > 6_000_000
        tracemalloc.reset_peak()
        count, total = 0, 0.0
        for rec in read_laser_log(path):
            count += 1
            total += float(rec.scan.ranges_m[10])
        _, read_peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert count == n_scans and total == pytest.approx(n_scans * round(base[10], 3))
    assert write_peak < 1_000_000 and read_peak < 1_000_000, (write_peak, read_peak)


# ---- damage --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("keep", [1, 7, 8, 12, 30, -1])
def test_a_truncated_last_record_is_ignored_and_counted(tmp_path, keep):
    path = _two_laser_log(tmp_path / "cut.alog", 3, 0)
    data = path.read_bytes()
    last = len(data) - (8 + 14 + 22 + 25)  # the last SCAN record
    keep = 8 + 14 + 22 + 24 if keep == -1 else keep  # -1: all but the pose's last byte
    path.write_bytes(data[:last + keep])
    reader = read_laser_log(path)
    assert [r.t_s for r in reader] == [1.0, 1.1]
    assert reader.truncated == 1 and reader.truncated_bytes == keep
    assert laser_log_info(path).truncated_bytes == keep


def _record(tag: bytes, payload: bytes) -> bytes:
    return struct.pack("<4sI", tag, len(payload)) + payload


def _decl(lid: int = 0, n: int = 3, **over) -> bytes:
    d = {"id": lid, "url": "ust://x", "kind": "ust", "model": "", "angle_min_rad": -1.0, "angle_increment_rad": 1.0,
         "mount": {"x_m": 0.0, "y_m": 0.0, "yaw_rad": 0.0, "pitch_rad": 0.0, "height_m": 0.0}, "n_beams": n,
         "range_max_m": 10.0, "stamps": "arrival", "latency_s": 0.0, **over}
    return _record(b"LASR", json.dumps(d).encode())


def _scan_rec(lid: int = 0, n: int = 3, t: float = 0.0, tail: bytes = b"\x00") -> bytes:
    return _record(b"SCAN", struct.pack("<HdI", lid, t, n) + b"\x10\x00" * n + tail)


GOOD = _decl() + _scan_rec()


@pytest.mark.parametrize("body, words", [
    (GOOD + _record(b"JUNK", b"1234"), "unknown record tag 'JUNK'"),
    (GOOD + _record(b"LASR", b"{not json"), "not UTF-8 JSON"),
    (GOOD + _decl(n=0), "n_beams must be a whole number >= 1"),
    (GOOD + _decl(stamps="gps"), "stamps must be"),
    (GOOD + _record(b"LASR", json.dumps({"id": 0}).encode()), "lacks url"),
    (GOOD + _scan_rec(n=4), "has 4 beams, its declaration (byte 20) says 3"),
    (GOOD + _scan_rec(lid=2), "SCAN of laser 2 before its LASR declaration"),
    (GOOD + _scan_rec(tail=b"\x02"), "pose flag 2"),
    (GOOD + _scan_rec(tail=b"\x00\x00\x00"), "does not fit 3 beams"),
    (GOOD + _record(b"SCAN", b"\x00" * 5), "shorter than its 14-byte header"),
    (GOOD + _scan_rec(t=math.inf), "non-finite stamp"),
])
def test_each_corruption_names_the_file_and_the_offset(tmp_path, body, words):
    path = tmp_path / "bad.alog"
    path.write_bytes(MAGIC + body)
    offset = len(MAGIC) + len(GOOD)
    with pytest.raises(LaserLogError) as e:
        list(read_laser_log(path))
    assert e.value.offset == offset and not isinstance(e.value, NotALaserLogError)
    assert str(e.value).startswith(f"{path}: byte {offset}: ") and words in str(e.value)
    with pytest.raises(LaserLogError, match=f"byte {offset}"):
        laser_log_info(path)


def test_a_corrupt_record_with_scans_before_it_yields_those_first(tmp_path):
    path = tmp_path / "late.alog"
    path.write_bytes(MAGIC + GOOD + _scan_rec(t=0.1) + b"\xff\xff\xff\xff\x00\x00\x00\x00")
    reader = read_laser_log(path)
    assert next(reader).t_s == 0.0 and next(reader).t_s == 0.1
    with pytest.raises(LaserLogError, match="unknown record tag 'ff ff ff ff'"):
        next(reader)


@pytest.mark.parametrize("content, words", [
    (b"", "an empty file"),
    (b"# agnav-scan v1\n# stamp_s=0.0\nangle_rad,range_m\n0.0,1.0\n", "a one-scan CSV (agnav-scan v1)"),
    (bytes(range(256)) * 4, "binary data starting 00 01 02 03"),
    (b"hello, world\n", "text starting 'hello, world'"),
    (b"# agnav-laserlog v2\n", "version v2"),
    (b"# agnav-laserlog v1\r\nLASR", "CR LF"),
    (MAGIC[:9], "cut off in its header line"),
])
def test_files_that_are_no_laser_log_say_what_they_are(tmp_path, content, words):
    path = tmp_path / "other.alog"
    path.write_bytes(content)
    with pytest.raises(NotALaserLogError) as e:
        read_laser_log(path)
    assert str(e.value).startswith(f"{path}: ") and words in str(e.value)


# ---- replay --------------------------------------------------------------------------------------------------


def test_replay_is_a_laser_source_with_the_logged_laser(tmp_path):
    path = _two_laser_log(tmp_path / "r.alog")
    src = open_laser(f"replay:{path}")
    assert isinstance(src, LaserSource)
    info = src.start()
    assert (info.kind, info.address, info.model, info.stamps, info.latency_s) == ("replay", str(path), "TiM561",
                                                                                 "device", 0.002)
    assert info.scan_hz == pytest.approx(10.0)
    assert src.mount == MOUNT0  # the logged mount: none was given
    assert src.start() is info
    src.close()
    src.close()
    assert src.latest() is None and src.finished


def test_replay_rate_0_gives_the_next_scan_on_every_call(tmp_path):
    path = _two_laser_log(tmp_path / "r0.alog", n0=5)
    src = open_laser(f"replay:{path}?rate=0")
    src.start()
    before = time.monotonic()
    scans = [src.latest() for _ in range(5)]
    after = time.monotonic()
    assert [float(s.ranges_m[0]) for s in scans] == [1.0, 2.0, 3.0, 4.0, 5.0]
    stamps = [s.stamp_s for s in scans]
    assert before <= stamps[0] and stamps == sorted(stamps) and stamps[-1] <= after  # the time of each call
    assert all(s.pose is None for s in scans)
    assert src.last_log_t_s == pytest.approx(1.4)
    assert src.finished and src.stats.scans == 5 and src.stats.dropped == 0
    assert src.latest() is None and src.wait(0.1) is None and src.finished


def test_replay_rate_10_spaces_the_stamps_by_the_log_spacing_over_the_rate(tmp_path):
    path = _two_laser_log(tmp_path / "r10.alog", n0=6, dt=0.1)
    src = open_laser(f"replay:{path}?rate=10")
    t_start = time.monotonic()
    src.start()
    first = src.latest()  # due at once
    assert first is not None and first.stamp_s == pytest.approx(t_start, abs=0.05)
    assert src.latest() is None  # the next one is 10 ms away
    scans = [first]
    deadline = time.monotonic() + 2.0
    while not src.finished and time.monotonic() < deadline:
        s = src.wait(0.5)
        if s is not None:
            assert s.stamp_s <= time.monotonic()  # never delivered before its stamp
            scans.append(s)
    assert src.finished and src.latest() is None
    stamps = np.array([s.stamp_s for s in scans])
    assert len(scans) + src.stats.dropped == 6
    np.testing.assert_allclose(np.diff(stamps), 0.01 * np.diff([float(s.ranges_m[0]) for s in scans]), atol=1e-9)


def test_replay_rate_1_keeps_only_the_newest_when_the_caller_is_late(tmp_path):
    path = _two_laser_log(tmp_path / "late.alog", n0=5, dt=0.02)
    src = open_laser(f"replay:{path}")
    src.start()
    time.sleep(0.07)  # scans at 0, 20, 40, 60 ms are due
    s = src.latest()
    assert float(s.ranges_m[0]) == 4.0 and src.stats.dropped == 3 and src.stats.scans == 4
    assert not src.finished
    src.close()
    assert src.finished and src.latest() is None


def test_replay_chooses_laser_1_and_an_explicit_mount_overrides_the_log(tmp_path):
    path = _two_laser_log(tmp_path / "l1.alog", n0=5, n1=4)
    src = open_laser(f"replay:{path}?laser=1&rate=0")
    info = src.start()
    assert info.model == "URG-04LX" and info.stamps == "arrival" and src.mount == MOUNT1
    got = []
    while (s := src.latest()) is not None:
        got.append(s)
    assert [float(s.ranges_m[0]) for s in got] == [2.0, 3.0, 4.0, 5.0] and all(len(s.ranges_m) == 3 for s in got)
    assert got[0].range_max_m == math.inf
    mine = LaserMount(1.0, 0.0, 0.0)
    src2 = open_laser(f"replay:{path}?laser=1&rate=0", mine)
    src2.start()
    assert src2.mount == mine and float(src2.latest().ranges_m[0]) == 2.0 and src2.mount == mine
    src2.close()


def test_replay_mount_follows_a_re_declaration(tmp_path):
    path = tmp_path / "redecl.alog"
    with LaserLogWriter(path) as w:
        w.declare(0, "ust://x", "ust", "", MOUNT0, _scan(4))
        w.write(0, _scan(4), 0.0)
        w.declare(0, "ust://x", "ust", "", LaserMount(0.5), _scan(6))
        w.write(0, _scan(6), 0.1)
    src = open_laser(f"replay:{path}?rate=0")
    src.start()
    assert len(src.latest().ranges_m) == 4 and src.mount == MOUNT0
    assert len(src.latest().ranges_m) == 6 and src.mount == LaserMount(0.5)


def test_replay_of_the_wrong_files_raises_the_right_errors(tmp_path):
    with pytest.raises(LaserAddressError, match="nope.alog"):
        open_laser(f"replay:{tmp_path / 'nope.alog'}").start()
    csv = save_scan_csv(_scan(5), tmp_path / "one.csv")
    with pytest.raises(WrongDeviceError, match="one-scan CSV"):
        open_laser(f"replay:{csv}").start()
    noise = tmp_path / "noise.alog"
    noise.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(WrongDeviceError, match="binary data"):
        open_laser(f"replay:{noise}").start()
    bad = tmp_path / "bad.alog"
    bad.write_bytes(MAGIC + GOOD + _scan_rec(n=5))
    with pytest.raises(TelegramError, match=f"byte {len(MAGIC) + len(GOOD)}"):
        open_laser(f"replay:{bad}").start()
    good = _two_laser_log(tmp_path / "good.alog")
    with pytest.raises(LaserAddressError, match="no laser 5 in the log; it declares 0, 1"):
        open_laser(f"replay:{good}?laser=5").start()
    empty = tmp_path / "empty.alog"
    empty.write_bytes(MAGIC)
    with pytest.raises(LaserAddressError, match="declares no laser"):
        open_laser(f"replay:{empty}").start()
    for url in (f"replay:{good}?rate=-1", f"replay:{good}?rate=fast", f"replay:{good}?laser=first",
                f"replay:{good}?speed=2"):
        with pytest.raises(LaserUrlError):
            open_laser(url)


def test_replay_of_a_log_with_a_cut_off_tail_plays_what_is_whole(tmp_path):
    path = _two_laser_log(tmp_path / "cut.alog", 3, 0)
    path.write_bytes(path.read_bytes()[:-10])
    src = open_laser(f"replay:{path}?rate=0")
    src.start()
    assert src.truncated_bytes > 0 and "cut-off" in src.stats.last_error
    assert [src.latest() is not None for _ in range(3)] == [True, True, False] and src.finished


# ---- agnav rows on a log -------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rows_log(tmp_path_factory):
    """Twelve scans of the crop_rows scenario's TiM561 (0.2 m ahead of the reference point) driving its middle
    lane, the robot weaving a few cm about the centre line; returns (log path, true offsets, true headings)."""
    from agnav_host.sim.scenario import load_scenario

    sc = load_scenario("crop_rows")
    assert sc.laser is not None
    rng = np.random.default_rng(3)
    centre = sc.start.y_m
    path = tmp_path_factory.mktemp("rows") / "rows.alog"
    offsets, headings = [], []
    mount = LaserMount(sc.laser.mount.x_m, sc.laser.mount.y_m, sc.laser.mount.yaw_rad)
    with LaserLogWriter(path) as w:
        for k in range(12):
            pose = Pose2D(0.5 + 0.25 * k, centre + 0.05 * math.sin(k), 0.03 * math.cos(k))
            scan = sc.laser.scan(sc.world, pose, k / 15.0, rng)
            if k == 0:
                w.declare(0, "replay:sim", "sim", sc.laser.spec.name, mount, scan, "device", 0.0)
            w.write(0, scan, k / 15.0, pose)
            offsets.append(pose.y_m - centre)
            headings.append(pose.yaw_rad)
    return path, offsets, headings


def test_rows_json_on_a_laser_log_gives_one_line_per_scan(rows_log, capsys):
    path, offsets, headings = rows_log
    assert main(["rows", "--scan", str(path), "--json"]) == 0
    captured = capsys.readouterr()
    lines = [json.loads(x) for x in captured.out.splitlines()]
    assert len(lines) == 12 and captured.err == ""
    for k, (row, off, hdg) in enumerate(zip(lines, offsets, headings)):
        assert set(row) == ROW_KEYS | {"index", "t_s"}
        assert row["index"] == k and row["t_s"] == pytest.approx(k / 15.0)
        assert row["lateral_offset_m"] == pytest.approx(off, abs=0.03)
        assert row["heading_rad"] == pytest.approx(hdg, abs=0.03)
        assert row["row_spacing_m"] == pytest.approx(0.7, abs=0.1) and row["confidence"] > 0.5
        assert row["end_of_row"] is False


def test_rows_on_one_scan_of_a_log_and_human_output(rows_log, capsys, tmp_path):
    path, offsets, _ = rows_log
    assert main(["rows", "--scan", str(path), "--index", "3", "--json"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["index"] == 3
    assert json.loads(lines[0])["lateral_offset_m"] == pytest.approx(offsets[3], abs=0.03)
    assert main(["rows", "--scan", str(path), "--index", "2"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("scan 2 t=0.133 s: method ransac: offset ") and "robot left of centre" in out
    renamed = tmp_path / "rows.bin"  # a log is known by its first line too
    renamed.write_bytes(path.read_bytes())
    assert main(["rows", "--scan", str(renamed), "--json", "--method", "lsq"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 12


def test_rows_mount_option_overrides_the_logged_mount(rows_log, capsys):
    path, _, _ = rows_log
    assert main(["rows", "--scan", str(path), "--index", "0", "--json"]) == 0
    logged = json.loads(capsys.readouterr().out)
    assert main(["rows", "--scan", str(path), "--index", "0", "--json", "--mount", "0.2,0,0"]) == 0
    assert json.loads(capsys.readouterr().out) == logged
    assert main(["rows", "--scan", str(path), "--index", "0", "--json", "--mount", "0,0,0"]) == 0
    assert json.loads(capsys.readouterr().out) != logged


def test_rows_on_bad_logs_and_options_exits_2_with_one_line(rows_log, tmp_path, capsys):
    path, _, _ = rows_log
    bad = tmp_path / "bad.alog"
    bad.write_bytes(MAGIC + GOOD + _scan_rec(t=0.1) + _record(b"JUNK", b""))
    csv = save_scan_csv(_scan(5), tmp_path / "one.csv")
    fake = tmp_path / "fake.alog"
    fake.write_bytes(csv.read_bytes())
    cases = [
        (["--scan", str(bad)], f"{bad}: byte {len(MAGIC) + len(GOOD) + len(_scan_rec())}: unknown record tag"),
        (["--scan", str(fake)], "a one-scan CSV (agnav-scan v1), not a laser log"),
        (["--scan", str(tmp_path / "gone.alog")], "cannot read laser log"),
        (["--scan", str(path), "--laser-id", "4"], "--laser-id 4: no such laser in the log; it declares 0"),
        (["--scan", str(path), "--index", "12"], "--index 12: laser 0 has 12 scans (index 0..11)"),
        (["--scan", str(csv), "--index", "0"], "--index reads a laser log"),
    ]
    for argv, words in cases:
        assert main(["rows", *argv, "--json"]) == 2, argv
        captured = capsys.readouterr()
        assert captured.out == "" and words in captured.err, (argv, captured.err)
        assert captured.err.count("\n") == 1 and "Traceback" not in captured.err


def test_rows_on_a_log_without_returns_and_with_a_cut_off_tail(tmp_path, capsys):
    blank = tmp_path / "blank.alog"
    with LaserLogWriter(blank) as w:
        w.declare(0, "ust://x", "ust", "", MOUNT0, _scan(50, value=math.nan))
        for k in range(3):
            w.write(0, _scan(50, value=math.nan), 0.1 * k)
    assert main(["rows", "--scan", str(blank), "--json"]) == 3
    captured = capsys.readouterr()
    rows = [json.loads(x) for x in captured.out.splitlines()]
    assert len(rows) == 3 and all(r["lateral_offset_m"] is None and r["confidence"] == 0.0 for r in rows)
    assert "none of the 3 scans of laser 0" in captured.err
    cut = tmp_path / "cut.alog"
    cut.write_bytes(blank.read_bytes()[:-5])
    assert main(["rows", "--scan", str(cut), "--json"]) == 3
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 2 and "ignored a cut-off last record" in captured.err


def test_rows_shows_progress_on_a_terminal_for_a_long_log(tmp_path, capsys, monkeypatch):
    import sys

    long_log = tmp_path / "long.alog"
    with LaserLogWriter(long_log) as w:
        w.declare(0, "ust://x", "ust", "", MOUNT0, _scan(20, value=math.nan))
        for k in range(250):
            w.write(0, _scan(20, value=math.nan), 0.04 * k)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    monkeypatch.setattr(sys.stdout, "isatty", lambda: False)
    assert main(["rows", "--scan", str(long_log), "--json"]) == 3
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 250
    assert "\ragnav rows: scan 1/250 (0%)" in captured.err and captured.err.count("\n") == 1
