"""APF: the artificial-potential-field waypoint controller of ref 001 with passive motion safety.

With d the distance and alpha the bearing of the current waypoint (ref 001 eqs. 2-4):

    u = 0                       d <= d_min      (waypoint reached; d_min = 0.3 m in ref 001)
    u = min(katt d^2 / 2, umax)  d_min < d < d_max
    u = umax                    d >= d_max       (eq. 13)
    r = Ka alpha + krep / d_obs               |alpha| <  alpha_max (eq. 12)
    r = +-r_max and u = 0                     |alpha| >= alpha_max (turn on the spot, eq. 14)

d_obs is the clearance to the nearest laser return beside the robot (outside the front cone, within
``side_span_rad``), taken as infinite beyond ``d_obs_threshold_m`` (eq. 11), so the repulsion only
keeps a distance from what is on the sides, as ref 001 assumes; the term turns the robot away from
that return's side (the paper gives krep / d_obs as a magnitude, the sign is our reading).

Ref 001 says the APF "avoids obstacles in its path by contouring them" but assumes the legs between
waypoints are free. For a leg that is not, the attraction acts from a shifted bearing: when a disc
of radius + ``contour_margin_m`` cannot travel ``min(d, contour_look_m)`` straight at the waypoint,
alpha in eqs. 12-14 is replaced by the free direction (5 deg candidates, +-150 deg) nearest to the
waypoint's bearing, staying on the side already being contoured while that side has a way; when the
straight way is free again alpha is the waypoint's bearing. Eqs. 12-14 themselves (including the
turn on the spot for |alpha| >= alpha_max) are unchanged. The speed is also scaled down as the
clearance ahead shrinks, so that passive safety stays the exception. ``d_min`` (ref 001: 0.3 m, its
waypoint tolerance) is lowered to 0.8 x the mission waypoint's own tolerance when that is tighter,
otherwise the robot would stop short of a 0.25 m goal for ever.

A return inside the front cone (``front_cone_rad``) closer than ``stop_m`` while driving forward
starts passive motion safety (ref 001, mirrored from the firmware's avoid layer): stop for
``stop_s``, back off ``backoff_m`` at ``backoff_speed_m_s``, wait ``wait_s`` (turning on the spot is
allowed while waiting, which lets the robot creep round a wall it faces), then resume. Waypoint
sequences come from the scenario: the simulator hands the next waypoint over as ``obs.goal``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..types import DriveCommand, Observation
from ..types import norm_angle_rad
from .base import RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view

__all__ = ["ApfParams", "ApfPlanner", "apf_linear", "apf_angular", "SafetyState"]


class SafetyState(IntEnum):
    CLEAR = 0
    STOP = 1
    BACKOFF = 2
    WAIT = 3


@dataclass(frozen=True)
class ApfParams:
    katt: float = 1.0
    umax_m_s: float | None = None  # None: the robot's max speed
    d_min_m: float = 0.3
    d_max_m: float | None = None  # None: where katt d^2 / 2 reaches umax
    ka: float = 1.2
    krep: float = 0.06
    d_obs_threshold_m: float = 0.5
    side_span_rad: float = math.radians(135.0)
    alpha_max_rad: float = math.radians(60.0)
    r_max_rad_s: float | None = None  # None: 0.8 x the robot's max yaw rate
    front_cone_rad: float = math.radians(30.0)
    stop_m: float = 0.12
    stop_s: float = 0.2
    backoff_m: float = 0.05
    backoff_speed_m_s: float = 0.1
    wait_s: float = 1.0
    contour_look_m: float = 1.0
    contour_margin_m: float = 0.08
    contour_side_cost_rad: float = math.radians(60.0)
    creep_m_s: float = 0.05  # the least speed towards a goal tighter than d_min_m, once inside d_min_m

    def __post_init__(self) -> None:
        if not (self.katt > 0 and self.d_min_m >= 0 and self.ka > 0 and self.krep >= 0 and self.d_obs_threshold_m > 0):
            raise ValueError("ApfParams: katt > 0, d_min >= 0, Ka > 0, krep >= 0, d_obs_threshold > 0")
        if not (self.backoff_speed_m_s > 0 and self.backoff_m >= 0 and self.creep_m_s > 0):
            raise ValueError("ApfParams: backoff_speed_m_s > 0, backoff_m >= 0, creep_m_s > 0")
        if not 0 < self.alpha_max_rad <= math.pi:
            raise ValueError("ApfParams.alpha_max_rad must be in (0, pi]")


def apf_linear(d_m: float, katt: float, umax: float, d_min_m: float, d_max_m: float) -> float:
    """Saturated attractive speed u(d) of ref 001 eq. 13, m/s."""
    if d_m <= d_min_m:
        return 0.0
    if d_m >= d_max_m:
        return umax
    return min(0.5 * katt * d_m * d_m, umax)


def apf_angular(alpha_rad: float, d_obs_m: float, obs_sign: float, ka: float, krep: float, alpha_max_rad: float,
                r_max: float) -> tuple[float, bool]:
    """(r, turn_in_place) of ref 001 eqs. 12 and 14. ``d_obs_m`` is inf when nothing is near;
    ``obs_sign`` is +1 to turn left (obstacle on the right), -1 to turn right."""
    if abs(alpha_rad) >= alpha_max_rad:
        return (r_max if alpha_rad >= 0 else -r_max), True
    rep = 0.0 if math.isinf(d_obs_m) else obs_sign * krep / max(d_obs_m, 1e-3)
    r = ka * alpha_rad + rep
    return max(-r_max, min(r_max, r)), False


class ApfPlanner:
    name = "apf"
    uses_sonar = False
    params_cls = ApfParams

    def __init__(self, spec: RobotSpec, params: ApfParams | None = None) -> None:
        self.spec = spec
        self.params = params or ApfParams()
        p = self.params
        self.umax = p.umax_m_s if p.umax_m_s is not None else spec.max_speed_m_s
        self.d_max = p.d_max_m if p.d_max_m is not None else math.sqrt(2.0 * self.umax / p.katt)
        self.r_max = p.r_max_rad_s if p.r_max_rad_s is not None else 0.8 * spec.max_yaw_rate_rad_s
        self._cand = np.radians(np.arange(-150.0, 150.1, 5.0))
        self.reset()

    def reset(self) -> None:
        self.state = SafetyState.CLEAR
        self._contour = 0.0
        self._t_state = 0.0
        self._backed = 0.0

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        dt = spec.control_dt_s
        view = local_view(obs, spec)
        d, alpha = goal_in_robot_frame(obs)
        # side obstacles -> d_obs and the side to turn away from (ref 001: repulsion from the sides)
        d_obs, sign = math.inf, 0.0
        front_clr = math.inf
        if len(view.range_m):
            clr = view.range_m - spec.radius_m
            b = view.bearing_rad
            m = (np.abs(b) <= p.side_span_rad) & (np.abs(b) > p.front_cone_rad)
            if m.any():
                i = int(np.argmin(np.where(m, clr, np.inf)))
                if clr[i] < p.d_obs_threshold_m:
                    d_obs = float(clr[i])
                    sign = -1.0 if b[i] > 0 else 1.0
            cone = np.abs(b) <= p.front_cone_rad
            front_clr = float(clr[cone].min()) if cone.any() else math.inf
        front = front_clr < p.stop_m
        # contouring (ref 001: "APF allows the robot to avoid obstacles in its path by contouring them"):
        # when the straight way to the waypoint is blocked, the attraction acts from the free direction
        # nearest to the waypoint's bearing on the side being contoured
        alpha_eff = alpha
        need = min(d, p.contour_look_m)
        half = spec.radius_m + p.contour_margin_m
        if float(free_distances_m(view.xy, np.array([alpha]), half, need)[0]) >= need - 1e-6:
            self._contour = 0.0
        else:
            cand = self._cand
            free = free_distances_m(view.xy, cand, half, need)
            ok = free >= need - 1e-6
            if not ok.any():
                ok = free >= 0.8 * float(free.max())
            rel = norm_angle_rad(cand - alpha)
            cost = np.abs(rel)
            if self._contour != 0.0:  # keep the side being contoured while it has a way
                same = ok & ((np.sign(rel) == self._contour) | (rel == 0.0))
                if same.any():
                    ok = same
            k = int(np.argmin(np.where(ok, cost, np.inf)))
            alpha_eff = float(cand[k])
            if self._contour == 0.0 or not (np.sign(rel[k]) == self._contour):
                self._contour = 1.0 if rel[k] >= 0 else -1.0
        # d_min is ref 001's waypoint tolerance (0.3 m); a mission with a tighter tolerance gets that
        tol = getattr(obs.goal, "tolerance_m", None)
        d_min = min(p.d_min_m, 0.8 * tol) if tol else p.d_min_m
        u = apf_linear(d, p.katt, self.umax, d_min, self.d_max)
        if d_min < d < p.d_min_m:
            # inside ref 001's own tolerance the quadratic speed falls below what the wheels turn at
            # (0.02 m/s at 0.2 m): creep the last centimetres instead of parking short of the goal
            u = max(u, p.creep_m_s, spec.min_speed_m_s)
        r, spin = apf_angular(alpha_eff, d_obs, sign, p.ka, p.krep, p.alpha_max_rad, self.r_max)
        if spin:
            u = 0.0
        else:  # slow down towards an obstacle ahead so that passive safety is the exception
            u *= max(0.0, math.cos(alpha_eff)) * min(1.0, max(0.0, front_clr - p.stop_m) / p.d_obs_threshold_m + 0.2,
                                                     (d_obs if d_obs < math.inf else 9.0) / p.d_obs_threshold_m + 0.2)
        # passive motion safety
        forward = u > 0.0 or obs.speed_m_s > 0.02
        self._t_state += dt
        if self.state == SafetyState.WAIT and self._t_state >= p.wait_s:
            self.state = SafetyState.CLEAR
        if self.state == SafetyState.CLEAR:
            if not (front and forward):
                return drive_command(spec, u, r, view, obs)
            self.state, self._t_state = SafetyState.STOP, 0.0
        if self.state == SafetyState.STOP and self._t_state >= p.stop_s and abs(obs.speed_m_s) <= 0.02:
            self.state, self._t_state, self._backed = SafetyState.BACKOFF, 0.0, 0.0
        if self.state == SafetyState.BACKOFF:
            self._backed += abs(obs.speed_m_s) * dt
            cap = 2.0 * p.backoff_m / p.backoff_speed_m_s + 0.2
            if self._backed >= p.backoff_m or self._t_state >= cap:
                self.state, self._t_state = SafetyState.WAIT, 0.0
            else:
                return drive_command(spec, -p.backoff_speed_m_s, 0.0, view, obs)
        if self.state == SafetyState.WAIT:  # turn on the spot towards the more open side (ref 001 sec. 3.4)
            if front_clr < p.d_obs_threshold_m:
                side = 1.0 if view.sector_min(0.0, 1.2, 9.0) >= view.sector_min(-1.2, 0.0, 9.0) else -1.0
                return drive_command(spec, 0.0, 0.5 * self.r_max * side, view, obs)
            return drive_command(spec, 0.0, r, view, obs)
        return drive_command(spec, 0.0, 0.0, view, obs)
