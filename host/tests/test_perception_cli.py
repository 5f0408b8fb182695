"""``agnav rows``: JSON keys and signs, bad files, negative values after options."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.scanio import save_scan_csv
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import World, plants_along
from agnav_host.types import Pose2D

from _scan_files import four_rows_scan_csv

KEYS = {"lateral_offset_m", "heading_rad", "row_spacing_m", "confidence", "end_of_row"}


@pytest.fixture(scope="module")
def scan_file(tmp_path_factory):
    return four_rows_scan_csv(tmp_path_factory.mktemp("scan"))


@pytest.mark.parametrize("method", ["offset", "lsq", "triangle", "ransac", "hough"])
def test_rows_json_has_the_keys_and_rep103_signs(scan_file, method, capsys):
    assert main(["rows", "--scan", str(scan_file), "--method", method, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == KEYS
    assert out["lateral_offset_m"] == pytest.approx(0.08, abs=0.04)
    if method in ("lsq", "ransac", "hough"):  # offset does not observe the heading; triangle may find no gap
        assert out["heading_rad"] == pytest.approx(-0.1, abs=0.04)
    assert out["end_of_row"] is False
    assert 0.0 < out["confidence"] <= 1.0


def test_rows_negative_mount_after_option(scan_file, capsys):
    # the laser 0.1 m behind the reference point: the reference point is then 0.1 m further along the
    # heading, which points 0.1 rad to the right, so it is 0.1 sin(0.1) ~ 0.01 m further right
    assert main(["rows", "--scan", str(scan_file), "--mount", "-0.1,0,0", "--json"]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main(["rows", "--scan", str(scan_file), "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    assert a["lateral_offset_m"] - b["lateral_offset_m"] == pytest.approx(-0.1 * math.sin(0.1), abs=0.004)


def test_rows_negative_mount_in_a_fresh_process(scan_file):
    entry = "import sys; from agnav_host.cli import main; sys.exit(main(sys.argv[1:]))"
    r = subprocess.run([sys.executable, "-c", entry, "rows", "--scan", str(scan_file), "--mount", "-0.1,0.05,-2",
                        "--json"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert set(json.loads(r.stdout)) == KEYS


def test_rows_bad_file_names_the_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("# agnav-scan v1\nangle_rad,range_m\n0.0,1.0\n0.1,oops\n", encoding="utf-8")
    assert main(["rows", "--scan", str(bad), "--json"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4:" in err and "not a number" in err


def test_rows_missing_file_and_unknown_method(tmp_path, scan_file, capsys):
    assert main(["rows", "--scan", str(tmp_path / "nope.csv")]) == 2
    assert "cannot read" in capsys.readouterr().err
    assert main(["rows", "--scan", str(scan_file), "--method", "magic"]) == 2
    assert "known: offset, lsq, triangle, ransac, hough" in capsys.readouterr().err


def test_rows_human_readable_output(scan_file, capsys):
    assert main(["rows", "--scan", str(scan_file)]) == 0
    assert "robot left of centre" in capsys.readouterr().out


def test_rows_signs_follow_rep103_both_ways(tmp_path, capsys):
    """Robot right of the centre line and turned CCW: negative offset, positive heading (the fixture has the
    opposite case)."""
    rng = np.random.default_rng(2)
    w = World()
    for y in (-1.125, -0.375, 0.375, 1.125):
        w.add_circles(plants_along(np.array([[-3.0, y], [8.0, y]]), 0.15, 0.05, rng, 3, 0.015))
    scan = Laser2D(laser_preset("tim310")).scan(w, Pose2D(0.0, -0.06, 0.08), 0.0, np.random.default_rng(1))
    path = save_scan_csv(scan, tmp_path / "right_ccw.csv")
    assert main(["rows", "--scan", str(path), "--method", "ransac", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["lateral_offset_m"] == pytest.approx(-0.06, abs=0.03)
    assert out["heading_rad"] == pytest.approx(0.08, abs=0.03)


@pytest.mark.parametrize("body, line, words", [
    ("# agnav-scan v1\nangle_rad,range_m\n0.0,1.0\n0.1,1.0\n0.05,1.0\n", 5, "strictly ascending"),
    ("# agnav-scan v1\nangle_rad,range_m\n0.0,1.0\n0.1,1.0\n0.2,1.0\n0.5,1.0\n", 6, "not evenly spaced"),
    ("# agnav-scan v1\n# pose_x_m=1.0,pose_y_m=2.0\nangle_rad,range_m\n0.0,1.0\n0.1,1.0\n", 2, "pose metadata incomplete"),
    ("# agnav-scan v1\nangle,range\n0.0,1.0\n", 2, "expected header"),
    ("# agnav-scan v1\nangle_rad,range_m\n0.0,1.0\n0.1,1.0,7\n", 4, "expected 2 columns"),
    ("# agnav-scan v1\nangle_rad,range_m\n0.0,1.0\n0.1,-2\n", 4, "negative range"),
    ("# agnav-scan v1\n# stamp_s=soon\nangle_rad,range_m\n0.0,1.0\n0.1,1.0\n", 2, "not a number"),
])
def test_rows_bad_files_name_the_line(tmp_path, capsys, body, line, words):
    bad = tmp_path / "bad.csv"
    bad.write_text(body, encoding="utf-8")
    assert main(["rows", "--scan", str(bad), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # nothing on stdout for a script reading the JSON
    assert f"{bad}:{line}:" in captured.err and words in captured.err
