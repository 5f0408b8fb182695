"""The host loop: one copy of what the host does every control period, for the simulator, the SIL and a robot.

Each call of :meth:`HostLoop.step` takes one :class:`SensorFrame` (the pose source's pose and velocity, the raw
odometry report when a new one came, the horizontal laser's newest scan, the tilted laser's, the sonar ring, the
referee's goal index in a scenario) and, in this order:

1. **localises**: a new odometry report and a healthy scan go into the localiser (when one is configured); the
   pose planned on is the localiser's, else the pose source's;
2. **checks the laser**: every scan (or its absence) goes through the :class:`~.perception.LaserWatchdog`; a
   faulty laser holds the robot (a zero command with the reason, said once per fault) until it is healthy;
3. **observes**: the scan placed in the world with the planned pose and the laser's mounting pose, the tilted
   scan the same way, the sonar ring for a controller that reads it, the goals and the goal index;
4. **steps the controller**, a registry controller with its guards (the ground and mover guards wrap it; the
   obstacle tracker runs inside the mover guard and the timed planner). With a laser mounted it steps on a new
   scan only: a step without one runs the watchdog and leaves the last command standing, so that no controller
   takes a missing scan for an empty field;
5. returns a :class:`Decision` (the command or the hold and why) for the entry point to send: the simulator
   moves its robot model with it, the SIL and ``agnav run`` turn it into the firmware's setpoint with
   :func:`firmware_setpoint` and send it over the link.

What differs between the three entry points is only which plant or link and which sources they plug in and how
time advances (physics steps, the lock-step firmware, the wall clock); see ``sim.runner``, ``sil.session`` and
``robot``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Protocol

from .perception._health import LaserWatchdog
from .types import DriveCommand, Goal, LaserScan, Observation, Pose2D, SonarFrame

__all__ = ["SensorFrame", "OdometryReport", "Decision", "HostLoop", "Localiser", "controller_needs",
           "firmware_setpoint", "TURN_SPEED_M_S", "SLOW_SHARE"]


@dataclass(frozen=True)
class OdometryReport:
    """A raw odometry report (the firmware's AGNAV_ODOMETRY): pose in the odometry frame (m, rad), its stamp on
    the robot's clock (s), speed (m/s) and yaw rate (rad/s)."""

    x_m: float
    y_m: float
    yaw_rad: float
    stamp_s: float
    speed_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0


@dataclass
class SensorFrame:
    """What the sources deliver for one control step (see the module docstring).

    ``pose`` is in the world frame (dead reckoning composed with the start pose, or the simulator's truth), None
    while there is none yet (no command is made then). Scans are in the sensor frame (their ``pose`` is ignored
    and set from the planned pose and the mounting pose). ``goal_index``: the referee's current goal in a
    scenario; None lets the loop advance the goals itself on the planned pose (a robot)."""

    t_s: float
    pose: Pose2D | None
    speed_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    odometry: OdometryReport | None = None
    scan: LaserScan | None = None
    tilted_scan: LaserScan | None = None
    sonar: SonarFrame | None = None
    goal_index: int | None = None
    extras: Mapping[str, object] | None = None


@dataclass(frozen=True)
class Decision:
    """What the loop decided at one step: ``command`` to send (None: send nothing, ``idle`` says why: no pose yet,
    or no new scan since the last step, when the last command stands),
    ``hold`` the reason when the robot is held stopped, ``arrived`` when the last goal is reached (the loop
    judged it on the planned pose), the planned ``pose`` and the controller's wall time ``step_s``."""

    t_s: float
    command: DriveCommand | None
    hold: str = ""
    arrived: bool = False
    pose: Pose2D | None = None
    observation: Observation | None = None
    step_s: float = 0.0
    event: str = ""  # something worth a log line and a STATUSTEXT (a laser fault, a goal reached)
    idle: str = ""  # why there is no command: "no pose yet", "no new scan"
    pose_sigma: tuple[float, float, float] | None = None  # the localiser's 1-sigma x, y (m), yaw (rad)
    localisation: str = ""  # the localiser's state when it reports one: "ok", "slow", "lost"


class Localiser(Protocol):
    def odometry(self, x_m: float, y_m: float, yaw_rad: float, stamp_s: float, speed_m_s: float,
                 yaw_rate_rad_s: float) -> None: ...

    def scan(self, ranges_m: Any, angles_rad: Any, t_s: float, range_max_m: float = math.inf) -> int: ...

    def pose_at(self, t_s: float) -> Pose2D: ...


#: the command's share while the localisation is uncertain (``slow``)
SLOW_SHARE = 0.5


def _sigma(loc: Any) -> tuple[float, float, float] | None:
    sig = getattr(loc, "sigma", None)
    if sig is None and getattr(loc, "filter", None) is not None:
        sig = getattr(loc.filter, "sigma", None)
    return tuple(float(v) for v in sig) if sig is not None else None  # type: ignore[return-value]


def controller_needs(ctrl: Any) -> frozenset[str]:
    """The sensors a built controller reads: ``sonar`` (``uses_sonar``), ``tilted_laser`` (``uses_tilted_laser``);
    every controller gets the horizontal laser when there is one."""
    need = set()
    if bool(getattr(ctrl, "uses_sonar", False)):
        need.add("sonar")
    if bool(getattr(ctrl, "uses_tilted_laser", False)):
        need.add("tilted_laser")
    return frozenset(need)


class HostLoop:
    """One control step at a time (see the module docstring).

    ``goals``: the mission; ``laser_mount`` / ``tilted_mount``: the scanners' poses on the robot (None: no such
    scanner, and no watchdog on it); ``localiser``: fuses odometry with the laser (None: the pose source's pose
    is planned on); ``watchdog``: the laser's health check (default parameters when None and a laser is
    mounted); ``extras``: fixed observation extras (a scenario's ``meta`` and ``path``)."""

    def __init__(self, controller: Any, goals: list[Goal], *, laser_mount: Pose2D | None = None,
                 tilted_mount: Pose2D | None = None, localiser: Localiser | None = None,
                 watchdog: LaserWatchdog | None = None, extras: Mapping[str, object] | None = None) -> None:
        if not goals:
            raise ValueError("the host loop needs at least one goal")
        self.controller = controller
        self.goals = list(goals)
        self.laser_mount = laser_mount
        self.tilted_mount = tilted_mount
        self.localiser = localiser
        self.watchdog = watchdog if watchdog is not None else (LaserWatchdog() if laser_mount is not None else None)
        self.needs = controller_needs(controller)
        self.goal_index = 0
        self._extras: dict[str, object] = {"goals": list(self.goals), "goal_index": 0, **(extras or {})}
        self._faults_said = 0
        self._loc_state = "ok"
        self.steps = 0
        controller.reset()

    @property
    def goal(self) -> Goal:
        return self.goals[min(self.goal_index, len(self.goals) - 1)]

    def step(self, f: SensorFrame) -> Decision:
        """One control step (see the module docstring). A localiser that reports a state (``status()``:
        ``ok`` / ``slow`` / ``lost`` and why) slows the command to :data:`SLOW_SHARE` while ``slow`` and holds
        the robot while ``lost``; each change of state is an event. The Decision carries the localiser's
        pose sigma."""
        d = self._step(f)
        loc = self.localiser
        if loc is None:
            return d
        status = getattr(loc, "status", None)
        extra: dict[str, Any] = {"pose_sigma": _sigma(loc) if d.pose is not None else None}
        if status is not None and d.pose is not None:
            state, why = status()
            extra["localisation"] = state
            if state != self._loc_state:
                text = {"ok": "localisation recovered; driving on",
                        "slow": f"localisation uncertain ({why}); slowing down",
                        "lost": f"localisation lost ({why}); holding the robot, re-localising"}.get(state, state)
                extra["event"] = f"{d.event}; {text}" if d.event else text
                self._loc_state = state
            if state == "lost" and not d.hold and not d.arrived:
                extra.update(command=DriveCommand(), hold="localisation lost; re-localising")
            elif state == "slow" and d.command is not None and not d.hold:
                c = d.command
                extra["command"] = DriveCommand(c.speed_m_s * SLOW_SHARE, c.yaw_rate_rad_s * SLOW_SHARE, c.steer_rad)
        return replace(d, **extra)

    def _step(self, f: SensorFrame) -> Decision:
        t = f.t_s
        if f.goal_index is not None:
            self.goal_index = f.goal_index
        loc = self.localiser
        if loc is not None and f.odometry is not None:
            o = f.odometry
            loc.odometry(o.x_m, o.y_m, o.yaw_rad, o.stamp_s, o.speed_m_s, o.yaw_rate_rad_s)
        if f.pose is None:
            return Decision(t, None, idle="no pose yet")
        scan = None
        if self.laser_mount is not None:
            assert self.watchdog is not None
            health = self.watchdog.update(f.scan, t)
            if loc is not None and health.ok and f.scan is not None:  # a failed laser must not move the pose
                loc.scan(f.scan.ranges_m, f.scan.angles_rad, f.scan.stamp_s, f.scan.range_max_m)
            pose = loc.pose_at(t) if loc is not None else f.pose
            if not health.ok:
                event = ""
                if self._faults_said < self.watchdog.faults:
                    self._faults_said = self.watchdog.faults
                    event = f"laser fault: {health.reason}; holding the robot"
                return Decision(t, DriveCommand(), hold=f"laser fault: {health.reason}", pose=pose, event=event)
            if f.scan is None:  # a laser between two scans: the controller steps on scans, the last command stands
                return Decision(t, None, pose=pose, idle="no new scan")
            s = f.scan
            scan = LaserScan(s.angle_min_rad, s.angle_increment_rad, s.ranges_m, s.range_max_m, s.stamp_s,
                             pose.compose(self.laser_mount))
        else:
            pose = loc.pose_at(t) if loc is not None else f.pose
        if f.goal_index is None:  # a robot: the loop judges the goals on the planned pose
            g = self.goal
            if math.hypot(g.x_m - pose.x_m, g.y_m - pose.y_m) <= g.tolerance_m:
                if self.goal_index + 1 < len(self.goals):
                    self.goal_index += 1
                else:
                    return Decision(t, DriveCommand(), arrived=True, pose=pose,
                                    event=f"goal reached at t={t:.1f} s")
        ex = self._extras
        ex["goal_index"] = self.goal_index
        if "tilted_laser" in self.needs and f.tilted_scan is not None and self.tilted_mount is not None:
            ex["tilted_scan"] = replace(f.tilted_scan, pose=pose.compose(self.tilted_mount))
        else:  # no new tilted scan this step: an earlier one must not be taken in again at today's pose
            ex.pop("tilted_scan", None)
        if f.extras:
            ex.update(f.extras)
        sonar = f.sonar if "sonar" in self.needs else None
        obs = Observation(t, pose, f.speed_m_s, f.yaw_rate_rad_s, self.goal, scan, sonar, ex)
        t0 = time.perf_counter()
        cmd = self.controller.step(obs)
        dt = time.perf_counter() - t0
        self.steps += 1
        return Decision(t, cmd, pose=pose, observation=obs, step_s=dt)


#: a differential robot asked to turn on the spot backs round its tightest arc at this speed (m/s)
TURN_SPEED_M_S = 0.1


def firmware_setpoint(cmd: DriveCommand, kinematics: str, track_m: float, wheelbase_m: float, max_steer_rad: float,
                      max_speed_m_s: float = math.inf, turn_speed_m_s: float = TURN_SPEED_M_S) -> tuple[float, float]:
    """(steer_rad, speed_m_s) for the firmware's HOST_COMMAND layer, from a controller's command.

    The firmware takes a steering angle for every drive kind and turns a differential robot like a car of
    wheelbase = track (drive.h: omega = v tan(phi) / track), so phi = atan(track * yaw_rate / v); an Ackermann
    command without a steering angle uses the wheelbase. A differential robot cannot turn on the spot through it:
    a turn on the spot becomes the tightest arc *backwards* at a crawl (``turn_speed_m_s``), a three-point turn
    that also opens room ahead. The speed is limited to +-``max_speed_m_s``."""
    v = max(-max_speed_m_s, min(max_speed_m_s, cmd.speed_m_s))
    if cmd.steer_rad is not None:
        return cmd.steer_rad, v
    if abs(v) < 1e-6:
        if abs(cmd.yaw_rate_rad_s) < 1e-6 or kinematics == "ackermann":
            return 0.0, 0.0
        return -math.copysign(max_steer_rad, cmd.yaw_rate_rad_s), -turn_speed_m_s
    base = wheelbase_m if kinematics == "ackermann" else track_m
    steer = math.atan(base * cmd.yaw_rate_rad_s / v)
    return max(-max_steer_rad, min(max_steer_rad, steer)), v
