"""``timed``: the time-critical planner of ref 003 as a host planner (Observation -> DriveCommand).

Each control step:

1. **plan** when the timed target changes: from the current state to the first goal with an
   ``arrival_s`` (earlier untimed goals become via points, 003's multiple waypoints), arriving at that
   absolute time. An impossible time is reported (``status``) and the plan is timed for the earliest
   feasible arrival instead.
2. **static obstacles** (laser and/or sonar returns, unknown in advance): if returns block the
   footprint within ``detect_range_m`` along the plan, the 003 deviation point is computed from the
   detection (range, bearing, size) and a new plan through it keeps the arrival time (catch-up).
3. **moving obstacles** (tracks in ``obs.extras["tracks"]``; without them, perception's
   :class:`~agnav_host.perception.ObstacleTracker` runs on the laser scans, placed with the pose the
   scan carries (the host's believed pose), and its *moving* tracks are used; and other robots'
   plans in ``obs.extras["peer_plans"]``; a track where a peer's plan puts that robot is taken as
   the robot and left to its plan): the plan is checked in space-time against each track predicted with
   its velocity and growing uncertainty; a conflict is resolved by waiting, then by deviating, keeping
   the arrival time where possible (:mod:`._resolve`).
4. **delays** (dead band, slip, a safety stop by the firmware): when the robot is more than
   ``delay_replan_m`` behind its schedule, replan from where it is to the same goal and time; when that
   is no longer feasible the new earliest arrival goes into ``status``.
5. **track** the plan with the 003 arc law (:mod:`._tracking`).

Every replanning call builds and checks at most ``max_candidates`` plans: a longer conflict search
keeps the current plan, reports "searching" and goes on at the next control step (:mod:`._resolve`).
``replan_budget_s`` is a wall-time backstop only (:class:`~agnav_host.planning.base.DeadlineMissed`
inside; the planner then keeps its current plan and doubles the budget of its next try, up to 16x).
Each call's wall and CPU time and its work go to ``replan_times_s``, ``replan_cpu_s`` and
``replan_work``. Python's automatic garbage collection is held off during a replanning call: a
collection that falls due inside it (a full one takes up to 2.4 ms on a long run's heap) runs when the
call returns, in the same control step, rather than inside the call (:func:`collection_deferred`).

Speed commands are never below ``command_min_m_s``: the firmware maps a setpoint under its speed
table's first point to neutral, which stopped the car in the middle of its final creep.
"""

from __future__ import annotations

import gc
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Iterable, Iterator, cast

import numpy as np
import numpy.typing as npt

from ...types import DriveCommand, FloatArray, Goal, Observation, Pose2D, norm_angle_rad
from ...perception._tracking import ObstacleTracker, Track, TrackerParams
from ..base import DeadlineMissed, RobotSpec, arc_blocked
from ._obstacles import (MovingObstacle, PlanObstacle, SpaceTimeObstacle, cluster_labels, deviation_point,
                         first_blocked_s, first_conflict, moving_obstacles_from)
from ._plan import TimedLimits, TimedPlan, plan_timed, via_state
from ._poly import BoundaryState
from ._resolve import hurry_plan, resolve
from ._tracking import TrackingParams, TrackState, track

__all__ = ["TimedParams", "TimedPlanner"]
#: static searches with nothing clear before the clearance is down to 0 (halved at each)
SQUEEZE_STEPS = 3


@contextmanager
def collection_deferred() -> Iterator[None]:
    """Hold off Python's automatic garbage collection for the block; a collection that fell due inside
    it runs at the first allocation after it. Nested use and a collector already disabled are kept."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


@dataclass(frozen=True)
class TimedParams:
    """Parameters of the ``timed`` planner (SI, angles in deg where named so)."""

    max_steer_deg: float = 20.0  # never command more
    plan_steer_deg: float = 17.0  # plans use at most this
    accel_m_s2: float = 1.0
    safety_margin_m: float = 0.15  # Rsm of 003 eq. 4.29
    robot_width_m: float = 0.22  # w of 003 eq. 4.29 (RC car body)
    detect_range_m: float = 2.5  # returns blocking the plan within this (along the path) trigger a deviation
    static_clear_m: float = 0.08  # clearance a new plan must keep between the footprint and static returns
    static_trigger_m: float = 0.02  # the current plan is replanned when it comes closer than this (hysteresis)
    moving_margin_m: float = 0.12  # clearance kept to predicted moving obstacles / other robots
    horizon_s: float = 6.0  # space-time look-ahead
    delay_replan_m: float = 0.25  # schedule error that triggers a catch-up replan
    early_retime_s: float = 0.5  # a plan arriving this much before the requested time (after a hurry) is re-timed
    min_replan_interval_s: float = 0.4
    replan_budget_s: float = 0.050  # wall-time backstop of one replanning call, for pathological cases only (the work bound is max_candidates)
    max_candidates: int = 2  # plans built and checked per replanning call; a longer search goes on at the next steps
    use_sonar: bool = True
    lookahead_s: float = 0.7
    lookahead_min_m: float = 0.35
    arc_gain: float = 2.0
    k_s: float = 0.8
    stop_lag_s: float = 0.25
    speed_ratio_gain: float = 0.05  # per step, learning rate of the measured/commanded speed ratio
    # smallest nonzero speed command. The firmware maps a setpoint below its speed table's first point
    # to neutral (stop): that point is 43.5 cm/s rounded to a whole PWM count, 446 mm/s in the default
    # table, so commands never go below 0.45 m/s (slower plans are driven through the speed ratio)
    command_min_m_s: float = 0.45
    # smallest nonzero steering commands, left and right. The firmware maps an angle below its steering
    # table's first point on that side to neutral (straight); the default table's first whole PWM counts
    # steer 0.65 deg left (PWM 134) and 1.03 deg right (PWM 132). Any smaller nonzero wanted angle is
    # sent as the step, so that the tracker's small corrections reach the wheels: alternating with
    # straight they average out (sent as they are, they would all be straight, and the 100 m run of the
    # timed benchmark ended 3 deg off its heading instead of 0.13); 0 sends the angle as it is
    steer_step_left_deg: float = 0.65
    steer_step_right_deg: float = 1.03
    # moving obstacles from perception's tracker on the scans when obs.extras has no "tracks"
    track_from_scan: bool = True
    track_coast_s: float = 1.0  # a track survives this long unseen (occlusions), predicted on its velocity
    peer_match_m: float = 0.5  # a track this close to where another robot's plan puts that robot is that robot

    def __post_init__(self) -> None:
        if not 0 < self.plan_steer_deg <= self.max_steer_deg < 90:
            raise ValueError("TimedParams: need 0 < plan_steer_deg <= max_steer_deg < 90")
        if self.max_candidates < 1:
            raise ValueError(f"TimedParams.max_candidates must be >= 1, got {self.max_candidates}")
        for k in ("steer_step_left_deg", "steer_step_right_deg"):
            if not 0 <= getattr(self, k) < self.max_steer_deg:
                raise ValueError(f"TimedParams.{k} must be in [0, max_steer_deg), got {getattr(self, k)}")
        for k in ("accel_m_s2", "detect_range_m", "horizon_s", "replan_budget_s", "lookahead_min_m", "command_min_m_s"):
            if not getattr(self, k) > 0:
                raise ValueError(f"TimedParams.{k} must be > 0, got {getattr(self, k)}")


class TimedPlanner:
    """Time-critical planner (registry name ``timed``); see the module docstring."""

    name = "timed"
    params_cls = TimedParams
    uses_sonar = True

    def __init__(self, spec: RobotSpec | None = None, params: TimedParams | None = None) -> None:
        self.spec = spec or RobotSpec(kinematics="ackermann", radius_m=0.16, max_speed_m_s=1.0, min_speed_m_s=0.435,
                                      max_accel_m_s2=2.0, wheelbase_m=0.174, footprint_offset_m=0.087, control_dt_s=0.05)
        self.params = p = params or TimedParams()
        # a differential drive follows the same car-like plans by yaw rate; its own speed lag, no dead band
        self._car = self.spec.kinematics == "ackermann"
        stop_lag_s = p.stop_lag_s if self._car else self.spec.stop_lag_s
        self.limits = TimedLimits.from_spec(self.spec, max_steer_rad=min(math.radians(p.max_steer_deg), self.spec.max_steer_rad),
                                            plan_steer_rad=min(math.radians(p.plan_steer_deg), self.spec.max_steer_rad),
                                            accel_m_s2=min(p.accel_m_s2, self.spec.max_accel_m_s2),
                                            stop_lag_s=stop_lag_s)
        self.track_params = TrackingParams(p.lookahead_s, p.lookahead_min_m, p.arc_gain, p.k_s, 0.10, stop_lag_s,
                                           self.spec.control_dt_s, self.spec.max_accel_m_s2)
        self.reset()

    # ---- lifecycle ----------------------------------------------------------------------------
    def reset(self) -> None:
        self.plan: TimedPlan | None = None
        self.ts = TrackState()
        self._key: tuple[float, ...] | None = None
        self._last_steer = 0.0
        self._last_replan_t = -math.inf
        self._budget_scale = 1.0
        self._squeeze = 0  # searches for a static deviation that ended with no clear candidate, in a row
        self._search: tuple[str, int, Any] | None = None  # (trigger, next candidate, best late candidate) of a search in progress
        self.replan_work: list[tuple[int, int]] = []  # per replanning call: (candidates built and checked, candidates screened out)
        self._last_v_cmd = 0.0
        self._prev_speed = 0.0
        self.speed_ratio = 1.0  # measured / commanded speed, learnt while cruising (slip, worn motor, table error)
        self.replan_times_s: list[float] = []  # wall time of each replanning call
        self.replan_cpu_s: list[float] = []  # CPU time of the planner's thread in it (what a shared, loaded machine does not inflate)
        self.events: list[tuple[float, str]] = []
        self.tracker = ObstacleTracker(TrackerParams(max_coast_s=self.params.track_coast_s, max_grow_m=0.15, max_shrink_m=0.15))
        self.tracked_moving: list[Track] = []  # the tracker's moving tracks at the last step
        self.status: dict[str, Any] = {"feasible": None, "reason": "no plan yet", "earliest_arrival_s": None,
                                       "arrival_s": None, "replans": 0, "last_action": None, "deadline_misses": 0}

    def set_plan(self, plan: TimedPlan, goal: Goal) -> None:
        """Adopt a plan made elsewhere (e.g. by :func:`coordinate` for several robots) for ``goal``."""
        self.plan = plan
        self.ts = TrackState()
        self._key = self._goal_key(goal)
        self._set_status(plan, "coordinated plan")

    # ---- helpers ----------------------------------------------------------------------------------
    @staticmethod
    def _goal_key(g: Goal) -> tuple[float, ...]:
        return (g.x_m, g.y_m, math.nan if g.yaw_rad is None else g.yaw_rad, math.nan if g.arrival_s is None else g.arrival_s)

    def _mission(self, obs: Observation) -> tuple[Goal, list[Goal]]:
        """(timed target, untimed goals before it)."""
        goals = obs.extras.get("goals")
        gi = obs.extras.get("goal_index", 0)
        if isinstance(goals, list) and goals and isinstance(gi, int):
            rest = goals[gi:]
            for k, g in enumerate(rest):
                if g.arrival_s is not None:
                    return g, rest[:k]
            return rest[-1], rest[:-1]
        return obs.goal, []

    def _state_now(self, obs: Observation) -> BoundaryState:
        v = max(0.0, obs.speed_m_s)
        return BoundaryState(obs.pose.x_m, obs.pose.y_m, obs.pose.yaw_rad, self._last_steer, v)

    def _set_status(self, plan: TimedPlan, action: str) -> None:
        self.status.update(feasible=plan.feasible, reason=plan.reason, earliest_arrival_s=plan.earliest_arrival_s,
                           arrival_s=plan.arrival_s, last_action=action)

    def _remaining_vias(self) -> tuple[BoundaryState, ...]:
        if self.plan is None:
            return ()
        knots = self.plan.path.knots_s
        vias = self.plan.states[1:-1]
        return tuple(v for k, v in enumerate(vias) if self.ts.s_m < knots[k + 1] - 0.3)

    def _initial_plan(self, obs: Observation, target: Goal, before: list[Goal]) -> None:
        pts = [(obs.pose.x_m, obs.pose.y_m)] + [(g.x_m, g.y_m) for g in before] + [(target.x_m, target.y_m)]
        vias = tuple(via_state(pts[i - 1], pts[i], pts[i + 1]) for i in range(1, len(pts) - 1))
        prev = pts[-2]
        yaw = target.yaw_rad if target.yaw_rad is not None else math.atan2(target.y_m - prev[1], target.x_m - prev[0])
        goal = BoundaryState(target.x_m, target.y_m, yaw, 0.0, 0.0)
        plan = plan_timed(self._state_now(obs), goal, obs.t_s, target.arrival_s, self.limits, vias)
        self.plan = plan
        self.ts = TrackState()
        self._key = self._goal_key(target)
        self._set_status(plan, "plan")
        self.events.append((obs.t_s, f"plan: {plan.reason}"))

    def _returns(self, obs: Observation) -> FloatArray:
        """Every laser and sonar return within ``detect_range_m + 1`` in the world frame, (n, 2) m."""
        chunks = []
        rng_max = self.params.detect_range_m + 1.0
        if obs.scan is not None:
            sp = obs.scan.pose if obs.scan.pose is not None else obs.pose
            r = obs.scan.ranges_m
            a = obs.scan.angles_rad + sp.yaw_rad
            ok = np.isfinite(r) & (r > 0.0) & (r < rng_max)
            chunks.append(np.column_stack((sp.x_m + r[ok] * np.cos(a[ok]), sp.y_m + r[ok] * np.sin(a[ok]))))
        if self.params.use_sonar and obs.sonar is not None:
            r = np.asarray(obs.sonar.ranges_m, dtype=float)
            b = obs.pose.yaw_rad + self.spec.sonar_spacing_rad * np.arange(len(r))
            ok = np.isfinite(r) & (r < rng_max)
            d = r[ok] + self.spec.sonar_mount_radius_m
            cx = obs.pose.x_m + self.spec.footprint_offset_m * math.cos(obs.pose.yaw_rad)
            cy = obs.pose.y_m + self.spec.footprint_offset_m * math.sin(obs.pose.yaw_rad)
            chunks.append(np.column_stack((cx + d * np.cos(b[ok]), cy + d * np.sin(b[ok]))))
        return np.concatenate(chunks) if chunks else np.zeros((0, 2))

    @staticmethod
    def _static_points(pts: FloatArray, seen_movers: list[SpaceTimeObstacle], t_s: float) -> FloatArray:
        """The returns less those of the moving obstacles (their discs now plus 0.25 m): the planner
        treats those in space-time instead. Only movers seen in this scan (and peers, placed by their plans)
        take returns away: a track coasting through an occlusion is where its velocity puts it, which may be
        on a wall or a box that then vanished from every check (a phantom track once took a box's face away
        and the car drove into it)."""
        if not (len(pts) and seen_movers):
            return pts
        keep = np.ones(len(pts), dtype=bool)
        for m in seen_movers:
            xy, r = m.predict(np.array([t_s]))
            keep &= np.hypot(pts[:, 0] - xy[0, 0], pts[:, 1] - xy[0, 1]) > r[0] + 0.25
        return pts[keep]

    def _sensor_pose(self, obs: Observation) -> Pose2D:
        if obs.scan is not None and obs.scan.pose is not None:
            return obs.scan.pose
        off = self.spec.footprint_offset_m
        return Pose2D(obs.pose.x_m + off * math.cos(obs.pose.yaw_rad), obs.pose.y_m + off * math.sin(obs.pose.yaw_rad), obs.pose.yaw_rad)

    @staticmethod
    def _beside_blocking(pts: FloatArray, c: npt.NDArray[np.intp], blocks: npt.NDArray[np.bool_], t_hat: FloatArray,
                         reach_m: float = 0.5) -> npt.NDArray[np.intp]:
        """The part of cluster ``c`` (indices into ``pts``, beam order) that lies along the plan (unit
        direction ``t_hat`` where it is blocked) within ``reach_m`` of its blocking returns (``blocks``,
        mask over ``c``): a box standing against a wall is one cluster with the wall, and the whole of it
        as "the obstacle" is as wide as the wall seen, so every deviation point landed beyond the wall."""
        along = pts[c] @ t_hat
        a_blk = along[blocks]
        keep = (along >= a_blk.min() - reach_m) & (along <= a_blk.max() + reach_m)
        out: npt.NDArray[np.intp] = c[keep]
        return out

    def _deviation_points(self, obs: Observation, pts: FloatArray, mask: np.ndarray,
                          s_blk_m: float) -> list[tuple[str, tuple[float, float]]]:
        """003 deviation points (eqs. 4.29-4.32) for the nearest obstacle that blocks the plan, preferred
        side first. The obstacle is the cluster of returns around the blocking ones, as far as it lies
        along the plan within 0.5 m of them (its size and mid bearing come from all of that, as in 003's
        listing: mid of the detected angles). A point that lands in a gap between returns on both sides
        comes first moved to the middle of the gap (:meth:`_centred_in_gap`)."""
        assert self.plan is not None
        sen = self._sensor_pose(obs)
        rel = pts - np.array([sen.x_m, sen.y_m])
        b_rel = norm_angle_rad(np.arctan2(rel[:, 1], rel[:, 0]) - sen.yaw_rad)
        order = np.argsort(b_rel)
        labels = cluster_labels(pts[order], 0.3)  # cluster of each return, in beam order
        dist = np.hypot(rel[:, 0], rel[:, 1])
        # of the clusters with a blocking return, the one nearest the sensor (the first such in beam order on a tie)
        blocking = np.zeros(int(labels[-1]) + 1, dtype=bool)
        blocking[labels[mask[order]]] = True
        cand = np.flatnonzero(blocking[labels])
        near = labels[cand[int(np.argmin(dist[order[cand]]))]]
        c = order[labels == near]
        path = self.plan.path
        yaw_blk = float(np.interp(min(max(s_blk_m, 0.0), path.length_m), path.s, path.yaw))  # path.sample's yaw
        t_hat = np.array([math.cos(yaw_blk), math.sin(yaw_blk)])  # the plan's direction where blocked
        c = self._beside_blocking(pts, c, mask[c], t_hat)
        d_dect = float(dist[c].min())
        bc = b_rel[c]
        theta_dect = sen.yaw_rad + 0.5 * float(bc.min() + bc.max())
        ends = pts[c[[int(bc.argmin()), int(bc.argmax())]]]
        r_obs = max(0.05, 0.5 * float(np.hypot(*(ends[1] - ends[0]))))
        p = self.params
        lim = self.limits
        # the lateral offset Rsm + w must clear the obstacle's radius plus the footprint: grow Rsm if not
        r_sm = max(p.safety_margin_m, r_obs + lim.radius_m + p.static_clear_m + 0.05 - p.robot_width_m)
        # side: away from the obstacle's centre relative to the planned path near the detection
        cx, cy = float(pts[c, 0].sum()) / len(c), float(pts[c, 1].sum()) / len(c)  # the means
        _, lat = self.plan.path.project(cx, cy, self.ts.s_m + d_dect, window_m=2.0)
        first = -1 if lat > 0 else 1
        out = []
        for extra in (0.0, 0.3, 0.6):
            for side in (first, -first):
                _, _, xd, yd = deviation_point(sen.x_m, sen.y_m, d_dect, theta_dect, r_obs, r_sm + extra, p.robot_width_m, side)
                name = f"deviate {'left' if side > 0 else 'right'}"
                mid = self._centred_in_gap(pts, (xd, yd), t_hat) if extra == 0.0 else None
                if mid is not None:
                    out.append((f"{name} (middle of the gap)", mid))
                out.append((f"{name} (003 point{'' if extra == 0 else f' +{extra:.1f} m'})", (xd, yd)))
        return out

    def _centred_in_gap(self, pts: FloatArray, via_xy: tuple[float, float], t_hat: FloatArray,
                        half_length_m: float = 0.35) -> tuple[float, float] | None:
        """``via_xy`` moved across the plan (unit direction ``t_hat``) to the middle of the free stretch it
        lies in, when returns bound that stretch on both sides within ``half_length_m`` along the plan and
        it is wider than the footprint; None otherwise (open on a side, too narrow, or already in the
        middle). The 003 point is placed from one obstacle only: between two crates 0.5 m apart it put the
        car 4 cm off the middle, where laser noise on the other crate's face kept stopping it."""
        n_hat = np.array([-t_hat[1], t_hat[0]])
        rel = pts - np.asarray(via_xy)
        along, lat = rel @ t_hat, rel @ n_hat
        near = np.abs(along) <= half_length_m
        below, above = lat[near & (lat < 0.0)], lat[near & (lat > 0.0)]
        if len(below) == 0 or len(above) == 0:
            return None
        lo, hi = float(below.max()), float(above.min())
        mid = 0.5 * (lo + hi)
        if hi - lo <= 2.0 * self.limits.radius_m or abs(mid) < 0.01:
            return None
        return float(via_xy[0] + mid * n_hat[0]), float(via_xy[1] + mid * n_hat[1])

    # ---- step ---------------------------------------------------------------------------------
    def step(self, obs: Observation) -> DriveCommand:
        t = obs.t_s
        target, before = self._mission(obs)
        if self.plan is None or self._goal_key(target) != self._key:
            self._initial_plan(obs, target, before)
        assert self.plan is not None
        if len(self.plan.path.s) < 2:
            # no drivable path to this goal (the status says why): stay stopped
            self._last_steer = 0.0
            self._last_v_cmd = 0.0
            return DriveCommand(0.0, 0.0, 0.0)
        p = self.params
        given = obs.extras.get("tracks", obs.extras.get("moving_obstacles"))
        if given is None and p.track_from_scan and obs.scan is not None and obs.scan.pose is not None:
            self.tracked_moving = [tr for tr in self.tracker.update(obs.scan, t, movers_only=True) if tr.moving]
            given = self.tracked_moving
        given_list: list[Any] = [] if given is None else list(cast(Iterable[Any], given))
        tracks = moving_obstacles_from(given_list, t)
        seen_now = [float(getattr(g, "unseen_s", 0.0)) <= 0.0 for g in given_list]
        peer_plans = obs.extras.get("peer_plans")
        peers = [PlanObstacle(pp, pp.limits.radius_m) for pp in list(cast(Iterable[Any], peer_plans or []))]
        if peers and tracks:  # a track where a peer's plan puts it is that robot: its plan predicts it better
            keep_t = [not _is_peer(m, peers, t, p.peer_match_m) for m in tracks]
            tracks = [m for m, k in zip(tracks, keep_t) if k]
            seen_now = [s for s, k in zip(seen_now, keep_t) if k]
        movers: list[SpaceTimeObstacle] = list(tracks)
        movers += peers
        returns = self._returns(obs)
        pts = self._static_points(returns, [m for m, s in zip(tracks, seen_now) if s] + list(peers), t)
        # progress is needed by the checks: a cheap projection first
        self.ts.s_m, _ = self.plan.path.project(obs.pose.x_m, obs.pose.y_m, self.ts.s_m,
                                                window_m=max(1.0, 3.0 * abs(obs.speed_m_s) + 0.5))
        due = self._search is not None or t - self._last_replan_t >= p.min_replan_interval_s
        if not self.ts.stopping and due and self.plan.path.length_m - self.ts.s_m > 0.6:
            with collection_deferred():
                self._maybe_replan(obs, target, pts, movers)
        v, steer = track(self.plan, obs.pose, obs.speed_m_s, t, self.ts, self.track_params)
        # learn how fast the car really goes for a command, and command through that ratio
        if self._last_v_cmd >= self.limits.v_min_m_s and obs.speed_m_s > 0.2 and abs(obs.speed_m_s - self._prev_speed) < 0.01:
            ratio = obs.speed_m_s / self._last_v_cmd
            self.speed_ratio = min(1.4, max(0.6, self.speed_ratio + p.speed_ratio_gain * (ratio - self.speed_ratio)))
        self._prev_speed = obs.speed_m_s
        if v > 0.0 and not self.ts.stopping:
            floor = p.command_min_m_s if self._car else 0.0  # the car's dead band
            v = min(max(v / self.speed_ratio, self.limits.v_min_m_s, floor), self.limits.v_max_m_s)
        # last line of defence: any return (a mover's too) inside the footprint's way within the braking
        # distance, along the plan and along the arc the car is on (it lags the plan: servo rate, speed lag;
        # turning into a gap it once swept a crate's corner the plan cleared)
        if len(returns) and v > 0:
            reach = 0.25 + obs.speed_m_s * p.stop_lag_s
            blk = first_blocked_s(self.plan, returns, self.ts.s_m, self.ts.s_m + reach, 0.0)
            arc_m = min(reach, self.plan.path.length_m - self.ts.s_m)  # not past the goal: the car stops there
            if blk is not None or arc_blocked(obs.pose.x_m, obs.pose.y_m, obs.pose.yaw_rad, self._kappa_now(obs), arc_m,
                                              returns, self.limits.radius_m, self.limits.footprint_offset_m):
                v = 0.0
        # the next plan starts from the tracker's wanted angle; the one sent differs by less than a step
        self._last_steer = steer
        self._last_v_cmd = v
        if not self._car:
            return DriveCommand(v, v * math.tan(steer) / self.limits.wheelbase_m, None)
        step = math.radians(p.steer_step_left_deg if steer > 0.0 else p.steer_step_right_deg)
        if 0.0 < abs(steer) < step:
            steer = math.copysign(step, steer)
        return DriveCommand(v, 0.0, steer)

    def _kappa_now(self, obs: Observation) -> float:
        """The curvature the car is on, 1/m: from its yaw rate when it moves, else from the steering
        angle last asked for."""
        if abs(obs.speed_m_s) > 0.1:
            k = obs.yaw_rate_rad_s / obs.speed_m_s
        else:
            k = math.tan(self._last_steer) / self.limits.wheelbase_m
        k_max = math.tan(self.limits.max_steer_rad) / self.limits.wheelbase_m
        return max(-k_max, min(k_max, k))

    def _clear(self, plan: TimedPlan, t: float, movers: list[SpaceTimeObstacle], pts: FloatArray, margin_m: float,
               clear_m: float) -> bool:
        """No predicted contact with a mover over the horizon (``margin_m`` of clearance) and no static return
        within ``clear_m`` of the footprint over the detection range: a plan adopted outside the search."""
        p = self.params
        return (first_conflict(plan, movers, t, t + p.horizon_s, margin_m) is None
                and (not len(pts) or first_blocked_s(plan, pts, 0.0, p.detect_range_m, clear_m) is None))

    def _static_clear_m(self, why: str) -> float:
        """Clearance a static deviation must keep: ``static_clear_m``, halved after each search in a row
        that found nothing clear, down to 0 (a car without reverse that has come close to a box would
        otherwise stay stopped there for ever, every way out a few centimetres short of the margin)."""
        if why != "static" or self._squeeze == 0:
            return self.params.static_clear_m
        return 0.0 if self._squeeze >= SQUEEZE_STEPS else self.params.static_clear_m * 0.5 ** self._squeeze

    def _maybe_replan(self, obs: Observation, target: Goal, pts: FloatArray, movers: list[SpaceTimeObstacle]) -> None:
        assert self.plan is not None
        p = self.params
        t = obs.t_s
        why = None
        extra: list[tuple[str, tuple[float, float]]] = []
        t0 = time.perf_counter()
        c0 = time.thread_time()
        blk = first_blocked_s(self.plan, pts, self.ts.s_m, self.ts.s_m + p.detect_range_m, p.static_trigger_m) if len(pts) else None
        if blk is not None:
            why = "static"
            t0 = time.perf_counter()  # the deviation points are part of the replanning work
            c0 = time.thread_time()
            extra = self._deviation_points(obs, pts, blk[1], blk[0])
        elif movers and first_conflict(self.plan, movers, t, t + p.horizon_s, p.moving_margin_m) is not None:
            why = "moving"
        else:
            s_ref, _ = self.plan.profile.eval(t - self.plan.t0_s)
            if float(s_ref) - self.ts.s_m > p.delay_replan_m:
                why = "delay"
            elif target.arrival_s is not None and self.plan.arrival_s < target.arrival_s - p.early_retime_s:
                why = "early"  # a hurry out of a mover's way is over: back to the requested arrival
        if why is None:
            self._search = None
            return
        if why != "static":
            t0 = time.perf_counter()
            c0 = time.thread_time()
        search = self._search if self._search is not None and self._search[0] == why else None
        self._search = None
        budget = p.replan_budget_s * self._budget_scale
        start = self._state_now(obs)
        goal = self.plan.goal
        arrival = target.arrival_s
        vias = self._remaining_vias()
        searching = False
        work = (1, 0)
        new: TimedPlan | None
        try:
            if why in ("delay", "early"):  # the same path re-timed to the requested arrival
                new = plan_timed(start, goal, t, arrival, self.limits, vias, deadline=t0 + budget, auto_via=False)
                action = "catch-up" if why == "delay" else "re-timed to the requested arrival"
                if why == "early" and not self._clear(new, t, movers, pts, p.moving_margin_m, p.static_clear_m):
                    new, action = None, "early; the requested arrival is not clear yet"
            else:
                res = resolve(start, goal, t, arrival, self.limits, vias, movers, pts, horizon_s=p.horizon_s,
                              margin_m=p.moving_margin_m, static_clear_m=self._static_clear_m(why),
                              static_range_m=p.detect_range_m + 2.0,
                              deadline=t0 + budget, extra_vias_xy=extra, try_yield=why == "moving",
                              try_base=why != "static", max_candidates=p.max_candidates,
                              start_index=0 if search is None else search[1], late=None if search is None else search[2])
                new, action = res.plan, f"{why}: {res.action}"
                work = (res.tried, res.screened)
                if why == "static" and res.next_index is None:
                    self._squeeze = 0 if new is not None else min(self._squeeze + 1, SQUEEZE_STEPS)
                if res.next_index is not None:  # not finished: go on from there at the next step
                    self._search = (why, res.next_index, res.late)
                    searching = True
        except DeadlineMissed:
            new, action = None, f"{why}: budget of {budget * 1e3:.1f} ms exhausted"
            self.status["deadline_misses"] += 1
            self._budget_scale = min(self._budget_scale * 2.0, 16.0)  # give the next try more room
        if new is None and movers and why not in ("delay", "early"):
            # nothing clear (yet) and contact with a mover within 2 s (1 s while the search goes on): stop and
            # wait. Also while a static blockage is being searched round: a walker does not wait for that
            c = first_conflict(self.plan, movers, t, t + (1.0 if searching else 2.0), 0.0)
            if c is not None:
                self._search = None
                new = plan_timed(start, goal, t, arrival, self.limits, vias, dwell_first_s=1.0, auto_via=False)
                fast = None
                if first_conflict(new, movers, t, t + 2.0, 0.0) is not None:
                    # stopped here the car would be hit standing (a crossing obstacle heading for where it
                    # brakes to): get out of the way at full speed when that way is clear
                    fast = hurry_plan(start, goal, t, self.limits, vias)
                if fast is not None and self._clear(fast, t, movers, pts, 0.0, 0.0):
                    new, action = fast, action + "; hurry out of the way (early)"
                else:
                    action += "; stop and wait"
        dt = time.perf_counter() - t0
        self.replan_times_s.append(dt)
        self.replan_cpu_s.append(time.thread_time() - c0)
        self.replan_work.append(work)
        self._last_replan_t = t
        if new is not None and new.path.length_m <= 0.0:
            # no drivable geometry from here (e.g. the rest of the way would need reversing): keep the
            # current plan rather than adopt an empty one
            action += f"; kept the current plan ({new.reason})"
            new = None
        self.events.append((t, action))
        if new is not None:
            if not action.endswith("stop and wait"):
                self._budget_scale = 1.0
            self.plan = new
            self.ts = TrackState(s_m=0.0)
            self.status["replans"] += 1
            self._set_status(new, action)
        else:
            self.status["last_action"] = action


def _is_peer(m: MovingObstacle, peers: list[PlanObstacle], t_s: float, tol_m: float) -> bool:
    """True when the track ``m`` is within ``tol_m`` of a peer robot's planned footprint at ``t_s``."""
    tt = np.array([t_s])
    for pe in peers:
        xy, _ = pe.predict(tt)
        if math.hypot(m.x_m - float(xy[0, 0]), m.y_m - float(xy[0, 1])) <= tol_m:
            return True
    return False


