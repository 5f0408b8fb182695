"""Laser perception: scan cleaning, crop rows, row following, ruts, ground obstacles, obstacle tracking.

Public surface (modules with a leading underscore may change without notice)::

    ScanParams, ScanPoints, check_scan, points_from_scan, mixed_pixel_mask        scans
    RowParams, RowEstimate, ROW_METHODS, row_method_names, detect_rows,
    detect_rows_points, RowEndDetector, fit_line_lsq                              crop rows
    DriveLimits, RowFollower(Params), ProximityFollower(Params), detect_single_row,
    HeadlandTurn, headland_path                                                   controllers
    TiltedMount, GroundParams, GroundObstacles, expected_ground_range_m,
    ground_points, detect_ground_obstacles, terrain_roughness, GroundTracker,
    GroundObstacleMap, scan_with_virtual_obstacles, GroundGuard(Params)           ground
    Rut, RutEstimate, RutParams, detect_ruts, RutFollower(Params)                 ruts
    Cluster, cluster_points, clusters_from_scan, Track, TrackerParams, ObstacleTracker   obstacles
"""

from ._follow import (
    DriveLimits,
    HeadlandTurn,
    ProximityFollower,
    ProximityFollowerParams,
    RowFollower,
    RowFollowerParams,
    SingleRowEstimate,
    detect_single_row,
    headland_path,
)
from ._ground import (
    GroundObstacles,
    GroundParams,
    GroundTracker,
    TiltedMount,
    detect_ground_obstacles,
    expected_ground_range_m,
    GroundGuard,
    GroundGuardParams,
    GroundObstacleMap,
    ground_points,
    scan_with_virtual_obstacles,
    terrain_roughness,
)
from ._rows import (
    ROW_METHODS,
    RowEndDetector,
    RowEstimate,
    RowParams,
    detect_rows,
    detect_rows_points,
    fit_line_lsq,
    row_method_names,
)
from ._ruts import Rut, RutEstimate, RutFollower, RutFollowerParams, RutParams, detect_ruts
from ._scan import ScanParams, ScanPoints, check_scan, mixed_pixel_mask, points_from_scan
from ._tracking import Cluster, ObstacleTracker, Track, TrackerParams, cluster_points, clusters_from_scan

__all__ = [
    "ScanParams", "ScanPoints", "check_scan", "points_from_scan", "mixed_pixel_mask",
    "RowParams", "RowEstimate", "ROW_METHODS", "row_method_names", "detect_rows", "detect_rows_points",
    "RowEndDetector", "fit_line_lsq",
    "DriveLimits", "RowFollower", "RowFollowerParams", "ProximityFollower", "ProximityFollowerParams",
    "SingleRowEstimate", "detect_single_row", "HeadlandTurn", "headland_path",
    "TiltedMount", "GroundParams", "GroundObstacles", "expected_ground_range_m", "ground_points",
    "detect_ground_obstacles", "terrain_roughness", "GroundTracker",
    "GroundObstacleMap", "scan_with_virtual_obstacles", "GroundGuard", "GroundGuardParams",
    "Rut", "RutEstimate", "RutParams", "detect_ruts", "RutFollower", "RutFollowerParams",
    "Cluster", "cluster_points", "clusters_from_scan", "Track", "TrackerParams", "ObstacleTracker",
]
