"""Time-critical motion planning (ref 003): arrive at a set pose at a set time, replan to keep it.

Public surface (the underscore modules may change without notice):

    BoundaryState, poly003_coeffs, hermite5_coeffs, cubic_coeffs, quintic_coeffs   polynomials (003 ch. 4)
    TimedLimits, TimedPlan, plan_timed, via_state                                    plans with a drivable speed law
    Seg, FamilyPath, dubins_paths, cc_paths, reeds_shepp_paths, shortest_dubins_m    path families (every reachable pose)
    SpeedLimits, SpeedProfile, solve_leg                                             speed profiles
    arc_radius_m, steer_from_arc, TrackingParams                                     003 tracking law (sec. 5.2)
    deviation_point, MovingObstacle, PlanObstacle, first_conflict                    obstacles (003 sec. 4.8)
    resolve                                                                          keep-the-time conflict resolution
    RobotTask, coordinate, plan_conflicts                                            several robots
    TimedPlanner, TimedParams                                                        the ``timed`` planner
"""

from ._multi import Coordination, RobotTask, coordinate, plan_conflicts
from ._obstacles import Conflict, MovingObstacle, PlanObstacle, deviation_point, first_blocked_s, first_conflict
from ._families import FamilyPath, Seg, cc_paths, dubins_paths, reeds_shepp_paths, shortest_dubins_m
from ._path import GeoPath, build_path
from ._plan import TimedLimits, TimedPlan, plan_timed, via_state
from ._poly import BoundaryState, cubic_coeffs, hermite5_coeffs, poly003_coeffs, poly_eval, quintic_coeffs, y_accel_from_steer
from ._profile import LegInfeasible, SpeedLimits, SpeedProfile, solve_leg
from ._resolve import Resolution, resolve
from ._tracking import TrackingParams, TrackState, arc_radius_m, steer_from_arc, track
from .planner import TimedParams, TimedPlanner

__all__ = [
    "BoundaryState", "cubic_coeffs", "quintic_coeffs", "poly003_coeffs", "hermite5_coeffs", "poly_eval", "y_accel_from_steer",
    "Seg", "FamilyPath", "dubins_paths", "cc_paths", "reeds_shepp_paths", "shortest_dubins_m",
    "GeoPath", "build_path", "TimedLimits", "TimedPlan", "plan_timed", "via_state",
    "SpeedLimits", "SpeedProfile", "LegInfeasible", "solve_leg",
    "arc_radius_m", "steer_from_arc", "TrackingParams", "TrackState", "track",
    "deviation_point", "MovingObstacle", "PlanObstacle", "Conflict", "first_conflict", "first_blocked_s",
    "Resolution", "resolve", "RobotTask", "Coordination", "coordinate", "plan_conflicts",
    "TimedPlanner", "TimedParams",
]
