"""Run a scenario with a controller in closed loop and write its outputs.

The simulator owns time: physics advances in fixed ``dt_s`` steps and the controller runs every
``control_every(sc)`` steps, ``1 / control_hz`` seconds rounded to a whole number of steps (the period the
planners are told, ``RobotSpec.control_dt_s``), on a fresh laser scan. All noise comes from generators spawned from one
seed, so the same seed gives byte-identical outputs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..atomic import savefig_atomic, write_atomic
from ..hostloop import HostLoop, OdometryReport, SensorFrame
from ..types import DriveCommand, Goal, SonarFrame

if TYPE_CHECKING:
    from ..planning.base import RobotSpec
from .controller import Controller, GoalSeekParams
from .metrics import RowDistance, RunMetrics
from .referee import HOLE_FALL_DEPTH_M, Referee
from .robots import AckermannParams
from .scenario import Scenario, run_length_problem

__all__ = ["RunResult", "run_scenario", "LOCALISERS", "DriftingOdometry", "make_localiser", "control_every", "write_outputs", "robot_spec", "planner_names", "TRAJECTORY_COLUMNS", "HOLE_FALL_DEPTH_M"]

TRAJECTORY_COLUMNS = ("t_s", "x_m", "y_m", "yaw_rad", "speed_m_s", "yaw_rate_rad_s", "clearance_m", "goal_index")


@dataclass
class RunResult:
    """Outcome of a run: metrics, the sampled trajectory (n, 8) in TRAJECTORY_COLUMNS order, and why it ended."""

    scenario: str
    planner: str
    seed: int
    metrics: RunMetrics
    trajectory: np.ndarray
    end_reason: str  # "arrived", "collision", "fell_in_hole", "timeout"
    step_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # wall time of each planner step, s
    scene: Scenario | None = None  # the scenario as run (its goals replaced when a goal was given): trajectory.png's world
    believed: Any = None  # (believed, true): the host's last planned pose and the true one then (``localise``)
    events: list[tuple[float, str]] = field(default_factory=list)  # (t_s, text): the host loop's events


def planner_names() -> list[str]:
    """Every base name ``run_scenario`` accepts: the controllers of the one registry
    (:func:`agnav_host.planning.registry.controller_names`; any of them also with ``+ground-guard`` or
    ``+mover-guard``)."""
    from ..planning.registry import controller_names

    return controller_names()


def control_every(sc: Scenario) -> int:
    """Physics steps between two controller calls: ``1 / control_hz`` seconds rounded to whole ``dt_s``
    steps, at least one. The controller's real period is this times ``dt_s``."""
    return max(1, int(round(1.0 / (sc.control_hz * sc.dt_s))))


def robot_spec(sc: Scenario) -> "RobotSpec":
    """The planners' view of the scenario's robot and sensors (agnav_host.planning.RobotSpec).
    ``control_dt_s`` is the period at which :func:`run_scenario` really calls the planner
    (:func:`control_every` physics steps), not ``1 / control_hz``."""
    from ..planning.base import RobotSpec

    p = sc.robot_params
    dt = control_every(sc) * sc.dt_s
    kw: dict[str, float | int | str] = {}
    if sc.sonar is not None:
        s = sc.sonar.spec
        kw = dict(sonar_count=s.count, sonar_spacing_rad=s.spacing_rad, sonar_mount_radius_m=s.mount_radius_m,
                  sonar_max_range_m=s.max_range_m)
    if isinstance(p, AckermannParams):
        vmin = p.true_speed.pos_value[0] if p.true_speed is not None and p.true_speed.pos_value else 0.0
        return RobotSpec(kinematics="ackermann", radius_m=p.radius_m, max_speed_m_s=sc.max_speed_m_s, min_speed_m_s=vmin,
                         max_accel_m_s2=p.max_accel_m_s2, track_m=p.track_m, wheelbase_m=p.wheelbase_m,
                         max_steer_rad=p.max_steer_rad, footprint_offset_m=0.5 * p.wheelbase_m, control_dt_s=dt,
                         stop_lag_s=p.speed_tau_s, **kw)  # type: ignore[arg-type]
    return RobotSpec(kinematics="diff_drive", radius_m=p.radius_m, max_speed_m_s=sc.max_speed_m_s,
                     max_accel_m_s2=p.max_accel_m_s2, track_m=p.track_m, control_dt_s=dt, stop_lag_s=p.tau_s, **kw)  # type: ignore[arg-type]


def _make_controller(sc: Scenario, planner: str) -> Controller:
    from .field_controllers import make_scenario_controller

    return make_scenario_controller(sc, planner)


class _SonarSlots:
    """Fires the ring in three slots of non-adjacent sensors (0, 3, 6, 9 / 1, 4, 7, 10 / ...), one
    slot per control step, as the firmware's scheduler does, and keeps the newest range of each."""

    def __init__(self, sc: Scenario) -> None:
        assert sc.sonar is not None
        self.ring = sc.sonar
        n = self.ring.spec.count
        self.slots = [list(range(k, n, 3)) for k in range(min(3, n))]
        self.k = 0
        self.us = np.full(n, np.nan)

    def frame(self, world: object, pose: object, t: float, rng: np.random.Generator) -> SonarFrame:
        first = self.k == 0
        for slot in (self.slots if first else [self.slots[self.k % len(self.slots)]]):
            self.us[slot] = self.ring.echo_us(world, pose, slot, t, rng)  # type: ignore[arg-type]
        self.k += 1
        us = self.us.copy()
        return SonarFrame(t, np.ones(len(us), dtype=bool), us, us * 1e-6 * self.ring.spec.speed_of_sound_m_s / 2.0)


def _standin_params(sc: Scenario) -> GoalSeekParams:
    from ..planning.registry import _standin_params as from_spec

    return from_spec(robot_spec(sc))


LOCALISERS = ("scan", "poles", "posts", "odometry")


class DriftingOdometry:
    """Wheel odometry of the simulated robot, in the odometry frame (the start pose at the origin): the true
    speed and yaw rate integrated with a distance scale error ``scale``, a yaw-rate scale error ``yaw_scale``
    and white noise per step (``speed_sd`` m/s, ``yaw_rate_sd`` rad/s)."""

    def __init__(self, rng: np.random.Generator, scale: float = 1.01, yaw_scale: float = 0.98,
                 speed_sd: float = 0.01, yaw_rate_sd: float = 0.01) -> None:
        from ..types import Pose2D

        self.rng, self.scale, self.yaw_scale = rng, scale, yaw_scale
        self.speed_sd, self.yaw_rate_sd = speed_sd, yaw_rate_sd
        self.pose = Pose2D()
        self.v = self.w = 0.0

    def advance(self, speed_m_s: float, yaw_rate_rad_s: float, dt_s: float) -> None:
        from ..types import Pose2D
        from .robots import integrate_arc

        moving = abs(speed_m_s) > 1e-4 or abs(yaw_rate_rad_s) > 1e-4
        n = self.rng.normal(0.0, 1.0, 2) if moving else np.zeros(2)
        self.v = speed_m_s * self.scale + n[0] * self.speed_sd
        self.w = yaw_rate_rad_s * self.yaw_scale + n[1] * self.yaw_rate_sd
        x, y, yaw = integrate_arc(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, self.v, self.w, dt_s)
        self.pose = Pose2D(x, y, yaw)

    def report(self, t_s: float, robot: object) -> "OdometryReport":
        return OdometryReport(self.pose.x_m, self.pose.y_m, self.pose.yaw_rad, t_s, self.v, self.w)


def make_localiser(sc: Scenario, localise: str, map_yaml: str | None = None) -> Any:
    """The host's localiser for ``sc`` by name (:data:`LOCALISERS`); None for ``odometry``. Raises ValueError for
    an unknown name, a scenario without a laser, ``posts`` without ``meta.landmarks``, or a map that cannot be
    read."""
    if localise not in LOCALISERS:
        raise ValueError(f"unknown localiser {localise!r}; known: {', '.join(LOCALISERS)}")
    if localise == "odometry":
        return None
    if sc.laser is None:
        raise ValueError(f"localising on {localise} needs the scenario's horizontal laser")
    if localise == "posts":
        from ..localisation import localiser_for

        loc = localiser_for(sc.meta, sc.start, sc.laser.mount)
        if loc is None:
            raise ValueError("localising on posts needs the scenario's surveyed posts (meta.landmarks)")
        return loc
    if localise == "poles":
        from ..localisation.pole_slam import PoleSlam

        return PoleSlam(sc.start, sc.laser.mount)
    from ..localisation.scan_localiser import scan_localiser_for

    return scan_localiser_for(sc.start, sc.laser.mount, map_yaml)


def run_scenario(
    sc: Scenario,
    planner: str = "goal_seek",
    seed: int = 0,
    duration_s: float | None = None,
    goal: Goal | None = None,
    progress: Callable[[float, float], None] | None = None,
    controller: Controller | None = None,
    localise: str | None = None,
    map_yaml: str | None = None,
) -> RunResult:
    """Simulate ``sc`` with the named controller: a stand-in (``goal_seek``) or a host planner from
    agnav_host.planning (``flb``, ``him``, ...; parameters from the scenario's ``[meta.planner_params.NAME]``).

    ``goal`` replaces the scenario's goals; ``progress(t_s, duration_s)`` is called about every
    simulated second. The run ends on arrival at the last goal, a collision, falling into a hole,
    or at ``duration_s`` (the scenario's when None).

    ``controller`` (anything with ``reset()`` and ``step(obs)``, e.g. a perception follower) replaces the
    named one; ``planner`` is then only its label. A scenario's tilted laser (``[tilted_laser]``) is scanned
    at every control step for a controller whose ``uses_tilted_laser`` is true, into
    ``obs.extras['tilted_scan']`` (a LaserScan; ``ground_points`` of the sensor turns it into 3-D points).

    ``localise`` (None: the controller gets the true pose): the host plans on wheel odometry (the true motion
    with :class:`DriftingOdometry`'s errors) fused by a localiser: ``scan`` (scan matching against ``map_yaml``
    or a map built online, :mod:`agnav_host.localisation.scan_localiser`), ``poles`` (poles and trunks learnt online,
    :mod:`agnav_host.localisation.pole_slam`), ``posts`` (the scenario's
    ``meta.landmarks``), ``odometry`` (none); a scenario's ``meta.localise`` (and ``meta.map``) when None.
    """
    if goal is not None:
        sc = replace(sc, goals=[goal])
    duration = sc.duration_s if duration_s is None else duration_s
    if not duration > 0:
        raise ValueError(f"duration_s must be > 0, got {duration}")
    too_long = run_length_problem(duration, sc.dt_s)
    if too_long:  # before the trajectory is allocated
        raise ValueError(too_long)
    ctrl = controller if controller is not None else _make_controller(sc, planner)
    static: dict[str, object] = {"meta": sc.meta}
    if "path" in sc.meta:
        static["path"] = np.asarray(sc.meta["path"], dtype=float)
    if localise is None and sc.meta.get("localise") is not None:  # the scenario says how its host localises
        localise, map_yaml = str(sc.meta["localise"]), map_yaml or sc.meta.get("map")
    localiser = make_localiser(sc, localise, map_yaml) if localise is not None else None
    loop = HostLoop(ctrl, list(sc.goals), laser_mount=sc.laser.mount if sc.laser is not None else None,
                    tilted_mount=sc.tilted_laser.mount if sc.tilted_laser is not None else None, extras=static,
                    localiser=localiser)
    use_tilted = sc.tilted_laser is not None and "tilted_laser" in loop.needs
    sonar_slots = _SonarSlots(sc) if sc.sonar is not None and "sonar" in loop.needs else None
    times: list[float] = []
    events: list[tuple[float, str]] = []
    believed = None
    ss = np.random.SeedSequence(seed)
    rng_robot, rng_laser, rng_sonar, rng_tilted = (np.random.default_rng(s) for s in ss.spawn(4))  # first 3 as before
    odo = DriftingOdometry(np.random.default_rng(ss.spawn(1)[0])) if localise is not None else None
    robot = sc.make_robot()
    world = sc.world
    dt = sc.dt_s
    n_steps = int(round(duration / dt))
    ctrl_every = control_every(sc)
    prog_every = max(1, int(round(1.0 / dt)))
    gi = 0
    cmd = DriveCommand()
    rows = np.zeros((n_steps + 1, len(TRAJECTORY_COLUMNS)))
    referee = Referee(sc)

    def clearance(t: float) -> float:
        cx, cy = robot.footprint_centre()
        return float(world.clearance_m(cx, cy, t)[0]) - robot.radius_m

    rows[0] = (0.0, robot.pose.x_m, robot.pose.y_m, robot.pose.yaw_rad, 0.0, 0.0, clearance(0.0), 0)
    k = 0
    for k in range(1, n_steps + 1):
        t_prev = (k - 1) * dt
        if (k - 1) % ctrl_every == 0:
            # the simulator's sources: the true pose (an ideal pose source) or the odometry, the scans cast from
            # the true pose
            frame = SensorFrame(
                t_prev, robot.pose if odo is None else sc.start.compose(odo.pose), robot.speed_m_s,
                robot.yaw_rate_rad_s, odometry=odo.report(t_prev, robot) if odo is not None else None,
                scan=sc.laser.scan(world, robot.pose, t_prev, rng_laser) if sc.laser is not None else None,
                tilted_scan=sc.tilted_laser.scan(world, robot.pose, t_prev, rng_tilted) if use_tilted else None,  # type: ignore[union-attr]
                sonar=sonar_slots.frame(world, robot.pose, t_prev, rng_sonar) if sonar_slots is not None else None,
                goal_index=gi)
            decision = loop.step(frame)
            if decision.event:
                events.append((t_prev, decision.event))
            if decision.pose is not None:
                believed = (decision.pose, robot.pose)
            if decision.command is not None:
                cmd = decision.command
            times.append(decision.step_s)
        robot.step(cmd, dt, rng_robot)
        if odo is not None:
            odo.advance(robot.speed_m_s, robot.yaw_rate_rad_s, dt)
        t = k * dt
        cl = clearance(t)
        p = robot.pose
        rows[k] = (t, p.x_m, p.y_m, p.yaw_rad, robot.speed_m_s, robot.yaw_rate_rad_s, cl, gi)
        if progress is not None and k % prog_every == 0:
            progress(t, duration)
        if referee.judge(t, robot, cl) is not None:
            break
        gi = referee.goal_index
    rows = rows[: k + 1]
    last = sc.goals[-1]
    metrics = RunMetrics.compute(
        rows[:, 0], rows[:, 1:3], rows[:, 3], rows[:, 4], rows[:, 5], rows[:, 6], (last.x_m, last.y_m),
        last.yaw_rad, last.arrival_s, referee.reason == "arrived", referee.arrival_s, field=referee.field_score(),
    )
    return RunResult(sc.name, planner, seed, metrics, rows, referee.reason, np.asarray(times), sc,
                     believed if localise is not None else None, events)


def write_outputs(result: RunResult, out_dir: str | Path, plot: bool = True) -> list[Path]:
    """Write summary.json (exactly the metric keys), run_info.json, trajectory.csv and, when
    matplotlib is importable and ``plot``, trajectory.png. Returns the written paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    summary = out / "summary.json"
    write_atomic(summary, json.dumps(result.metrics.to_dict(), indent=2) + "\n")
    written.append(summary)
    info = out / "run_info.json"
    write_atomic(info, json.dumps({"scenario": result.scenario, "planner": result.planner, "seed": result.seed,
                                   "end_reason": result.end_reason, "samples": int(len(result.trajectory))}, indent=2) + "\n")
    written.append(info)
    traj = out / "trajectory.csv"
    lines = [",".join(TRAJECTORY_COLUMNS)]
    for r in result.trajectory:
        lines.append(f"{r[0]:.3f},{r[1]:.6f},{r[2]:.6f},{r[3]:.6f},{r[4]:.6f},{r[5]:.6f},{r[6]:.6f},{int(r[7])}")
    write_atomic(traj, "\n".join(lines) + "\n")
    written.append(traj)
    if plot:
        png = _try_plot(result, out / "trajectory.png")
        if png is not None:
            written.append(png)
    return written


def write_row_distance(rd: RowDistance, out_dir: str | Path, plot: bool = True) -> list[Path]:
    """Write row_distance.json (:meth:`RowDistance.to_dict`) and, when matplotlib is importable and ``plot``,
    row_distance.png (the distance along the travel, with the set distance and its band)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js = out / "row_distance.json"
    write_atomic(js, json.dumps(rd.to_dict(), indent=2) + "\n")
    written = [js]
    plt = _pyplot() if plot else None
    if plt is not None:
        fig, ax = plt.subplots(figsize=(9, 3))
        ax.axhspan(rd.set_m - rd.band_m, rd.set_m + rd.band_m, color="0.9", label=f"{rd.set_m:g} +- {rd.band_m:g} m")
        if rd.planted_m is not None:
            ax.plot(rd.travel_m, rd.planted_m, "g-", lw=1,
                    label=f"distance from the row as planted (stems over {rd.planted_window_m:g} m)")
        ax.plot(rd.travel_m, rd.distance_m, "b-", lw=1, label="distance from the row's design line")
        ax.set_xlabel("travel, m")
        ax.set_ylabel("m")
        ax.set_title(f"row distance: mean {rd.mean_m:.3f} m, {rd.min_m:.3f}-{rd.max_m:.3f} m, "
                     f"{100 * rd.within:.1f} % within the band")
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        png = out / "row_distance.png"
        savefig_atomic(fig, png, dpi=100)
        plt.close(fig)
        written.append(png)
    return written


def _pyplot() -> Any:
    """matplotlib's pyplot on the Agg backend, or None when matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def _try_plot(result: RunResult, path: Path) -> Path | None:
    """trajectory.png: the run in its world (when the result carries its scenario), the path coloured by speed, the
    robot's outline every 2 s and at the end; None when matplotlib is not installed."""
    if _pyplot() is None:
        return None
    from ..viz.world_plot import plot_run

    return plot_run(path, result.trajectory, result.scene, title=f"{result.scenario} ({result.planner})",
                    end_reason=result.end_reason)
