"""Tracking law of ref 003 (section 5.2) with a speed law that keeps the schedule.

Steering (003 eqs. 5.1-5.3, reconstructed: the symbols survived, the layout did not): the robot at
its rear-axle centre CP reaches the next reference point RP along an arc of radius

    Rb = d / (2 sin(dtheta / 2)),        phi = atan(l / Rb),  clipped to +-phi_max,

where d is the chord to the reference point and dtheta the heading change along that arc. For an arc
tangent to the current heading, dtheta is twice the bearing alpha of RP (the chord-tangent angle),
so the law is pure pursuit with curvature 2 sin(alpha) / d. (003's Matlab listing passes alpha itself
as dtheta, which halves the gain; ``arc_gain`` = 1 reproduces that, 2 is the exact arc.) RP is the
reference path point ``lookahead`` ahead of the robot's own progress, so the steering follows the
geometry even when the robot is early or late.

Final approach (AgNav, not in 003): pure pursuit aims at a point ``lookahead`` ahead, and near the goal
that point lies on the straight beyond it, so on a plan that still turns in its last metre (a late
swerve round a box) the car under-steers the turn and stops a few degrees off the goal heading. Within
``final_approach_m`` of the goal the steering is instead the path's own curvature a servo delay ahead
plus a heading and a lateral correction,

    kappa = kappa_path(s + v * final_preview_s) - k_heading * e_heading - k_lateral * e_lateral,

a second-order law in arc length (natural frequency sqrt(k_lateral) per metre, damping
k_heading / (2 sqrt(k_lateral))); the defaults 6 /m and 9 /m^2 are critically damped at 3 per metre.

Speed: the profile's speed at time t plus a correction on the along-path error, and the band rule of
the car: below v_min the command is v_min while the robot is behind or on schedule and 0 when it is
ahead (it then waits), or while the plan brakes into or stands in a dwell and the robot is less than
``hold_behind_m`` behind. Near the goal the command drops to 0 once the remaining path is within the
stopping distance under the speed controller's lag (v * tau), so the car rolls to rest on the goal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...types import Pose2D, norm_angle_rad
from ._plan import TimedPlan

__all__ = ["arc_radius_m", "steer_from_arc", "TrackingParams", "TrackState", "track"]


def arc_radius_m(d_m: float, dtheta_rad: float) -> float:
    """Rb = d / (2 sin(dtheta / 2)), m (signed like dtheta; inf for a straight chord)."""
    s = math.sin(0.5 * dtheta_rad)
    if abs(s) < 1e-12:
        return math.inf
    return d_m / (2.0 * s)


def steer_from_arc(d_m: float, dtheta_rad: float, wheelbase_m: float, max_steer_rad: float) -> float:
    """phi = atan(l / Rb), clipped to +-max_steer_rad; rad, + = left. A reference point on the robot
    (d = 0, Rb = 0) gives full lock towards dtheta."""
    rb = arc_radius_m(d_m, dtheta_rad)
    if math.isinf(rb):
        return 0.0
    if rb == 0.0:
        return math.copysign(max_steer_rad, dtheta_rad) if dtheta_rad != 0.0 else 0.0
    phi = math.atan(wheelbase_m / rb)
    return max(-max_steer_rad, min(max_steer_rad, phi))


@dataclass(frozen=True)
class TrackingParams:
    """``lookahead_s`` / ``lookahead_min_m``: RP distance (speed times lookahead_s, at least the
    minimum), m; ``arc_gain`` see the module docstring; ``k_s`` along-path error gain, 1/s;
    ``ahead_wait_m``: ahead of schedule by more than this, a sub-band speed becomes a wait, m;
    ``stop_lag_s``: the speed controller's time constant used for the stopping distance, s;
    ``brake_m_s2``: the largest deceleration the drive gives (the lag's rate is capped there), m/s^2;
    ``hold_behind_m``: braking into or standing in a dwell (a yield to an obstacle), the car stays put unless
    it is behind schedule by more than this, m (creeping at v_min to the planned stopping point would carry
    it towards what it yields to, and each new stop plan from a rolling start lies further on);
    ``final_*``: the final-approach law of the module docstring (0 ``final_approach_m`` turns it off)."""

    lookahead_s: float = 0.7
    lookahead_min_m: float = 0.35
    arc_gain: float = 2.0
    k_s: float = 0.8
    ahead_wait_m: float = 0.10
    stop_lag_s: float = 0.25
    control_dt_s: float = 0.05
    brake_m_s2: float = 2.0
    hold_behind_m: float = 0.15
    final_approach_m: float = 1.5
    final_k_heading_per_m: float = 6.0
    final_k_lateral_per_m2: float = 9.0
    final_preview_s: float = 0.2


@dataclass
class TrackState:
    """What the tracker reports each step (and keeps between steps: ``s_m``)."""

    s_m: float = 0.0  # robot progress along the path, m
    s_ref_m: float = 0.0  # where the schedule wants it, m
    lateral_m: float = 0.0
    v_ref_m_s: float = 0.0
    remaining_m: float = 0.0
    stopping: bool = False


def track(plan: TimedPlan, pose: Pose2D, speed_m_s: float, t_s: float, st: TrackState,
          p: TrackingParams) -> tuple[float, float]:
    """(speed m/s, steering rad) for the robot at ``pose`` at time ``t_s`` following ``plan``.
    Updates ``st`` in place."""
    lim = plan.limits
    path = plan.path
    s_rob, lat = path.project(pose.x_m, pose.y_m, st.s_m, window_m=max(1.0, 3.0 * abs(speed_m_s) + 0.5))
    st.s_m, st.lateral_m = s_rob, lat
    s_ref_a, v_ref_a = plan.profile.eval(t_s - plan.t0_s)
    s_ref, v_ref = float(s_ref_a), float(v_ref_a)
    st.s_ref_m, st.v_ref_m_s = s_ref, v_ref
    gx, gy = plan.goal.x_m, plan.goal.y_m
    remaining = max(path.length_m - s_rob, 0.0)
    # the path's end: use the true distance along the goal heading once close
    c, s = math.cos(plan.goal.yaw_rad), math.sin(plan.goal.yaw_rad)
    along_goal = (gx - pose.x_m) * c + (gy - pose.y_m) * s
    if remaining < 0.5:
        remaining = along_goal
    st.remaining_m = remaining
    if remaining < p.final_approach_m:
        # ---- steering near the goal: the final-approach law (module docstring) ------------------
        _, _, yaw, kap = path.sample(np.array([s_rob, s_rob + abs(speed_m_s) * p.final_preview_s]))
        e_heading = norm_angle_rad(pose.yaw_rad - float(yaw[0]))
        kappa = float(kap[1]) - p.final_k_heading_per_m * e_heading - p.final_k_lateral_per_m2 * lat
        steer = max(-lim.max_steer_rad, min(lim.max_steer_rad, math.atan(lim.wheelbase_m * kappa)))
    else:
        # ---- steering: 003 arc to the reference point ----------------------------------------
        L = max(p.lookahead_min_m, p.lookahead_s * max(abs(speed_m_s), v_ref))
        rx, ry, _, _ = path.sample(s_rob + L)
        dx, dy = float(rx) - pose.x_m, float(ry) - pose.y_m
        alpha = norm_angle_rad(math.atan2(dy, dx) - pose.yaw_rad)
        if abs(alpha) > 0.5 * math.pi:
            # the reference point is behind: the arc through it would be nearly straight (Rb -> inf as alpha
            # -> 180 deg) and drive away from the path; turn towards it at full lock instead
            steer = math.copysign(lim.max_steer_rad, alpha)
        else:
            steer = steer_from_arc(math.hypot(dx, dy), p.arc_gain * alpha, lim.wheelbase_m, lim.max_steer_rad)
    # ---- speed: schedule + along-path correction, band rule, stop on the goal -----------------
    err = s_ref - s_rob  # > 0: behind schedule
    v = v_ref + p.k_s * err
    v = min(v, lim.v_max_m_s)
    # stopping distance under the speed controller: first-order lag tau, deceleration capped at a_brake
    # (rate-limited while v / tau > a_brake, exponential below), plus half a control period of travel
    v_now, tau, ab = abs(speed_m_s), p.stop_lag_s, p.brake_m_s2
    if v_now > ab * tau:
        stop_d = (v_now * v_now - (ab * tau) ** 2) / (2.0 * ab) + ab * tau * tau
    else:
        stop_d = v_now * tau
    stop_d += 0.5 * v_now * p.control_dt_s
    if remaining <= stop_d or remaining <= 0.0:
        st.stopping = True
        return 0.0, steer
    st.stopping = False
    if v < lim.v_min_m_s:
        if (err < -p.ahead_wait_m or v_ref <= 0.0 and err < 0.02
                or err < p.hold_behind_m and plan.profile.coming_to_rest(t_s - plan.t0_s)):
            v = 0.0  # early, or stopping for a planned dwell (a yield): wait
        else:
            v = lim.v_min_m_s
    return v, steer
