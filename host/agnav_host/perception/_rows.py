"""Crop-row detection from a horizontal 2-D laser scan.

Five detectors, chosen by name through :data:`ROW_METHODS` (``offset``, ``lsq``, ``triangle``,
``ransac``, ``hough``). Each works on robot-frame points and returns a :class:`RowEstimate`:

* ``lateral_offset_m``: signed distance of the robot's reference point from the centre line between
  the two rows, positive when the robot is left of it (REP-103, y left);
* ``heading_rad``: robot heading relative to the rows, counter-clockwise positive;
* ``row_spacing_m``: distance between the two rows; ``confidence`` in [0, 1];
* ``fill``: the fraction of the next ``end_ahead_m`` of row (0.1 m bins) that holds plants, the input
  of the end-of-row test (:class:`RowEndDetector` adds hysteresis across scans).

A row line is kept as (phi, c): direction phi in the robot frame and signed lateral position c, so that
every point p on it has ``n . p = c`` with the left normal ``n = (-sin phi, cos phi)``. The robot's
heading relative to the rows is ``-phi`` and its offset is ``-(c_left + c_right) / 2``.

The ``offset``, ``lsq`` and ``triangle`` methods follow ref 004 (sections 2.1-2.3). Its equations 1, 2,
5 and 6 were lost in the text; the reconstructions are noted where they are used.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Callable

import numpy as np

from ..types import FloatArray, LaserScan, Pose2D, ScanXY, norm_angle_rad
from ._scan import ScanParams, ScanPoints, points_from_scan

__all__ = [
    "RowParams",
    "RowEstimate",
    "ROW_METHODS",
    "row_method_names",
    "detect_rows",
    "detect_rows_points",
    "RowEndDetector",
    "fit_line_lsq",
]


@dataclass(frozen=True)
class RowParams:
    """Parameters of the row detectors (SI units). Defaults suit rows 0.75 m apart (ref 004)."""

    expected_spacing_m: float = 0.75
    x_min_m: float = -0.5  # robot-frame window used by lsq, ransac and hough
    x_max_m: float = 2.5
    near_x_max_m: float = 1.0  # window of the first, coarse split into left and right
    # offset (ref 004 2.1): 30 readings per side around +-90 deg, readings beyond 0.75 m dropped
    readings_per_side: int = 30
    offset_max_range_m: float = 0.75
    # lsq (ref 004 2.2): one refit on the points within this distance of the first fit
    lsq_refit_tol_m: float = 0.15
    # triangle (ref 004 2.3)
    robot_width_m: float = 0.5
    max_base_angle_rad: float = math.radians(100.0)
    triangle_near_x_m: float = 0.35
    triangle_max_range_m: float = 2.5  # returns beyond are ignored, so the gap ends lie at similar ranges
    # ransac
    ransac_iterations: int = 48
    ransac_tol_m: float = 0.05
    ransac_seed: int = 0
    # hough (OpenCV)
    hough_cell_m: float = 0.02
    hough_theta_step_rad: float = math.radians(1.0)
    hough_votes: int = 6
    hough_tol_m: float = 0.06
    max_heading_rad: float = math.radians(40.0)
    # end of row
    end_ahead_m: float = 1.0
    end_bin_m: float = 0.1
    end_band_m: float = 0.15
    end_fill_low: float = 0.25
    min_points_per_side: int = 4
    scan: ScanParams = field(default_factory=ScanParams)

    def __post_init__(self) -> None:
        if not self.expected_spacing_m > 0:
            raise ValueError(f"RowParams.expected_spacing_m must be > 0, got {self.expected_spacing_m}")
        if not self.x_min_m < self.x_max_m:
            raise ValueError("RowParams: x_min_m must be < x_max_m")
        if self.readings_per_side < 2 or self.ransac_iterations < 1 or self.min_points_per_side < 2:
            raise ValueError("RowParams: readings_per_side, ransac_iterations and min_points_per_side too small")
        if not 0 < self.max_base_angle_rad < math.pi:
            raise ValueError("RowParams.max_base_angle_rad must be in (0, pi)")
        if not (self.end_ahead_m > 0 and 0 < self.end_bin_m <= self.end_ahead_m):
            raise ValueError("RowParams: need end_ahead_m > 0 and 0 < end_bin_m <= end_ahead_m")


@dataclass(frozen=True)
class RowEstimate:
    """Result of one row detection (see the module docstring for signs). Units in the names."""

    method: str
    lateral_offset_m: float
    heading_rad: float
    row_spacing_m: float
    confidence: float
    fill: float = 0.0
    end_of_row: bool = False
    left_m: float | None = None  # c of the left row line, m (positive)
    right_m: float | None = None  # c of the right row line, m (negative)
    aim_xy: tuple[float, float] | None = None  # lsq: lines' crossing; triangle: segment midpoint (robot frame, m)
    n_left: int = 0
    n_right: int = 0
    heading_observed: bool = True  # False for ``offset``, which sees only the lateral offset

    @property
    def valid(self) -> bool:
        return self.confidence > 0.0

    def to_dict(self) -> dict[str, object]:
        return asdict(self)

    @staticmethod
    def invalid(method: str, spacing_m: float, n_left: int = 0, n_right: int = 0) -> "RowEstimate":
        return RowEstimate(method, 0.0, 0.0, spacing_m, 0.0, 0.0, True, None, None, None, n_left, n_right)


# ---- line helpers --------------------------------------------------------------------------------


def fit_line_lsq(x: FloatArray, y: FloatArray) -> tuple[float, float, float] | None:
    """Least-squares line ``y = k x + n`` from the running sums of ref 004 (eqs. 3-4).

    Returns (phi_rad, c_m, rms_m) in the (phi, c) form of the module docstring, or None for fewer
    than 2 points or a vertical spread of x. Ref 004 sums distances and angles in degrees; the same
    formulas are applied here to Cartesian x and y (reconstruction: the printed equations lost their
    operators, the standard normal-equation solution is used).
    """
    n_pts = len(x)
    if n_pts < 2:
        return None
    sx, sy = float(x.sum()), float(y.sum())
    sxx, sxy = float((x * x).sum()), float((x * y).sum())
    den = n_pts * sxx - sx * sx
    if den <= 1e-12 * max(1.0, n_pts * sxx):
        return None
    k = (n_pts * sxy - sx * sy) / den
    n0 = (sxx * sy - sx * sxy) / den
    phi = math.atan(k)
    c = n0 * math.cos(phi)
    res = y - (k * x + n0)
    return phi, c, float(math.sqrt(float(np.mean(res * res))) * math.cos(phi))


def _signed_dist(xy: ScanXY, phi: float, c: float) -> FloatArray:
    return -math.sin(phi) * xy[:, 0] + math.cos(phi) * xy[:, 1] - c


def _joint_fit(left: ScanXY, right: ScanXY) -> tuple[float, float | None, float | None]:
    """Two parallel lines through two point sets: shared direction from the pooled, per-side centred
    scatter (total least squares), then each side's c. Returns (phi, c_left, c_right)."""
    parts = [p - p.mean(axis=0) for p in (left, right) if len(p) >= 2]
    pooled = np.vstack(parts)
    sxx = float((pooled[:, 0] ** 2).sum())
    syy = float((pooled[:, 1] ** 2).sum())
    sxy = float((pooled[:, 0] * pooled[:, 1]).sum())
    phi = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    if phi > math.pi / 2:
        phi -= math.pi
    elif phi < -math.pi / 2:
        phi += math.pi
    nx, ny = -math.sin(phi), math.cos(phi)
    cl = float(nx * left[:, 0].mean() + ny * left[:, 1].mean()) if len(left) >= 2 else None
    cr = float(nx * right[:, 0].mean() + ny * right[:, 1].mean()) if len(right) >= 2 else None
    return phi, cl, cr


def _fill(xy: ScanXY, phi: float, cl: float, cr: float, p: RowParams) -> float:
    """Fraction of 0.1 m bins over the next end_ahead_m (along the rows) holding a point of either row line."""
    ux, uy = math.cos(phi), math.sin(phi)
    along = xy[:, 0] * ux + xy[:, 1] * uy
    nb = max(1, int(round(p.end_ahead_m / p.end_bin_m)))
    ahead = (along >= 0.0) & (along < nb * p.end_bin_m)
    fills = []
    for c in (cl, cr):
        d = np.abs(_signed_dist(xy, phi, c))
        sel = ahead & (d < p.end_band_m)
        bins = np.unique((along[sel] / p.end_bin_m).astype(int))
        fills.append(len(bins) / nb)
    return float(np.mean(fills))


def _finish(method: str, pts: ScanPoints, p: RowParams, phi: float, cl: float | None, cr: float | None,
            nl: int, nr: int, quality: float, aim: tuple[float, float] | None = None) -> RowEstimate:
    """Turn per-side row lines into a RowEstimate (one missing side: the expected spacing is assumed)."""
    s0 = p.expected_spacing_m
    if cl is None and cr is None:
        return RowEstimate.invalid(method, s0, nl, nr)
    conf = quality
    if cl is not None and cr is not None:
        spacing = cl - cr
        centre = 0.5 * (cl + cr)
        # implausible spacing (a row missed, or a weed line taken for a row) lowers the confidence
        conf *= max(0.0, 1.0 - abs(spacing - s0) / (0.5 * s0))
    elif cl is not None:
        spacing, centre, cr = s0, cl - 0.5 * s0, cl - s0
        conf *= 0.5
    else:
        assert cr is not None
        spacing, centre, cl = s0, cr + 0.5 * s0, cr + s0
        conf *= 0.5
    assert cl is not None and cr is not None
    fill = _fill(pts.xy, phi, cl, cr, p)
    conf = float(min(1.0, max(0.0, conf)))
    return RowEstimate(method, -centre, -phi, spacing, conf, fill, fill < p.end_fill_low,
                       cl if nl else None, cr if nr else None, aim, nl, nr)


def _support(n: int, p: RowParams) -> float:
    return min(1.0, n / (4.0 * p.min_points_per_side))


# ---- side split ------------------------------------------------------------------------------


def _coarse_centre(xy: ScanXY, p: RowParams) -> tuple[float, float]:
    """Coarse centre line (phi, c) from the near window, where a heading error shifts the rows little."""
    gate = p.expected_spacing_m
    near = xy[(xy[:, 0] >= p.x_min_m) & (xy[:, 0] <= p.near_x_max_m) & (np.abs(xy[:, 1]) < gate)]
    fits = []
    for side in (near[near[:, 1] > 0], near[near[:, 1] < 0]):
        f = fit_line_lsq(side[:, 0], side[:, 1]) if len(side) >= p.min_points_per_side else None
        if f is not None and abs(f[0]) > p.max_heading_rad:
            f = None
        fits.append(f)
    fl, fr = fits
    if fl is not None and fr is not None:
        return 0.5 * (fl[0] + fr[0]), 0.5 * (fl[1] + fr[1])
    if fl is not None:
        return fl[0], fl[1] - 0.5 * p.expected_spacing_m
    if fr is not None:
        return fr[0], fr[1] + 0.5 * p.expected_spacing_m
    return 0.0, 0.0


def _split(pts: ScanPoints, p: RowParams) -> tuple[ScanXY, ScanXY]:
    """Left and right row candidates in the window: within one spacing of the coarse centre line."""
    xy = pts.xy
    xy = xy[(xy[:, 0] >= p.x_min_m) & (xy[:, 0] <= p.x_max_m)]
    phi0, c0 = _coarse_centre(xy, p)
    d = _signed_dist(xy, phi0, c0)
    s = p.expected_spacing_m
    return xy[(d > 0) & (d < s)], xy[(d < 0) & (d > -s)]


# ---- the detectors -----------------------------------------------------------------------------


def _rows_offset(pts: ScanPoints, p: RowParams) -> RowEstimate:
    """Ref 004 2.1: ``readings_per_side`` beams around +-90 deg, those beyond ``offset_max_range_m``
    dropped, the mean lateral distance of each side.

    Reconstruction (eq. 1 lost): offset = (d_r - d_l) / 2 from the mean lateral distances, which is
    ``-(c_l + c_r) / 2`` here. The method does not observe the heading (the reference steers on the
    offset alone, eq. 2): ``heading_rad`` is 0 and ``heading_observed`` False.
    """
    half = 0.5 * p.readings_per_side * abs(pts.angle_increment_rad)
    close = pts.ranges_m <= p.offset_max_range_m
    # the beams' bearings in the robot frame about the laser (whatever its mounting yaw, its sense of
    # rotation or where its angles start)
    bearing = np.arctan2(pts.xy[:, 1] - pts.mount.y_m, pts.xy[:, 0] - pts.mount.x_m)
    cs: list[float | None] = []
    ns: list[int] = []
    for sign in (1.0, -1.0):
        sel = close & (np.abs(norm_angle_rad(bearing - sign * math.pi / 2)) <= half + 1e-9)
        ns.append(int(sel.sum()))
        cs.append(float(pts.xy[sel, 1].mean()) if ns[-1] >= p.min_points_per_side else None)
    (cl, cr), (nl, nr) = cs, ns
    q = math.sqrt(_support(nl, p) * _support(nr, p)) if cl is not None and cr is not None else _support(max(nl, nr), p)
    est = _finish("offset", pts, p, 0.0, cl, cr, nl if cl is not None else 0, nr if cr is not None else 0, q)
    return replace(est, heading_observed=False)


def _rows_lsq(pts: ScanPoints, p: RowParams) -> RowEstimate:
    """Ref 004 2.2: one least-squares line per side (eqs. 3-4) and their crossing point.

    The two lines' crossing (eqs. 5-6, lost in the text; here ``x = (n_r - n_l) / (k_l - k_r)``) is
    returned as ``aim_xy`` when it lies ahead; offset and heading come from the two lines directly.
    """
    left, right = _split(pts, p)
    fits: list[tuple[float, float, float] | None] = []
    sizes = []
    for side in (left, right):
        f = fit_line_lsq(side[:, 0], side[:, 1]) if len(side) >= p.min_points_per_side else None
        if f is not None:  # one refit without the points far from the first line (weeds, the next row)
            keep = np.abs(_signed_dist(side, f[0], f[1])) < p.lsq_refit_tol_m
            if keep.sum() >= p.min_points_per_side:
                f = fit_line_lsq(side[keep, 0], side[keep, 1]) or f
                side = side[keep]
        fits.append(f)
        sizes.append(len(side) if f is not None else 0)
    fl, fr = fits
    nl, nr = sizes
    if fl is None and fr is None:
        return RowEstimate.invalid("lsq", p.expected_spacing_m, nl, nr)
    phis = [(f[0], n) for f, n in ((fl, nl), (fr, nr)) if f is not None]
    phi = sum(a * w for a, w in phis) / sum(w for _, w in phis)
    aim = None
    if fl is not None and fr is not None:
        kl, kr = math.tan(fl[0]), math.tan(fr[0])
        nl0, nr0 = fl[1] / math.cos(fl[0]), fr[1] / math.cos(fr[0])
        if abs(kl - kr) > 1e-9:
            xc = (nr0 - nl0) / (kl - kr)
            if xc > 0:
                aim = (xc, kl * xc + nl0)
    rms = max((f[2] for f in (fl, fr) if f is not None), default=0.0)
    q = math.sqrt(_support(nl, p) * _support(nr, p)) if fl and fr else _support(max(nl, nr), p)
    q *= 1.0 / (1.0 + (rms / 0.1) ** 2)
    return _finish("lsq", pts, p, phi, fl[1] if fl else None, fr[1] if fr else None, nl, nr, q, aim)


def _rows_triangle(pts: ScanPoints, p: RowParams) -> RowEstimate:
    """Ref 004 2.3: among gaps between consecutive returns (in beam order) at least ``robot_width_m``
    wide, keep those whose triangle with the sensor has both base angles below ``max_base_angle_rad``
    (100 deg) and steer to the midpoint of the one nearest straight ahead.

    Returns beyond ``triangle_max_range_m`` are ignored: with rows longer than the laser's range the
    gap's two ends would otherwise lie at very different ranges and always fail the angle test.
    The reference outputs only the steering angle to that midpoint. Offset and spacing are taken here
    from the nearest row points beside the robot (|x| < ``triangle_near_x_m``), and the heading from
    the line joining the centre beside the robot to the midpoint.
    """
    xy = pts.xy[pts.ranges_m <= p.triangle_max_range_m]
    o = np.array([pts.mount.x_m, pts.mount.y_m])
    # consecutive in bearing about the laser, from behind on the right round to behind on the left: the
    # beam order, whatever the laser's sense of rotation or where its angles start (a full-circle laser
    # whose angles run 0..2 pi has its seam straight ahead)
    xy = xy[np.argsort(np.arctan2(xy[:, 1] - o[1], xy[:, 0] - o[0]), kind="stable")]
    best: tuple[float, float, float] | None = None  # (|bearing|, mx, my)
    if len(xy) >= 2:
        p1, p2 = xy[:-1], xy[1:]
        seg = p2 - p1
        w = np.hypot(seg[:, 0], seg[:, 1])
        to_o1, to_o2 = o - p1, o - p2
        n1 = np.hypot(to_o1[:, 0], to_o1[:, 1])
        n2 = np.hypot(to_o2[:, 0], to_o2[:, 1])
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_a = (to_o1 * seg).sum(axis=1) / (n1 * w)
            cos_b = (to_o2 * -seg).sum(axis=1) / (n2 * w)
        ok = (w >= p.robot_width_m) & (cos_a > math.cos(p.max_base_angle_rad)) & (cos_b > math.cos(p.max_base_angle_rad))
        mid = 0.5 * (p1 + p2)
        ok &= mid[:, 0] > o[0]
        if ok.any():
            bearing = np.abs(np.arctan2(mid[:, 1] - o[1], mid[:, 0] - o[0]))
            j = int(np.argmin(np.where(ok, bearing, np.inf)))
            best = (float(bearing[j]), float(mid[j, 0]), float(mid[j, 1]))
    s = p.expected_spacing_m
    near = xy[(np.abs(xy[:, 0]) <= p.triangle_near_x_m) & (np.abs(xy[:, 1]) < s)]
    left, right = near[near[:, 1] > 0], near[near[:, 1] < 0]
    nl, nr = len(left), len(right)
    # the row's near face: the median of the points closest to the robot on each side
    cl = float(np.median(left[:, 1])) if nl >= 2 else None
    cr = float(np.median(right[:, 1])) if nr >= 2 else None
    if cl is None and cr is None:
        return RowEstimate.invalid("triangle", s, nl, nr)
    centre = 0.5 * (cl + cr) if cl is not None and cr is not None else (cl - 0.5 * s if cl is not None else cr + 0.5 * s)  # type: ignore[operator]
    if best is None:
        phi, q, aim = 0.0, 0.3, None
    else:
        _, mx, my = best
        phi = math.atan2(my - centre, mx) if mx > 0.3 else 0.0
        q, aim = 1.0, (mx, my)
        if abs(phi) > p.max_heading_rad:
            phi, q = 0.0, 0.3
    q *= math.sqrt(min(1.0, nl / 4.0) * min(1.0, nr / 4.0)) if nl and nr else 0.5
    return _finish("triangle", pts, p, phi, cl, cr, nl, nr, q, aim)


def _ransac_side(side: ScanXY, p: RowParams, rng: np.random.Generator) -> np.ndarray | None:
    """Inlier mask of the best line through ``side`` from random point pairs, or None."""
    m = len(side)
    if m < p.min_points_per_side:
        return None
    i = rng.integers(0, m, p.ransac_iterations)
    j = rng.integers(0, m, p.ransac_iterations)
    d = side[j] - side[i]
    ln = np.hypot(d[:, 0], d[:, 1])
    good = ln > 0.2
    # hypotheses must run roughly along the robot (rows within max_heading of straight ahead)
    good &= np.abs(d[:, 1]) < np.tan(p.max_heading_rad) * np.abs(d[:, 0])
    if not good.any():
        return None
    i, d, ln = i[good], d[good], ln[good]
    nx, ny = -d[:, 1] / ln, d[:, 0] / ln
    res = np.abs(nx[:, None] * (side[None, :, 0] - side[i, 0][:, None]) + ny[:, None] * (side[None, :, 1] - side[i, 1][:, None]))
    score = (res < p.ransac_tol_m).sum(axis=1)
    k = int(np.argmax(score))
    if score[k] < p.min_points_per_side:
        return None
    return np.asarray(res[k] < p.ransac_tol_m)


def _refine(side: ScanXY, mask: np.ndarray | None, tol: float, phi: float, c: float | None) -> ScanXY:
    """Inliers of a side: the given mask, then (after the joint fit) those within tol of its line."""
    if mask is None:
        return side[:0]
    s: ScanXY = side[mask]
    if c is not None:
        s2 = side[np.abs(_signed_dist(side, phi, c)) < tol]
        if len(s2) >= 2:
            return s2
    return s


def _rows_ransac(pts: ScanPoints, p: RowParams) -> RowEstimate:
    """RANSAC line per side (random point pairs, inliers within ``ransac_tol_m``), then one joint fit
    of two parallel lines to both sides' inliers (shared direction), refitted once on the new inliers.
    Robust to gaps, weeds and stray returns; the window ``x_max_m`` bounds the error on curved rows."""
    left, right = _split(pts, p)
    rng = np.random.default_rng(p.ransac_seed)
    ml, mr = _ransac_side(left, p, rng), _ransac_side(right, p, rng)
    return _joint_estimate("ransac", pts, p, left, right, ml, mr, p.ransac_tol_m)


def _joint_estimate(method: str, pts: ScanPoints, p: RowParams, left: ScanXY, right: ScanXY,
                    ml: np.ndarray | None, mr: np.ndarray | None, tol: float) -> RowEstimate:
    il, ir = (left[ml] if ml is not None else left[:0]), (right[mr] if mr is not None else right[:0])
    if len(il) < 2 and len(ir) < 2:
        return RowEstimate.invalid(method, p.expected_spacing_m, len(il), len(ir))
    phi, cl, cr = _joint_fit(il, ir)
    il, ir = _refine(left, ml, tol, phi, cl), _refine(right, mr, tol, phi, cr)
    if len(il) >= 2 or len(ir) >= 2:
        phi, cl, cr = _joint_fit(il, ir)
    nl, nr = len(il), len(ir)
    q = math.sqrt(_support(nl, p) * _support(nr, p)) if nl >= 2 and nr >= 2 else _support(max(nl, nr), p)
    return _finish(method, pts, p, phi, cl if nl >= 2 else None, cr if nr >= 2 else None, nl, nr, q)


def _rows_hough(pts: ScanPoints, p: RowParams) -> RowEstimate:
    """OpenCV standard Hough transform of the window's points rasterised at ``hough_cell_m``; the
    strongest line on each side (direction within ``max_heading_rad``), then the joint parallel fit
    of :func:`_rows_ransac` on the points within ``hough_tol_m`` of it."""
    import cv2

    left, right = _split(pts, p)
    cell = p.hough_cell_m
    x0 = p.x_min_m
    ny_half = p.expected_spacing_m * 1.6
    w = int(math.ceil((p.x_max_m - x0) / cell)) + 1
    h = int(math.ceil(2 * ny_half / cell)) + 1
    masks: list[np.ndarray | None] = []
    for side in (left, right):
        if len(side) < p.min_points_per_side:
            masks.append(None)
            continue
        img = np.zeros((h, w), dtype=np.uint8)
        col = np.clip(((side[:, 0] - x0) / cell).astype(int), 0, w - 1)
        row = np.clip(((side[:, 1] + ny_half) / cell).astype(int), 0, h - 1)
        img[row, col] = 255
        # in the image, columns are x and rows are y; a row line's normal points near +-90 deg
        lines = cv2.HoughLines(img, 1.0, p.hough_theta_step_rad, p.hough_votes, None, 0, 0,
                               math.pi / 2 - p.max_heading_rad, math.pi / 2 + p.max_heading_rad)
        if lines is None or len(lines) == 0:
            masks.append(None)
            continue
        rho, theta = float(lines[0][0][0]), float(lines[0][0][1])
        # pixel centres: col + 0.5, row + 0.5 -> metres
        d = ((side[:, 0] - x0) / cell - 0.5) * math.cos(theta) + ((side[:, 1] + ny_half) / cell - 0.5) * math.sin(theta) - rho
        mask = np.abs(d) * cell < p.hough_tol_m
        masks.append(mask if mask.sum() >= 2 else None)
    return _joint_estimate("hough", pts, p, left, right, masks[0], masks[1], p.hough_tol_m)


#: Row detectors by name (the CLI, the benchmark and the followers choose by name).
ROW_METHODS: dict[str, Callable[[ScanPoints, RowParams], RowEstimate]] = {
    "offset": _rows_offset,
    "lsq": _rows_lsq,
    "triangle": _rows_triangle,
    "ransac": _rows_ransac,
    "hough": _rows_hough,
}


def row_method_names() -> list[str]:
    return list(ROW_METHODS)


def detect_rows_points(pts: ScanPoints, method: str = "ransac", params: RowParams | None = None) -> RowEstimate:
    """Run the named detector on already cleaned points; ValueError lists the names on a miss."""
    try:
        fn = ROW_METHODS[method]
    except KeyError:
        raise ValueError(f"unknown row method {method!r}; known: {', '.join(ROW_METHODS)}") from None
    return fn(pts, params or RowParams())


def detect_rows(scan: LaserScan, method: str = "ransac", params: RowParams | None = None, mount: Pose2D | None = None) -> RowEstimate:
    """Clean ``scan`` and detect the rows; ``mount`` is the laser's pose on the robot (default: at the
    reference point, facing forward)."""
    p = params or RowParams()
    return detect_rows_points(points_from_scan(scan, mount, p.scan), method, p)


class RowEndDetector:
    """End of row with hysteresis across scans.

    The detector arms once ``fill`` has been at least ``high`` for ``n_in`` scans in a row (the robot
    is between rows), and reports the end once ``fill`` has stayed below ``low`` for ``n_out`` scans
    in a row; one or two missing plants leave ``fill`` well above ``low``. A reported end stays until
    the detector is re-armed or reset.
    """

    def __init__(self, low: float = 0.25, high: float = 0.5, n_in: int = 3, n_out: int = 3) -> None:
        if not 0.0 <= low < high <= 1.0 or n_in < 1 or n_out < 1:
            raise ValueError("RowEndDetector needs 0 <= low < high <= 1 and n_in, n_out >= 1")
        self.low, self.high, self.n_in, self.n_out = low, high, n_in, n_out
        self.reset()

    def reset(self) -> None:
        self.armed = False
        self.ended = False
        self._hi = 0
        self._lo = 0

    def update(self, fill: float) -> bool:
        """Feed one scan's fill (0..1); returns True while the end of the row is reported."""
        self._hi = self._hi + 1 if fill >= self.high else 0
        self._lo = self._lo + 1 if fill < self.low else 0
        if self._hi >= self.n_in:
            self.armed, self.ended = True, False
        if self.armed and self._lo >= self.n_out:
            self.ended, self.armed = True, False
        return self.ended

