"""The referee of a simulated run: judges the robot's *true* pose after every physics step, whoever drives it
(the ideal runner, the lock-step SIL, or the SIL served to ``agnav run`` over TCP).

A run ends on a collision (the footprint's clearance below 0; a field's plants and weeds are soft and not in it),
on falling into a hole (the footprint's centre
over ground more than :data:`HOLE_FALL_DEPTH_M` below nominal) or on arrival at the last goal; the goals count
in order, each within its tolerance. Without any of these it is a ``timeout`` when its time is up. On a whole field
(a scenario with ``[field]``) the referee also keeps the footprint's track and scores it (:meth:`Referee.field_score`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .scenario import Scenario

__all__ = ["Referee", "HOLE_FALL_DEPTH_M", "END_REASONS"]

HOLE_FALL_DEPTH_M = 0.1  # the robot's centre over ground this far below nominal counts as fallen in
END_REASONS = ("arrived", "collision", "fell_in_hole", "timeout")


class Referee:
    """Call :meth:`judge` after every physics step; it returns the end reason once the run is over (None before)
    and keeps ``goal_index`` (the goal the robot is heading for) and ``arrival_s``."""

    def __init__(self, sc: Scenario) -> None:
        self.goals = list(sc.goals)
        self.world = sc.world
        self.goal_index = 0
        self.reason = "timeout"
        self.arrival_s: float | None = None
        self.ended = False
        self.scenario = sc
        # a whole field: the footprint's centre at every judged step (t_s, x_m, y_m), scored at the end
        self._track: list[tuple[float, float, float]] | None = [] if sc.field is not None else None
        self._radius_m: float | None = None

    def judge(self, t_s: float, robot: Any, clearance_m: float) -> str | None:
        """``robot``: the true robot model (``pose``, ``footprint_centre()``); ``clearance_m``: its footprint's
        clearance to the nearest obstacle at ``t_s``."""
        if self.ended:
            return self.reason
        if self._track is not None:
            cx, cy = robot.footprint_centre()
            self._track.append((t_s, float(cx), float(cy)))
            self._radius_m = float(robot.radius_m)
        if clearance_m < 0.0:
            return self._end("collision")
        if self.world.has_ground_features:
            cx, cy = robot.footprint_centre()
            if float(self.world.ground_height_m(np.array(cx), np.array(cy))) < -HOLE_FALL_DEPTH_M:
                return self._end("fell_in_hole")
        p = robot.pose
        g = self.goals[self.goal_index]
        if math.hypot(g.x_m - p.x_m, g.y_m - p.y_m) <= g.tolerance_m:
            if self.goal_index + 1 < len(self.goals):
                self.goal_index += 1
            else:
                self.arrival_s = t_s
                return self._end("arrived")
        return None

    def _end(self, reason: str) -> str:
        self.reason = reason
        self.ended = True
        return reason

    def field_score(self, t0_s: float = 0.0) -> Any:
        """The run scored on the scenario's field (:func:`~agnav_host.sim.field_gen.score_field`: lanes in the
        pattern's order, stems run over, the Field Robot Event's distance, time and score), its times counted
        from ``t0_s``; None off a field."""
        if self._track is None or self._radius_m is None:
            return None
        from .field_gen import score_field

        tr = np.asarray(self._track, dtype=float)
        return score_field(self.scenario, tr[:, 0] - t0_s, tr[:, 1:3], self._radius_m)
