"""FLB: the fuzzy-logic planner of ref 000 (chapters 2-3) on a laser scan.

Inputs are the smallest laser ranges in three 60 deg sectors (right -90..-30, front -30..30, left
30..90 deg, ref 000 eq. 1), turned into clearances normalised by the robot radius and mapped to
Close / Medium / Far. The 27 rules of table 3-I give a heading change and a speed class
(Stop / 0.2 Vmax / Vmax); product inference, centre-of-largest-area defuzzification with the
threshold ``trsh`` (0.3 for cluttered scenes, 0.6 for simple ones, ref 000 sec. 3.4). The heading
change becomes a yaw rate ``dphi / turn_time_s``.

One addition: rules 4 and 7 (Close on both sides) stop without turning, which never ends in a
passage narrower than the Close band; after ``stall_s`` in that state the robot creeps ahead when
the straight path is free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..types import DriveCommand, Observation
from .base import RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view
from .fuzzy import DistanceSets, Inference, TurnSets, infer

__all__ = ["FlbParams", "FlbPlanner"]


@dataclass(frozen=True)
class FlbParams:
    trsh: float = 0.6
    sector_rad: float = math.radians(30.0)  # front sector half width; sides run from here to 90 deg
    horizon_m: float = 10.0  # a sector with no return reads this far
    distance_sets: DistanceSets = field(default_factory=DistanceSets)
    turn_sets: TurnSets = field(default_factory=TurnSets)
    turn_time_s: float = 0.7  # yaw rate = heading change / this
    slow_radius_m: float = 0.8  # speed scaled down inside this goal distance
    stall_s: float = 2.0
    creep_fraction: float = 0.15

    def __post_init__(self) -> None:
        if not 0.0 <= self.trsh <= 1.0:
            raise ValueError(f"FlbParams.trsh must be in [0, 1], got {self.trsh}")
        if not (self.turn_time_s > 0 and self.horizon_m > 0 and 0 < self.sector_rad < math.pi / 2):
            raise ValueError("FlbParams: turn_time_s, horizon_m must be > 0 and sector_rad in (0, 90 deg)")


class FlbPlanner:
    """Fuzzy-logic based planner (ref 000). ``last`` keeps the latest :class:`Inference`."""

    name = "flb"
    uses_sonar = False
    params_cls = FlbParams

    def __init__(self, spec: RobotSpec, params: FlbParams | None = None) -> None:
        self.spec = spec
        self.params = params or FlbParams()
        self.last: Inference | None = None
        self._stall_t = 0.0

    def reset(self) -> None:
        self.last = None
        self._stall_t = 0.0

    def sector_clearances(self, obs: Observation) -> tuple[float, float, float]:
        """Normalised clearances (left, front, right): (sector min range - radius) / radius."""
        p, r = self.params, self.spec.radius_m
        v = local_view(obs, self.spec)
        h = p.horizon_m
        d_r = v.sector_min(-math.pi / 2, -p.sector_rad, h)
        d_f = v.sector_min(-p.sector_rad, p.sector_rad, h)
        d_l = v.sector_min(p.sector_rad, math.pi / 2, h)
        return ((d_l - r) / r, (d_f - r) / r, (d_r - r) / r)

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        view = local_view(obs, spec)
        h, r = p.horizon_m, spec.radius_m
        d_r = view.sector_min(-math.pi / 2, -p.sector_rad, h)
        d_f = view.sector_min(-p.sector_rad, p.sector_rad, h)
        d_l = view.sector_min(p.sector_rad, math.pi / 2, h)
        d_goal, g_rel = goal_in_robot_frame(obs)
        inf = infer((d_l - r) / r, (d_f - r) / r, (d_r - r) / r, g_rel, p.trsh, p.distance_sets, p.turn_sets)
        self.last = inf
        turn = inf.turn_rad
        v = inf.speed_fraction * spec.max_speed_m_s * min(1.0, d_goal / p.slow_radius_m + 0.15)
        ahead = float(free_distances_m(view.xy, np.array([0.0]), r + 0.02, 1.0)[0])
        if v <= 1e-6 and abs(turn) < math.radians(5.0):
            self._stall_t += spec.control_dt_s
            if self._stall_t >= p.stall_s and ahead > 0.3:
                v = p.creep_fraction * spec.max_speed_m_s
        else:
            self._stall_t = 0.0
        if ahead < 0.05:
            v = 0.0
        return drive_command(spec, v, turn / p.turn_time_s)
