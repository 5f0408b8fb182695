"""``agnav slam`` end to end on a short simulated drive round a hall (CARMEN and AgNav laser logs), and its
answers to bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from _slam_helpers import carmen_lines, drifting_odometry, drive, relations_of, write_alog, write_carmen
from agnav_host import cli
from agnav_host.localisation.occupancy import FREE, OCCUPIED, load_map
from agnav_host.localisation.relations import read_relations, score_relations
from agnav_host.localisation.slam_io import read_trajectory


@pytest.fixture(scope="module")
def hall():
    truth = drive(step_m=0.3, laps=1.2)  # 60 m: round the block once and on past the start
    odom = drifting_odometry(truth, np.random.default_rng(7))
    times = 1031745824.658 + 0.5 * np.arange(len(truth))
    pairs = [(k, k + 1) for k in range(0, len(truth) - 1, 3)] + [(k, k + 180) for k in range(0, len(truth) - 180, 4)]
    return truth, odom, times, relations_of(truth, times, pairs)


def _run(capsys, argv):
    code = cli.main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_slam_on_a_carmen_log_writes_trajectory_map_and_plot_and_beats_the_odometry(tmp_path, capsys, hall):
    truth, odom, times, rel_text = hall
    log = write_carmen(tmp_path / "hall.log", carmen_lines(truth, odom))
    rel = tmp_path / "hall.relations"
    rel.write_text(rel_text)
    out = tmp_path / "out"
    code, stdout, stderr = _run(capsys, ["slam", str(log), "--out", str(out), "--relations", str(rel), "--json"])
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["scans"] == len(truth) and summary["loops_accepted"] >= 2
    assert {p.name for p in out.iterdir()} >= {"trajectory.csv", "map.pgm", "map.yaml", "map.png"}
    rows = (out / "trajectory.csv").read_text().splitlines()
    assert rows[0] == "t,x,y,yaw" and len(rows) == len(truth) + 1
    assert rows[1].split(",")[0] == f"{times[0]:.6f}", "the stamp as the log writes it"
    t, poses = read_trajectory(out / "trajectory.csv")
    relations = read_relations(rel)
    slam = score_relations(t, poses, relations)
    dead = score_relations(times, odom, relations)
    assert slam.scored == len(relations)
    # the odometry drifts metres over the lap; the map closes the loop to centimetres
    assert dead.trans_mean_m > 0.5
    assert slam.trans_mean_m < 0.05 and slam.rot_mean_deg < 0.5
    assert summary["relations"]["trans_mean_m"] == pytest.approx(slam.trans_mean_m, abs=1e-5)
    grid = load_map(out / "map.yaml")
    # the map's frame is the odometry's, which starts at the true first pose: the outer wall y = 0 at x = 12 m
    # is occupied, the aisle 2 m from it free
    def cell(x: float, y: float) -> np.ndarray:
        i = int((y - grid.origin[1]) / grid.resolution_m)
        j = int((x - grid.origin[0]) / grid.resolution_m)
        return grid.cells[i - 1:i + 2, j - 1:j + 2]

    assert (cell(12.0, 0.0) == OCCUPIED).any() and (cell(12.0, 2.0) == FREE).all()
    assert "skipped" not in stderr


def test_slam_on_an_agnav_laser_log(tmp_path, capsys, hall):
    truth, odom, _, _ = hall
    log = write_alog(tmp_path / "hall.alog", truth[:80], odom[:80])
    code, stdout, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o"), "--no-loops"])
    assert code == 0, stderr
    assert "80 scans" in stdout and "ms per scan" in stdout
    t, poses = read_trajectory(tmp_path / "o" / "trajectory.csv")
    assert t[1] == pytest.approx(0.5) and len(poses) == 80
    # 24 m driven: the scan matching holds the pose to centimetres, the odometry drifts by decimetres
    assert np.hypot(*(poses[:, :2] - truth[:80, :2]).T).max() < 0.1
    assert np.hypot(*(odom[79, :2] - truth[79, :2])) > 0.3


def test_garbage_lines_are_counted_and_the_run_goes_on(tmp_path, capsys, hall):
    truth, odom, _, _ = hall
    lines = carmen_lines(truth[:40], odom[:40])
    lines[5:5] = ["this is not a log line", "FLASER 181 1 2 3"]
    log = write_carmen(tmp_path / "g.log", lines)
    code, stdout, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o")])
    assert code == 0, stderr
    assert "skipped 2 bad lines (line 8" in stderr
    assert "40 scans" in stdout


def test_missing_odometry_is_said_and_scan_matching_carries_the_pose(tmp_path, capsys, hall):
    truth, odom, _, _ = hall
    lines = carmen_lines(truth[:40], odom[:40])
    for k in range(10, 20):  # ten scans whose odometry the log lost
        toks = lines[k].split()
        toks[182:188] = ["nan"] * 6
        lines[k] = " ".join(toks)
    log = write_carmen(tmp_path / "m.log", lines)
    code, stdout, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o"), "--no-loops"])
    assert code == 0, stderr
    assert "10 scans without odometry" in stderr
    t, poses = read_trajectory(tmp_path / "o" / "trajectory.csv")
    step = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    assert np.all(np.abs(step - 0.3) < 0.1), "no jump where the odometry is missing"


def test_truncated_log_reads_up_to_the_cut(tmp_path, capsys, hall):
    truth, odom, _, _ = hall
    text = "\n".join(carmen_lines(truth[:30], odom[:30]))
    log = tmp_path / "t.log"
    log.write_text(text[: len(text) - 500])
    code, stdout, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o"), "--no-loops"])
    assert code == 0, stderr
    assert "29 scans" in stdout and "truncated" in stderr


@pytest.mark.parametrize("content, message", [
    (b"", "empty"),
    (b"t,x,y\n1,2,3\n", "neither an AgNav laser log"),
    (b"ODOM 0 0 0 0 0 0 1.0 host 0\n", "no laser scan"),
    (b"# agnav-laserlog v1\nSCAN\x00\x00", "declares no laser"),
    (b"# agnav-laserlog v1\nXXXX\x05\x00\x00\x00hello", "byte 20"),
])
def test_bad_logs_exit_2_with_a_message_and_no_traceback(tmp_path, capsys, content, message):
    log = tmp_path / "bad.log"
    log.write_bytes(content)
    code, _, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o")])
    assert code == 2
    assert message in stderr and "Traceback" not in stderr


def test_missing_log_and_bad_relations_exit_2(tmp_path, capsys, hall):
    code, _, stderr = _run(capsys, ["slam", str(tmp_path / "nope.log"), "--out", str(tmp_path / "o")])
    assert code == 2 and "cannot read the log" in stderr
    truth, odom, _, _ = hall
    log = write_carmen(tmp_path / "ok.log", carmen_lines(truth[:5], odom[:5]))
    bad = tmp_path / "r.relations"
    bad.write_text("1 2 3\n")
    code, _, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "o"), "--relations", str(bad)])
    assert code == 2 and "expected 8 numbers" in stderr


def test_an_out_folder_that_is_a_file_exits_1(tmp_path, capsys, hall):
    truth, odom, _, _ = hall
    log = write_carmen(tmp_path / "ok.log", carmen_lines(truth[:5], odom[:5]))
    (tmp_path / "f").write_text("x")
    code, _, stderr = _run(capsys, ["slam", str(log), "--out", str(tmp_path / "f")])
    assert code == 1 and "is a file" in stderr
