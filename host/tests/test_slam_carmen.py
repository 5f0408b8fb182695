"""The CARMEN log reader: the scan messages, odometry (own fields, interpolated ODOM, a g2o graph's edges),
and what it does with garbage lines, missing odometry and a truncated file."""

from __future__ import annotations

import math
import zipfile

import numpy as np
import pytest

from agnav_host.localisation.carmen import (
    FLASER_RANGE_MAX_M,
    CarmenLogError,
    looks_like_carmen,
    parse_carmen_lines,
    read_carmen_log,
)

R180 = " ".join(["2.50"] * 178 + ["81.90", "0.00"])  # the last two beams: no return


def flaser(t: str, odom: str = "1.0 2.0 0.5", laser: str | None = None) -> str:
    return f"FLASER 180 {R180} {laser or odom} {odom} {t} nohost 12.5"


def robotlaser(t: str, laser: str = "1.0 2.0 0.5", robot: str = "1.0 2.0 0.5", n: int = 5) -> str:
    ranges = " ".join(["3.0"] * (n - 1) + ["50.0"])
    return (f"ROBOTLASER1 0 -1.570796 3.141593 0.785398 50.000000 0.1 0 {n} {ranges} 0 {laser} {robot} "
            f"0 0 0 0 0 {t} host 606.86")


def test_flaser_line_gives_beams_geometry_odometry_and_the_stamp_as_written():
    log = parse_carmen_lines([flaser("1031745824.658000")])
    (s,) = log.scans
    assert s.t_text == "1031745824.658000" and s.t_s == pytest.approx(1031745824.658)
    assert s.angle_min_rad == pytest.approx(-math.pi / 2) and s.angle_increment_rad == pytest.approx(math.pi / 180)
    assert len(s.ranges_m) == 180 and s.ranges_m[0] == 2.5
    assert np.isnan(s.ranges_m[-2:]).all(), f"81.9 m is beyond {FLASER_RANGE_MAX_M} m, 0 is no return"
    assert (s.odom.x_m, s.odom.y_m, s.odom.yaw_rad) == (1.0, 2.0, 0.5)
    assert s.mount.x_m == pytest.approx(0.0) and s.mount.yaw_rad == pytest.approx(0.0)


def test_flaser_laser_pose_ahead_of_the_robot_gives_the_mount():
    log = parse_carmen_lines([flaser("5.0", odom="1.0 2.0 1.5707963", laser="1.0 2.3 1.5707963")])
    m = log.scans[0].mount
    assert m.x_m == pytest.approx(0.3, abs=1e-6) and m.y_m == pytest.approx(0.0, abs=1e-6)


def test_robotlaser_line_uses_its_own_geometry_and_range_limit():
    (s,) = parse_carmen_lines([robotlaser("7.25")]).scans
    assert s.angle_min_rad == pytest.approx(-1.570796) and s.angle_increment_rad == pytest.approx(0.785398)
    assert s.range_max_m == 50.0 and np.isnan(s.ranges_m[-1]) and s.ranges_m[0] == 3.0
    assert s.t_text == "7.25"


def test_garbage_lines_are_skipped_and_counted_with_their_line_numbers():
    lines = [flaser("1.0"), "hello world", "FLASER 180 1 2 3", "\x00\x01binary", flaser("2.0"),
             "FLASER abc", "ODOM 1 2 x 0 0 0 3.0 host 1.0", flaser("3.0")]
    log = parse_carmen_lines(lines)
    assert [s.t_text for s in log.scans] == ["1.0", "2.0", "3.0"]
    assert log.skipped == 5
    assert [s.line for s in log.skip_examples] == [2, 3, 4, 6, 7]
    assert "180 beams need 191 fields" in log.skip_examples[1].why
    assert "skipped 5 bad lines" in log.summary()


def test_other_messages_are_counted_as_ignored_not_as_bad():
    log = parse_carmen_lines(["PARAM robot_length 0.5 host 0", "SYNC a b", "TRUEPOS 1 2 3 4 5 6 7 h 8", flaser("1.0")])
    assert log.skipped == 0 and log.ignored == {"PARAM": 1, "SYNC": 1, "TRUEPOS": 1}


def test_scan_with_non_finite_odometry_has_none():
    log = parse_carmen_lines([flaser("1.0", odom="nan nan nan"), flaser("2.0")])
    assert log.scans[0].odom is None and log.scans[1].odom is not None
    assert log.without_odometry == 1 and "1 scans without odometry" in log.summary()


def test_rawlaser_scans_take_odometry_interpolated_from_odom_lines():
    raw = "RAWLASER1 0 -1.570796 3.141593 0.785398 50.0 0.1 0 5 1 1 1 1 1 0 {t} host 0"
    lines = ["ODOM 0 0 0 0 0 0 10.0 host 0", raw.format(t="10.5"), "ODOM 1 2 0.2 0 0 0 11.0 host 0",
             raw.format(t="12.0")]
    log = parse_carmen_lines(lines)
    a, b = log.scans
    assert (a.odom.x_m, a.odom.y_m, a.odom.yaw_rad) == pytest.approx((0.5, 1.0, 0.1))
    assert b.odom is None, "after the last ODOM line: no odometry, not an extrapolation"


def test_rawlaser_scans_without_any_odom_line_have_no_odometry():
    raw = "RAWLASER1 0 -1.570796 3.141593 0.785398 50.0 0.1 0 5 1 1 1 1 1 0 {t} host 0"
    log = parse_carmen_lines([raw.format(t="1"), raw.format(t="2")])
    assert len(log.scans) == 2 and log.without_odometry == 2


def test_truncated_file_reads_every_whole_line_and_names_the_cut_one(tmp_path):
    full = "\n".join([flaser("1.0"), flaser("2.0"), flaser("3.0")])
    p = tmp_path / "cut.log"
    p.write_text(full[: len(full) - 400], encoding="utf-8")  # ends inside the third line
    log = read_carmen_log(p)
    assert [s.t_text for s in log.scans] == ["1.0", "2.0"]
    assert log.skipped == 1 and "truncated" in log.skip_examples[0].why and log.skip_examples[0].line == 3


def test_file_without_scans_is_an_error_naming_what_it_found(tmp_path):
    p = tmp_path / "odom_only.log"
    p.write_text("ODOM 0 0 0 0 0 0 1.0 host 0\nrubbish here\n", encoding="utf-8")
    with pytest.raises(CarmenLogError, match="no laser scan.*skipped 1 bad line"):
        read_carmen_log(p)


def test_binary_file_is_an_error(tmp_path):
    p = tmp_path / "bin.log"
    p.write_bytes(b"FLASER\x00\x00\x01\x02" * 10)
    with pytest.raises(CarmenLogError, match="binary"):
        read_carmen_log(p)


def test_zip_archive_holding_one_log_is_read(tmp_path):
    p = tmp_path / "log.zip"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("inner/killian.log", "\n".join([flaser("1.0"), flaser("2.0")]) + "\n")
    assert len(read_carmen_log(p).scans) == 2


def test_g2o_graph_odometry_comes_from_its_sequential_edges_not_its_vertices():
    lines = []
    for k in range(4):
        lines.append(f"VERTEX_SE2 {k} {10.0 + k} 5.0 0.0")  # the graph's estimate: not odometry
        lines.append(robotlaser(f"{k}.5", laser=f"{10.0 + k} 5.0 0.0", robot=f"{10.0 + k} 5.0 0.0"))
    for k in range(3):
        lines.append(f"EDGE_SE2 {k} {k + 1} 0.5 0 0.1 500 0 0 500 0 5000")
    lines.append("EDGE_SE2 0 3 9 9 0 500 0 0 500 0 5000")  # a loop edge: not used
    log = parse_carmen_lines(lines)
    odo = [(s.odom.x_m, s.odom.y_m, s.odom.yaw_rad) for s in log.scans]
    assert odo[0] == pytest.approx((10.0, 5.0, 0.0))
    assert odo[1] == pytest.approx((10.5, 5.0, 0.1))
    assert odo[2][2] == pytest.approx(0.2) and odo[3][2] == pytest.approx(0.3)
    assert "sequential EDGE_SE2" in log.odometry_source
    assert log.ignored == {"VERTEX_SE2": 4, "EDGE_SE2": 4} and log.skipped == 0


def test_looks_like_carmen_tells_logs_from_other_text():
    assert looks_like_carmen(b"# CARMEN Logfile\nPARAM a b\n")
    assert looks_like_carmen(flaser("1").encode())
    assert not looks_like_carmen(b"t,x,y\n1,2,3\n")
    assert not looks_like_carmen(b"")


def test_a_cut_robotlaser_or_rawlaser_line_names_the_fields_a_whole_one_has():
    whole = robotlaser("7.25", n=5).split()
    assert len(whole) == 5 + 10 + 14
    log = parse_carmen_lines([" ".join(whole[:12]), "RAWLASER1 0 -1.57 3.14 0.78 50 0.1 0 5 3 3"])
    assert log.skipped == 2
    assert "5 beams need at least 29 fields, the line has 12" in log.skip_examples[0].why
    assert "5 beams need at least 18 fields, the line has 11" in log.skip_examples[1].why
