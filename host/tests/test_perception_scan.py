"""Scan cleaning and conversion to points."""

import math

import numpy as np
import pytest

from agnav_host.perception import ScanParams, check_scan, mixed_pixel_mask, points_from_scan
from agnav_host.types import LaserScan, Pose2D


def _scan(r: list[float], inc_deg: float = 1.0) -> LaserScan:
    n = len(r)
    return LaserScan(-math.radians(inc_deg) * (n - 1) / 2, math.radians(inc_deg), np.asarray(r, dtype=float), 4.0)


def test_check_scan_drops_nan_inf_zero_and_out_of_range_returns():
    s = _scan([1.0, math.nan, 1.0, math.inf, 1.0, 0.0, 1.0, 0.01, 1.0, 5.0, 1.0])
    keep = check_scan(s, ScanParams(min_range_m=0.05))
    assert keep.tolist() == [True, False, True, False, True, False, True, False, True, False, True]


def test_check_scan_honours_params_max_range():
    s = _scan([1.0, 2.0, 3.0])
    assert check_scan(s, ScanParams(max_range_m=2.5, drop_mixed=False)).tolist() == [True, True, False]


def test_mixed_pixel_between_foreground_and_background_is_dropped():
    # an edge: 1 m foreground, 3 m background, one beam at 2 m in between (a blend of both)
    r = np.array([1.0, 1.0, 1.0, 2.0, 3.0, 3.0, 3.0])
    a = np.radians(np.arange(7) - 3.0)
    m = mixed_pixel_mask(a, r, 0.15)
    assert m.tolist() == [False, False, False, True, False, False, False]
    # an isolated thin stem in front of the background is kept (nearer than both neighbours)
    r2 = np.array([3.0, 3.0, 1.0, 3.0, 3.0])
    assert not mixed_pixel_mask(np.radians(np.arange(5) - 2.0), r2, 0.15).any()


def test_points_from_scan_applies_the_mount_pose():
    s = LaserScan(0.0, math.radians(1.0), np.array([1.0, 1.0]), 4.0)
    pts = points_from_scan(s, Pose2D(0.2, -0.1, math.pi / 2))
    # sensor facing left, 0.2 m ahead and 0.1 m right of the reference point
    assert pts.xy[0] == pytest.approx([0.2, 0.9])
    assert pts.index.tolist() == [0, 1]


def test_check_scan_rejects_two_dimensional_ranges():
    s = LaserScan(0.0, 0.1, np.ones((2, 2)))
    with pytest.raises(ValueError, match="one-dimensional"):
        check_scan(s)
