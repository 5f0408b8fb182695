import math

import numpy as np
import pytest

from agnav_host.scanio import ScanFileError, load_scan_csv, save_scan_csv
from agnav_host.types import LaserScan, Pose2D


def _scan():
    r = np.linspace(0.5, 9.5, 811)
    r[3] = np.nan
    r[4] = np.inf
    r[5] = 0.0
    return LaserScan(-math.radians(135), math.radians(270) / 810, r, 10.0, 12.25, Pose2D(1.5, -2.0, 0.3))


def test_round_trip(tmp_path):
    s = _scan()
    p = save_scan_csv(s, tmp_path / "a" / "scan.csv")
    assert p.read_text().splitlines()[2] == "angle_rad,range_m"
    t = load_scan_csv(p)
    assert t.pose == s.pose and t.stamp_s == 12.25 and t.range_max_m == 10.0
    assert t.angle_min_rad == pytest.approx(s.angle_min_rad) and t.angle_increment_rad == pytest.approx(s.angle_increment_rad)
    assert np.array_equal(t.ranges_m, s.ranges_m, equal_nan=True)
    assert t.valid_mask().sum() == 808


def test_without_pose(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("angle_rad,range_m\n0.0,1.0\n0.1,nan\n0.2,0\n")
    t = load_scan_csv(p)
    assert t.pose is None and len(t.ranges_m) == 3


@pytest.mark.parametrize("text, match", [
    ("angle,range\n0,1\n0.1,1\n", "expected header"),
    ("angle_rad,range_m\n0,1\n0.1\n", r":3: expected 2 columns"),
    ("angle_rad,range_m\n0,1\n0.1,abc\n", r":3: not a number"),
    ("angle_rad,range_m\n0,1\n0.1,-2\n", "negative range"),
    ("angle_rad,range_m\n0,1\n0.1,1\n0.5,1\n", "evenly spaced"),
    ("angle_rad,range_m\n0.2,1\n0.1,1\n", "ascending"),
    ("# pose_x_m=1,pose_y_m=2\nangle_rad,range_m\n0,1\n0.1,1\n", "pose metadata incomplete"),
    ("# pose_x_m=abc\nangle_rad,range_m\n0,1\n0.1,1\n", r":1: metadata pose_x_m"),
    ("# only a comment\n", "no 'angle_rad,range_m' header"),
])
def test_bad_files(tmp_path, text, match):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ScanFileError, match=match):
        load_scan_csv(p)


def test_missing_file(tmp_path):
    with pytest.raises(ScanFileError, match="cannot read"):
        load_scan_csv(tmp_path / "nope.csv")
