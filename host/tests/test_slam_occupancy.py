"""Occupancy grids: built from scans, saved and loaded in ROS map_server's PGM + YAML."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.localisation.occupancy import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapFileError,
    OccupancyGrid,
    load_map,
    map_picture,
    occupancy_from_scans,
    save_map,
)


def _grid() -> OccupancyGrid:
    rng = np.random.default_rng(3)
    cells = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(37, 53))
    return OccupancyGrid(cells, 0.05, (-3.25, 1.5, 0.0))


def test_save_then_load_gives_the_same_grid(tmp_path):
    g = _grid()
    y, pgm = save_map(g, tmp_path / "map.yaml")
    back = load_map(y)
    assert pgm.name == "map.pgm"
    assert back.resolution_m == pytest.approx(0.05) and back.origin == pytest.approx((-3.25, 1.5, 0.0))
    np.testing.assert_array_equal(back.cells, g.cells)


def test_saved_files_follow_map_server(tmp_path):
    g = OccupancyGrid(np.array([[FREE, OCCUPIED], [UNKNOWN, FREE]], dtype=np.int8), 0.1, (1.0, 2.0, 0.0))
    y, pgm = save_map(g, tmp_path / "m.yaml")
    text = y.read_text()
    for line in ("image: m.pgm", "resolution: 0.1", "origin: [1.000000, 2.000000, 0.000000]", "negate: 0",
                 "occupied_thresh: 0.65", "free_thresh: 0.196"):
        assert line in text
    data = pgm.read_bytes()
    assert data.startswith(b"P5\n")
    pixels = data[-4:]
    # the picture's top row is the grid's last row (highest y): unknown 205, free 254; then free, occupied
    assert list(pixels) == [205, 254, 254, 0]


def test_load_reads_ascii_pgm_negate_and_thresholds(tmp_path):
    (tmp_path / "a.pgm").write_text("P2\n# a comment\n3 1\n100\n0 50 100\n")
    (tmp_path / "a.yaml").write_text("image: a.pgm\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 1\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    g = load_map(tmp_path / "a.yaml")
    # negate 1: p = value / max, so 0 is free, 100 occupied, 50 in between (unknown)
    assert g.cells.tolist() == [[FREE, UNKNOWN, OCCUPIED]]


def test_load_refuses_a_cut_off_picture_and_a_yaml_without_resolution(tmp_path):
    g = _grid()
    y, pgm = save_map(g, tmp_path / "map.yaml")
    pgm.write_bytes(pgm.read_bytes()[:-10])
    with pytest.raises(MapFileError, match="cut off"):
        load_map(y)
    (tmp_path / "b.yaml").write_text("image: map.pgm\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="resolution"):
        load_map(tmp_path / "b.yaml")


def test_grid_from_a_scan_marks_the_wall_occupied_and_the_space_before_it_free():
    # a laser at the origin facing +x sees a wall at x = 2 m over +-30 deg
    a = np.radians(np.linspace(-30, 30, 61))
    r = 2.0 / np.cos(a)
    pts = np.column_stack([r * np.cos(a), r * np.sin(a)])
    g = occupancy_from_scans(np.zeros((1, 3)), [pts], [np.zeros(2)], resolution_m=0.05)

    def cell(x: float, y: float) -> int:
        i = int(math.floor((y - g.origin[1]) / g.resolution_m))
        j = int(math.floor((x - g.origin[0]) / g.resolution_m))
        return int(g.cells[i, j])

    assert cell(2.01, 0.0) == OCCUPIED and cell(2.01, 1.0) == OCCUPIED
    assert cell(1.0, 0.0) == FREE and cell(1.5, 0.5) == FREE
    assert cell(-0.5, 0.0) == UNKNOWN and cell(2.5, 0.0) == UNKNOWN


def test_map_picture_draws_the_path_on_the_map():
    g = OccupancyGrid(np.zeros((100, 200), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    img = map_picture(g, np.array([[2.0, 5.0], [18.0, 5.0]]))
    assert img.shape == (100, 200, 3)
    row = 100 - 50  # y = 5 m
    assert tuple(img[row, 100]) == (0, 0, 220) or img[row - 1:row + 1, 100, 2].max() >= 200
