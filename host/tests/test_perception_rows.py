"""Row detectors on synthetic scans with known offset and heading (both signs), and end of row."""

import math

import numpy as np
import pytest

from agnav_host.perception import (
    ROW_METHODS,
    RowEndDetector,
    RowParams,
    detect_rows,
    fit_line_lsq,
    row_method_names,
)
from agnav_host.sim.sensors import Laser2D, laser_preset
from agnav_host.sim.world import World, plants_along
from agnav_host.types import LaserScan, Pose2D

MOUNT = Pose2D(0.2, 0.0, 0.0)


def _field(length_m: float = 10.0, gaps: list[tuple[float, float]] | None = None, seed: int = 3) -> World:
    rng = np.random.default_rng(seed)
    w = World()
    for k in range(4):  # rows at y = -1.125, -0.375, 0.375, 1.125: the lane around y = 0
        y = -1.125 + 0.75 * k
        w.add_circles(plants_along(np.array([[-3.0, y], [length_m, y]]), 0.15, 0.05, rng, 3, 0.015, gaps))
    return w


def _scan(w: World, e: float, psi: float, x: float = 0.0, seed: int = 0) -> LaserScan:
    return Laser2D(laser_preset("tim310"), MOUNT).scan(w, Pose2D(x, e, psi), 0.0, np.random.default_rng(seed))


def test_registry_has_the_five_methods():
    assert row_method_names() == ["offset", "lsq", "triangle", "ransac", "hough"]
    with pytest.raises(ValueError, match="known: offset, lsq"):
        detect_rows(_scan(_field(), 0, 0), "nope")


@pytest.mark.parametrize("method", list(ROW_METHODS))
@pytest.mark.parametrize("e", [0.1, -0.1, 0.0])
def test_lateral_offset_sign_and_size(method, e):
    w = _field()
    est = detect_rows(_scan(w, e, 0.0), method, mount=MOUNT)
    assert est.confidence > 0.2
    assert est.lateral_offset_m == pytest.approx(e, abs=0.03), f"{method}: offset {est.lateral_offset_m:+.3f} for {e:+.3f}"
    assert est.row_spacing_m == pytest.approx(0.75, abs=0.1)  # the plants' near faces, a little under 0.75
    assert not est.end_of_row


@pytest.mark.parametrize("method", ["lsq", "triangle", "ransac", "hough"])
@pytest.mark.parametrize("psi", [0.12, -0.12])
def test_heading_sign_and_size(method, psi):
    w = _field()
    errs = []
    for seed in range(3):
        est = detect_rows(_scan(w, 0.05, psi, seed=seed), method, mount=MOUNT)
        if est.confidence > 0.5:
            errs.append(est.heading_rad - psi)
    assert len(errs) >= 2, f"{method}: too few confident detections"
    assert abs(float(np.mean(errs))) < 0.03, f"{method}: heading error {np.mean(errs):+.3f} rad at {psi:+.2f}"


def test_offset_method_reports_no_heading():
    est = detect_rows(_scan(_field(), 0.0, 0.1), "offset", mount=MOUNT)
    assert not est.heading_observed and est.heading_rad == 0.0


def test_offset_method_drops_readings_beyond_0_75_m():
    # only one row: the other side is empty, so the estimate leans on the expected spacing
    w = World()
    rng = np.random.default_rng(0)
    w.add_circles(plants_along(np.array([[-3.0, 0.375], [6.0, 0.375]]), 0.15, 0.05, rng, 3, 0.015))
    w.add_circles(plants_along(np.array([[-3.0, -0.9], [6.0, -0.9]]), 0.15, 0.05, rng, 3, 0.015))  # beyond 0.75 m
    est = detect_rows(_scan(w, 0.0, 0.0), "offset", mount=MOUNT)
    assert est.n_right == 0 and est.n_left > 0
    assert est.confidence <= 0.5


def test_fit_line_lsq_is_exact_on_a_line():
    x = np.linspace(-1, 2, 20)
    phi, c, rms = fit_line_lsq(x, 0.3 + 0.1 * x)  # type: ignore[misc]
    assert phi == pytest.approx(math.atan(0.1))
    assert c == pytest.approx(0.3 * math.cos(math.atan(0.1)))
    assert rms == pytest.approx(0.0, abs=1e-12)
    assert fit_line_lsq(np.ones(5), np.arange(5.0)) is None  # vertical: no y = kx + n


def test_row_end_detector_ignores_a_missing_plant_or_two():
    det = RowEndDetector(0.25, 0.5, 3, 3)
    fills = [0.9] * 5 + [0.6, 0.5, 0.55, 0.6] + [0.9] * 3  # a gap of one or two plants
    assert not any(det.update(f) for f in fills)
    out = [det.update(f) for f in [0.2, 0.1, 0.0, 0.0]]
    assert out == [False, False, True, True]
    # a single low reading never ends a row
    det.reset()
    assert not any(det.update(f) for f in [0.9, 0.9, 0.9, 0.1, 0.9, 0.1, 0.9])


def test_fill_drops_at_the_row_end_but_not_at_a_two_plant_gap():
    w = _field(length_m=6.0, gaps=[(2.9, 3.2)])
    in_gap = detect_rows(_scan(w, 0.0, 0.0, x=2.6), "ransac", mount=MOUNT)
    at_end = detect_rows(_scan(w, 0.0, 0.0, x=6.1), "ransac", mount=MOUNT)
    assert in_gap.fill > 0.5 and not in_gap.end_of_row
    assert at_end.fill < 0.25 and at_end.end_of_row


def test_row_params_are_validated():
    with pytest.raises(ValueError):
        RowParams(expected_spacing_m=0.0)
    with pytest.raises(ValueError):
        RowEndDetector(0.6, 0.5)
