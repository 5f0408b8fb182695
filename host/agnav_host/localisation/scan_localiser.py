"""Laser localisation in the host loop without surveyed posts: wheel odometry as the prior, each scan matched
to a map of what the laser has seen.

Two maps. A saved occupancy map (``agnav slam``'s PGM + YAML) is a cloud of wall points, its occupied cells,
and each scan is aligned to it by point-to-line ICP (:func:`~.scan_match.icp_point_to_line`) starting from,
and drawn to, the odometry's prediction with the filter's covariance. The result is the posterior: its
information is the match's Hessian (scaled by the fit's residual and by how many independent points a scan is
worth) plus the prior's, so along a crop row or a corridor, where the walls leave the position along the row
open, the odometry carries it.

Without a saved map the localiser runs the SLAM of :mod:`.slam` online: a scan becomes a node of its pose
graph whenever the robot has moved ``node_m`` or turned ``node_rad`` since the last node; the front end
matches it to the last scans (a local map that moves with the robot) with the odometry increment as its
prior, and loop closure on the graph pulls the pose back onto the map of an earlier pass when the robot
revisits the same benches. The newest node's pose, loop closures included, corrects the filter.
A map that keeps every keyframe instead (one growing cloud) bends with the viewpoint: a hedge of bushes seen
from ahead and from abeam shows different faces, and the faces of each keyframe, inserted at its slightly
wrong pose, pull the next match the same way (1.6 % of the distance along a 50 m curved row, against
0.3 % with the local map).

A match is *poor* when too few returns fall near the map (``good_overlap``) or they fit it badly
(``good_rms_m``). After ``slow_after`` poor scans in a row the state is ``slow`` (the host loop halves the
command), after ``lost_after`` it is ``lost`` (the loop holds the robot stopped, with the reason). A scan with
too few returns (``min_points``: a blanked or blinded laser, an empty stretch of field) matches nothing and
the odometry carries the pose; the state then follows the distance driven without a correction
(``slow_after_m``, ``lost_after_m``). A lost localiser re-localises with the wide correlative search of the offline
matcher (:func:`~.scan_match.correlative_search`, metres and tens of degrees around the prediction) followed by
ICP; a fit good enough ends the lost state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import FloatArray, Pose2D, norm_angle_rad
from .occupancy import OCCUPIED, MapFileError, OccupancyGrid, load_map
from .pose_filter import FilterParams, PoseFilter, extrapolate
from .scan_match import LikelihoodGrid, PointMap, correlative_search, icp_point_to_line, transform_points, voxel_filter
from .slam import Slam, SlamParams

__all__ = ["ScanLocaliserParams", "ScanLocaliser", "map_points", "scan_localiser_for"]

OK, SLOW, LOST = "ok", "slow", "lost"


@dataclass(frozen=True)
class ScanLocaliserParams:
    """Map: ``cell_m`` (one point a cell); online, a graph node every ``node_m`` / ``node_rad``. Match:
    ``min_points`` returns at least, good when ``overlap >= good_overlap`` and ``rms <= good_rms_m``;
    ``point_sigma_m`` the smallest residual sigma of a point, ``independent_points`` how many independent
    points a scan is worth (its points share the map's errors). State: ``slow_after`` / ``lost_after`` poor
    scans in a row. Re-localising: ``relocalise_xy_m`` / ``relocalise_yaw_rad`` search window,
    ``relocalise_score`` the least mean likelihood of the points accepted. ``odo_walk_m`` / ``odo_walk_rad``: the
    odometry's error per square root of a metre driven."""

    cell_m: float = 0.05
    node_m: float = 0.05
    node_rad: float = math.radians(2.0)
    min_points: int = 10
    good_overlap: float = 0.6
    good_rms_m: float = 0.05
    point_sigma_m: float = 0.02
    independent_points: float = 4.0
    slow_after: int = 5
    lost_after: int = 15
    slow_after_m: float = 2.0
    lost_after_m: float = 5.0
    relocalise_xy_m: float = 1.5
    relocalise_yaw_rad: float = math.radians(25.0)
    relocalise_score: float = 0.5
    max_range_m: float = 20.0
    icp_iterations: int = 10
    odo_walk_m: float = 0.02
    odo_walk_rad: float = math.radians(1.0)

    def __post_init__(self) -> None:
        for k in ("cell_m", "node_m", "node_rad", "good_overlap", "good_rms_m", "point_sigma_m", "slow_after_m",
                  "lost_after_m",
                  "independent_points", "relocalise_xy_m", "relocalise_yaw_rad", "max_range_m"):
            if not getattr(self, k) > 0:
                raise ValueError(f"ScanLocaliserParams.{k} must be > 0")
        if not 0 < self.slow_after <= self.lost_after:
            raise ValueError("ScanLocaliserParams: need 0 < slow_after <= lost_after")


def map_points(grid: OccupancyGrid) -> FloatArray:
    """The centres of a map's occupied cells in the world frame, (k, 2) m."""
    rows, cols = np.nonzero(grid.cells == OCCUPIED)
    r = grid.resolution_m
    local = np.column_stack([(cols + 0.5) * r, (rows + 0.5) * r])
    return transform_points(np.asarray(grid.origin, dtype=float), local)


def _arr(p: Pose2D) -> FloatArray:
    return np.array([p.x_m, p.y_m, p.yaw_rad])


def _pose(a: FloatArray) -> Pose2D:
    return Pose2D(float(a[0]), float(a[1]), norm_angle_rad(float(a[2])))


class ScanLocaliser:
    """See the module docstring. ``start``: the odometry frame's origin in the world; ``mount``: the laser on
    the robot; ``grid``: a saved map (None: the map is built online from the first scan on)."""

    def __init__(self, start: Pose2D, mount: Pose2D = Pose2D(), grid: OccupancyGrid | None = None,
                 params: ScanLocaliserParams | None = None, filter_params: FilterParams | None = None,
                 slam_params: SlamParams | None = None) -> None:
        self.p = params or ScanLocaliserParams()
        self.mount = mount
        self.start = start
        self.filter = PoseFilter(start, None, mount, filter_params)
        self._pts = map_points(grid) if grid is not None else np.zeros((0, 2))
        if grid is not None and len(self._pts) < 3:
            raise MapFileError(f"the map has {len(self._pts)} occupied cells: nothing to localise against")
        self._ref: PointMap | None = PointMap(self._pts) if len(self._pts) >= 3 else None
        self._lik: LikelihoodGrid | None = None
        # online: the pose graph, and the odometry pose (world frame) of its last node
        self.slam: Slam | None = None if grid is not None else Slam(slam_params)
        self._last_node_odo: FloatArray | None = None
        self.state = OK
        self.reason = ""
        self.poor = 0
        self.uncorrected_m = 0.0  # driven since the last correction, m
        self.matched = 0
        self.relocalised = 0
        self.last_fit: tuple[float, float] = (1.0, 0.0)  # overlap, rms m of the last match

    # ---- the Localiser protocol ------------------------------------------------------------------
    def odometry(self, x_m: float, y_m: float, yaw_rad: float, stamp_s: float, speed_m_s: float,
                 yaw_rate_rad_s: float) -> None:
        f = self.filter
        step = 0.0
        if f.stamp_s is not None and stamp_s > f.stamp_s:
            step = math.hypot(x_m - f._last_odo.x_m, y_m - f._last_odo.y_m)
            self.uncorrected_m += step
        f.odometry(Pose2D(x_m, y_m, yaw_rad), stamp_s, speed_m_s, yaw_rate_rad_s)
        # the odometry's error as a random walk in the distance driven (the filter's own noise grows with the
        # square of each increment, which vanishes at a high report rate)
        q = self.p.odo_walk_m ** 2 * step
        f.P = f.P + np.diag([q, q, self.p.odo_walk_rad ** 2 * step])

    def pose_at(self, t_s: float) -> Pose2D:
        return self.filter.pose_at(t_s)

    def scan(self, ranges_m: FloatArray, angles_rad: FloatArray, t_s: float, range_max_m: float = math.inf) -> int:
        """Match one scan taken at ``t_s``; returns 1 when it corrected the pose, else 0."""
        p = self.p
        r = np.asarray(ranges_m, dtype=float)
        a = np.asarray(angles_rad, dtype=float)
        ok = np.isfinite(r) & (r > 0.05) & (r < min(range_max_m, p.max_range_m))
        src = voxel_filter(transform_points(_arr(self.mount), np.column_stack([r[ok] * np.cos(a[ok]),
                                                                               r[ok] * np.sin(a[ok])])), p.cell_m)
        pred = _arr(self.filter.pose_at(t_s))
        if self.slam is not None:
            return self._scan_online(src, pred, t_s)
        if len(src) < p.min_points:  # nothing to match: the odometry carries the pose
            self._check_dead_reckoning(f"{len(src)} laser returns, fewer than {p.min_points}")
            return 0
        if self.state == LOST:
            return self._relocalise(src, pred)
        assert self._ref is not None  # a saved map has points (checked when it is given)
        P = self.filter.P
        sigma2 = p.point_sigma_m ** 2
        res = icp_point_to_line(src, self._ref, pred, iterations=p.icp_iterations, max_dist_m=0.3, final_dist_m=0.1,
                                prior=pred, prior_info=sigma2 * np.linalg.inv(P))
        self.last_fit = (res.overlap, res.rms_m)
        if not (res.overlap >= p.good_overlap and res.rms_m <= p.good_rms_m):
            self._poor(f"scan match poor: {100 * res.overlap:.0f} % of the returns on the map, "
                       f"rms {res.rms_m:.3f} m")
            return 0
        s2 = max(res.rms_m, p.point_sigma_m) ** 2 * max(res.n_points / p.independent_points, 1.0)
        info = res.hessian / s2 + np.linalg.inv(P)
        self._correct(pred, res.pose, np.asarray(np.linalg.inv(info), dtype=np.float64))
        self._good()
        return 1

    def _odometry_at(self, t_s: float) -> FloatArray:
        """The odometry alone at ``t_s`` in the world frame: the last report, extrapolated with its speed and yaw
        rate."""
        f = self.filter
        o = f._last_odo
        if f.stamp_s is not None:  # as the filter's pose_at carries its estimate
            o = extrapolate(o, f.speed_m_s, f.yaw_rate_rad_s, min(t_s - f.stamp_s, 0.5))
        return _arr(self.start.compose(o))

    def _scan_online(self, src: FloatArray, pred: FloatArray, t_s: float) -> int:
        """A scan for the online SLAM: a new node when the robot has moved enough since the last one."""
        p = self.p
        slam = self.slam
        assert slam is not None
        if len(src) < p.min_points:  # nothing to match: the odometry carries the pose
            if self._last_node_odo is not None:
                self._check_dead_reckoning(f"{len(src)} laser returns, fewer than {p.min_points}")
            return 0
        odo = self._odometry_at(t_s)
        last = self._last_node_odo
        if last is not None and self.state != LOST:
            d = math.hypot(odo[0] - last[0], odo[1] - last[1])
            if d < p.node_m and abs(math.remainder(odo[2] - last[2], 2 * math.pi)) < p.node_rad:
                return 0  # not far enough from the last node: the odometry carries the pose
        guess = None
        if self.state == LOST and len(slam.graph.poses) > 0:  # the wide search over the last nodes' map first
            guess = self._wide_search(src, pred)
            if guess is None:
                return 0
        was_lost = self.state == LOST
        origin = _arr(self.mount)[:2]
        pose = slam.add_points(src, t_s, f"{t_s}", origin, odo, guess=guess)
        self._last_node_odo = odo
        res = slam.last_match
        if len(slam.graph.poses) == 1:  # the first node starts the map at the prediction
            self.filter.updates += 1
            return 0
        if res is None:
            self._poor("scan match impossible: no local map")
            return 0
        self.last_fit = (res.overlap, res.rms_m)
        P = self.filter.P
        if not (res.overlap >= p.good_overlap and res.rms_m <= p.good_rms_m):
            self._poor(f"scan match poor: {100 * res.overlap:.0f} % of the returns on the map, "
                       f"rms {res.rms_m:.3f} m")
            if res.overlap >= 0.3 and not was_lost:  # the graph took the match: the filter follows the graph
                self._correct(pred, pose, P)
            return 0
        s2 = max(res.rms_m, p.point_sigma_m) ** 2 * max(res.n_points / p.independent_points, 1.0)
        info = res.hessian / s2 + np.linalg.inv(P)
        self._correct(pred, pose, np.asarray(np.linalg.inv(info), dtype=np.float64))
        self._good(relocalised=was_lost)
        return 1

    def _wide_search(self, src: FloatArray, pred: FloatArray) -> FloatArray | None:
        """Re-localising: the correlative search over ``relocalise_xy_m`` / ``relocalise_yaw_rad`` around the
        prediction, against the points of the graph's last nodes; None (and a poor scan) when nothing fits."""
        p = self.p
        slam = self.slam
        assert slam is not None
        pts = slam.local_points(len(slam.graph.poses))
        found = correlative_search(src, LikelihoodGrid(voxel_filter(pts, p.cell_m)), pred, p.relocalise_xy_m,
                                   p.relocalise_yaw_rad)
        if found.score < p.relocalise_score:
            self._poor(f"re-localising, best fit {found.score:.2f} < {p.relocalise_score:.2f}")
            return None
        return np.asarray(found.pose, dtype=float)

    # ---- state -----------------------------------------------------------------------------------
    def status(self) -> tuple[str, str]:
        """(state, reason): ``ok``, ``slow`` or ``lost``, and why when not ok."""
        return self.state, self.reason

    @property
    def sigma(self) -> tuple[float, float, float]:
        """1-sigma of x, y (m) and yaw (rad) of the estimate."""
        return self.filter.sigma

    @property
    def sighted(self) -> int:
        """Scans that corrected the pose (the count :class:`~.post_localiser.PostLocaliser` keeps of posts)."""
        return self.matched + self.relocalised

    @property
    def map_size(self) -> int:
        """Points in the map: the saved map's, or those of every node of the online graph."""
        if self.slam is not None:
            return int(sum(len(q) for q in self.slam.points))
        return len(self._pts)

    def _poor(self, reason: str) -> None:
        self.poor += 1
        self.reason = reason
        if self.poor >= self.p.lost_after:
            self.state = LOST
        elif self.poor >= self.p.slow_after and self.state == OK:
            self.state = SLOW

    def _check_dead_reckoning(self, reason: str) -> None:
        """A scan with nothing to match: the state follows the distance driven on odometry alone."""
        d = self.uncorrected_m
        if d >= self.p.lost_after_m:
            self.state, self.reason = LOST, f"{reason}; {d:.1f} m on odometry alone"
        elif d >= self.p.slow_after_m and self.state == OK:
            self.state, self.reason = SLOW, f"{reason}; {d:.1f} m on odometry alone"

    def _good(self, relocalised: bool = False) -> None:
        self.poor = 0
        self.uncorrected_m = 0.0
        if relocalised:
            self.relocalised += 1
        else:
            self.matched += 1
        self.state, self.reason = OK, ""

    # ---- correction and the map ------------------------------------------------------------------
    def _correct(self, pred: FloatArray, post: FloatArray, cov: FloatArray) -> None:
        """Move the filter so that its pose at the scan's time is ``post`` (the correction is applied in the
        world frame to the pose at the last report, which the extrapolation then carries to the scan)."""
        f = self.filter
        dyaw = norm_angle_rad(float(post[2] - pred[2]))
        c, s = math.cos(dyaw), math.sin(dyaw)
        q = f.pose  # T(q) = R(dyaw) (q - pred) + post
        dx, dy = q.x_m - pred[0], q.y_m - pred[1]
        f.pose = Pose2D(float(post[0] + c * dx - s * dy), float(post[1] + s * dx + c * dy),
                        norm_angle_rad(q.yaw_rad + dyaw))
        f.P = 0.5 * (cov + cov.T)
        f.updates += 1

    def _relocalise(self, src: FloatArray, pred: FloatArray) -> int:
        p = self.p
        assert self._ref is not None
        if self._lik is None:
            self._lik = LikelihoodGrid(self._pts)
        found = correlative_search(src, self._lik, pred, p.relocalise_xy_m, p.relocalise_yaw_rad)
        if found.score < p.relocalise_score:
            self._poor(f"re-localising, best fit {found.score:.2f} < {p.relocalise_score:.2f}")
            return 0
        res = icp_point_to_line(src, self._ref, found.pose)
        self.last_fit = (res.overlap, res.rms_m)
        if not (res.overlap >= p.good_overlap and res.rms_m <= p.good_rms_m):
            self._poor(f"re-localising, {100 * res.overlap:.0f} % of the returns on the map")
            return 0
        s2 = max(res.rms_m, p.point_sigma_m) ** 2 * max(res.n_points / p.independent_points, 1.0)
        cov = np.asarray(np.linalg.inv(res.hessian / s2 + 1e-6 * np.eye(3)), dtype=np.float64)
        self._correct(pred, res.pose, cov)
        self._good(relocalised=True)
        return 1


def scan_localiser_for(start: Pose2D, mount: Pose2D, map_yaml: str | None = None,
                       params: ScanLocaliserParams | None = None) -> ScanLocaliser:
    """A :class:`ScanLocaliser` on a saved map (``map_yaml``, map_server YAML + PGM; raises
    :class:`~.occupancy.MapFileError` for a map that cannot be read) or on one built online (None)."""
    try:
        grid = load_map(map_yaml) if map_yaml is not None else None
    except OSError as e:
        raise MapFileError(f"{map_yaml}: cannot read the map: {e.strerror or e}") from None
    return ScanLocaliser(start, mount, grid, params)
