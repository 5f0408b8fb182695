"""Perception benchmark: closed-loop row following, proximity following, hole detection, latency.

Run:  .venv/bin/python bench/bench_perception.py            (all, a few minutes)
      .venv/bin/python bench/bench_perception.py --only rows,proximity,proximity_sil,face,oracle,holes,ruts,ruts_sil,hole_field,hole_field_sil,latency
Everything is seeded; the figures go to bench/results/perception.md by hand.

* rows: five runs per detection method ("clean": reached the row end without touching a crop plant;
  the robot may drive over the weeds, which the simulator models as 1.2 cm posts) through an 8 m lane between rows 0.75 m apart (TiM310-like
  laser: 1 deg, 4 m, 2 cm range noise; 10 % of the plants missing; weeds in the lane). Each run has
  its own world seed, noise seed and a start offset of up to +-3 cm and +-2 deg. Error = |distance of
  the reference point from the lane's centre line| sampled every physics step while the reference
  point is between the row ends; mean +- sd over each run, then averaged over the five runs (ref 004
  reports its table the same way).
* proximity: the built-in curvy_row (50 m of bushes, ref 000), follow at 1 m from the row centre line; seed n
  draws its bushes from world_seed 7 + n (seed 0 is the built-in world) and its laser and wheel-slip noise from n.
  The visible half-width of the row is calibrated once (the follower's estimator on calibration drives along a line
  1 m from three other rows, world_seeds 1007-1009). Distance = from the robot to the row's centre polyline, every
  physics step once the robot is past x = 2 m (the settling: it starts 0.92 m from the line, 21 deg off the row).
  A second table measures the same runs against the row as planted: the bushes' centres (mean of each bush's
  circles, what a surveyor would mark) averaged over 2, 3 and 6 m of row, instead of the design sine.
* face: how far the curvy row's visible face itself strays from its plant line, per world (no simulation):
  the floor under any follower that sees only the face (see bush_face_floor).
* oracle: the row's shape estimated from the bushes' true centres by local polynomials and smoothers over a grid
  of windows, scored on the design line (see oracle_floor): what a follower could at best do with this planting.
* holes: the five hole sizes of ref 000 table 5-I, each approached head-on and at 30 deg from three
  seeded starts; "detected" = a hole cell reported inside the true hole while the robot's front is
  still outside it.
* ruts: the built-in ruts scenario (two ruts 1.5 m apart along y = sin(2 pi x / 16)) run by the simulator's
  runner with the tilted laser as a scenario sensor and the rut follower in closed loop; lateral error = signed
  distance from the ruts' true midline (the world's polyline), every physics step past x = 3 m (the capture:
  the robot starts 0.14-0.33 m off the midline, 9 deg off its direction).
* proximity_sil, ruts_sil, hole_field_sil: the same in the SIL (native firmware, radio link): the controllers place what the
  tilted laser sees with the firmware's odometry, not the simulator's true pose.
* hole_field: the built-in hole_field (holes of ref 000 in the way to a goal 24 m ahead) run by the runner, the
  goal-seeking stand-in without and with GroundGuard (the tilted laser's holes as posts in its scan); the
  robot's disc's nearest approach to each hole's rim, from the world's hole shapes.
* latency: median wall time of detection + one control step on an 811-beam TiM561 scan in a row field, and of
  one ProximityFollower step on the curvy row once its row map is full.

Figures of the closed-loop runs (ruts, hole_field, proximity) go to ``--plots DIR`` (default bench/results/perception/).
"""

from __future__ import annotations

import argparse
import itertools
import math
import re
import statistics
import sys
import time
import tomllib
from dataclasses import replace
from typing import Callable, Iterator

import numpy as np

from agnav_host.sim.metrics import along_and_offset_m, disc_clearance_to_hole_m, signed_offset_m
from agnav_host.perception import (
    GroundParams,
    ProximityFollower,
    ProximityFollowerParams,
    RowFollower,
    RowFollowerParams,
    detect_ground_obstacles,
    row_method_names,
)
from agnav_host.sim.runner import control_every
from agnav_host.sim.scenario import Scenario, builtin_text, load_scenario, parse_scenario
from agnav_host.sim.world import Hole
from agnav_host.types import DriveCommand, Goal, Observation, Pose2D, norm_angle_rad

PROXIMITY_SETTLE_X_M = 2.0  # proximity: samples before the robot passes this x are the settling
PROXIMITY_CALIBRATION_SEEDS = (1000, 1001, 1002)  # proximity: the half-width is calibrated once, on rows no run uses
REF_004 = {"offset": (0.041, 0.034), "lsq": (0.070, 0.059), "triangle": (0.078, 0.055)}


def closed_loop(sc: Scenario, ctrl: object, seed: int, duration_s: float,
                stop: Callable[[Pose2D], bool] | None = None, tilted: bool = False) -> np.ndarray:
    """Run ``ctrl`` (reset/step) in ``sc``; returns poses (n, 4): t_s, x_m, y_m, yaw_rad every physics step.

    The tilted laser's scan (when asked) goes to ``obs.extras['tilted_scan']``."""
    ss = np.random.SeedSequence(seed)
    rng_robot, rng_laser, rng_tilt = (np.random.default_rng(s) for s in ss.spawn(3))
    robot = sc.make_robot()
    ctrl.reset()  # type: ignore[attr-defined]
    dt = sc.dt_s
    every = control_every(sc)
    cmd = DriveCommand()
    out = [(0.0, robot.pose.x_m, robot.pose.y_m, robot.pose.yaw_rad)]
    goal = sc.goals[0] if sc.goals else Goal(0.0, 0.0)
    for k in range(int(round(duration_s / dt))):
        t = k * dt
        if k % every == 0:
            scan = sc.laser.scan(sc.world, robot.pose, t, rng_laser) if sc.laser is not None else None
            extras: dict[str, object] = {}
            if tilted and sc.tilted_laser is not None:
                extras["tilted_scan"] = sc.tilted_laser.scan(sc.world, robot.pose, t, rng_tilt)
            obs = Observation(t, robot.pose, robot.speed_m_s, robot.yaw_rate_rad_s, goal, scan, None, extras)
            cmd = ctrl.step(obs)  # type: ignore[attr-defined]
        robot.step(cmd, dt, rng_robot)
        p = robot.pose
        out.append((t + dt, p.x_m, p.y_m, p.yaw_rad))
        if stop is not None and stop(p):
            break
    return np.asarray(out)


def row_lane_toml(world_seed: int, gap_fraction: float = 0.10, start_y_m: float = 0.0, start_yaw_deg: float = 0.0,
                  robot: str = "diff_drive", laser: str = "tim310") -> str:
    """Four rows 8 m long, 0.75 m apart; the robot drives the lane centred on y = 0 (rows at +-0.375)."""
    rng = np.random.default_rng(world_seed)
    rows = []
    for k in range(4):
        y = -1.125 + 0.75 * k
        # missing plants: gaps of 1-2 plants (0.15-0.30 m) until gap_fraction of the row is empty
        gaps: list[list[float]] = []
        total = 0.0
        while total < gap_fraction * 8.0 - 1e-9:
            w = float(rng.choice([0.16, 0.31]))
            s0 = float(rng.uniform(0.2, 7.8 - w))
            if any(s0 < g1 + 0.2 and s0 + w > g0 - 0.2 for g0, g1 in gaps):
                continue
            gaps.append([round(s0, 3), round(s0 + w, 3)])
            total += w
        rows.append(f"""[[rows]]
points = [[0.0, {y}], [8.0, {y}]]
plant_spacing_m = 0.15
plant_radius_m = 0.05
cluster = 3
jitter_m = 0.015
gaps = {sorted(gaps)}
""")
    robot_block = ('model = "diff_drive"\nradius_m = 0.2\ntrack_m = 0.4\n' if robot == "diff_drive"
                   else 'model = "ackermann"\n')
    return f"""[scenario]
name = "row_lane"
duration_s = 40.0
world_seed = {world_seed}
[robot]
{robot_block}start = {{ x_m = -0.6, y_m = {start_y_m}, yaw_deg = {start_yaw_deg} }}
max_speed_m_s = 0.4
[laser]
model = "{laser}"
mount = {{ x_m = 0.2, y_m = 0.0, yaw_deg = 0.0 }}
[[goals]]
x_m = 9.0
y_m = 0.0
{''.join(rows)}
[[weeds]]
region = [0.3, -0.28, 7.7, 0.28]
count = 12
radius_m = 0.012
"""


def bench_rows(methods: list[str], runs: int = 5, speed_m_s: float = 0.4) -> dict[str, list[tuple[float, float, bool]]]:
    """Per method, per run: (mean |e|, sd |e|, reached the row end without touching a plant)."""
    res: dict[str, list[tuple[float, float, bool]]] = {}
    for m in methods:
        per_run = []
        for r in range(runs):
            rng = np.random.default_rng(1000 + r)
            y0, yaw0 = float(rng.uniform(-0.03, 0.03)), float(rng.uniform(-2.0, 2.0))
            sc = parse_scenario(row_lane_toml(100 + r, start_y_m=y0, start_yaw_deg=yaw0), "<row_lane>")
            assert sc.laser is not None
            ctrl = RowFollower(RowFollowerParams(method=m, speed_m_s=speed_m_s, mount=sc.laser.mount))
            traj = closed_loop(sc, ctrl, seed=r, duration_s=40.0, stop=lambda p: p.x_m > 8.3)
            inside = (traj[:, 1] >= 0.0) & (traj[:, 1] <= 8.0)
            err = np.abs(traj[inside, 2])
            # clearance to the crop plants (circles of 2.5 cm); the robot may drive over the small weeds
            plants = sc.world.circles[sc.world.circles[:, 2] > 0.02]
            d = np.hypot(traj[:, 1, None] - plants[None, :, 0], traj[:, 2, None] - plants[None, :, 1]) - plants[None, :, 2]
            clear = float(d.min()) - sc.robot_params.radius_m
            per_run.append((float(err.mean()), float(err.std()), float(traj[-1, 1]) > 8.0 and clear > 0.0))
        res[m] = per_run
    return res


def curvy_row_scenario(seed: int, jitter_m: float | None = None) -> Scenario:
    """The built-in curvy_row with its bushes drawn from ``world_seed = 7 + seed`` (seed 0 is the built-in world),
    so each benchmark seed has its own bush scatter, not only its own sensor and wheel-slip noise. ``jitter_m``
    replaces the row's planting jitter (m, 1 sigma per bush centre; the scenario's own 0.05 when None)."""
    text = builtin_text("curvy_row")
    text, n = re.subn(r"(?m)^world_seed = \d+$", f"world_seed = {7 + seed}", text)
    assert n == 1, "curvy_row.toml: no world_seed line"
    if jitter_m is not None:
        text, n = re.subn(r"(?m)^jitter_m = [0-9.eE+-]+$", f"jitter_m = {jitter_m!r}", text)
        assert n == 1, "curvy_row.toml: no jitter_m line"
    return parse_scenario(text, f"<curvy_row seed {seed}>")


def _on_design_line(x_m: float) -> tuple[float, float]:
    """(y m, heading rad) of the curvy_row's design line y = 1.5 sin(2 pi x / 24) at ``x_m``."""
    k = 2 * math.pi / 24.0
    return 1.5 * math.sin(k * x_m), math.atan(1.5 * k * math.cos(k * x_m))


def _beside_row(x_m: float, side: str, distance_m: float) -> Pose2D:
    """Pose on the path ``distance_m`` from the curvy_row centre line (y = 1.5 sin(2 pi x / 24)), heading along it."""
    yr, th = _on_design_line(x_m)
    sgn = 1.0 if side == "left" else -1.0  # the row is on this side of the robot
    return Pose2D(x_m + sgn * math.sin(th) * distance_m, yr - sgn * math.cos(th) * distance_m, th)


def _drive_beside_row(sc: Scenario, side: str, distance_m: float, n: int, rng: np.random.Generator,
                      rate_hz: float = 15.0) -> Iterator[tuple[float, Observation]]:
    """The robot pushed at 0.5 m/s along the path ``distance_m`` from the curvy row's design line (the row on its
    ``side``), one laser scan every 1 / rate_hz s: (x, observation) for n scans, speed and yaw rate from the poses."""
    assert sc.laser is not None
    prev = _beside_row(0.0, side, distance_m)
    for i in range(n):
        x = i * (0.5 / rate_hz)  # as np.arange(0, ., 0.5 / rate_hz) lays the stations
        pose = _beside_row(x, side, distance_m)
        v = math.hypot(pose.x_m - prev.x_m, pose.y_m - prev.y_m) * rate_hz
        w = norm_angle_rad(pose.yaw_rad - prev.yaw_rad) * rate_hz
        prev = pose
        yield x, Observation(i / rate_hz, pose, v, w, Goal(0.0, 0.0), sc.laser.scan(sc.world, pose, i / rate_hz, rng))


def calibrate_half_width(sc: Scenario, params: ProximityFollowerParams, distance_m: float = 1.0,
                         x0_m: float = 2.0, x1_m: float = 22.0) -> float:
    """Field calibration of the crop's visible half-width with the follower's own estimator: the robot is pushed
    at 0.5 m/s along a line marked ``distance_m`` from the centre line of a calibration row (a string line, as one
    would lay with a tape measure) from the row start to ``x1_m``; half-width = distance_m - mean estimated distance
    of the visible face over ``x0_m``..``x1_m``. Only the follower's estimator runs (``observe``), it does not steer."""
    ctrl = ProximityFollower(replace(params, row_half_width_m=0.0))
    ctrl.reset()
    got = []
    n = len(np.arange(0.0, x1_m, 0.5 / 15.0))  # scans from the row start to x1_m
    for x, obs in _drive_beside_row(sc, params.side, distance_m, n, np.random.default_rng(500)):
        est = ctrl.observe(obs)
        if est is not None and x >= x0_m:
            got.append(abs(est.offset_m))
    return distance_m - float(np.mean(got))


PLANTED_WINDOWS_M = (2.0, 3.0, 6.0)  # proximity: the row as planted = mean of the bush centres within this length


def bush_centres(sc: Scenario) -> np.ndarray:
    """The centre of each bush (the mean of its circles; what a surveyor would mark), (k, 2). The curvy row's
    bushes are ``cluster`` circles each, stored bush by bush."""
    cluster = int(tomllib.loads(builtin_text("curvy_row"))["rows"][0]["cluster"])
    c = sc.world.circles
    assert len(c) % cluster == 0, "curvy_row: circles are not whole bushes"
    return c[:, :2].reshape(-1, cluster, 2).mean(axis=1)


def planted_row_offset_m(s_query: np.ndarray, s_bush: np.ndarray, n_bush: np.ndarray, window_m: float) -> np.ndarray:
    """Where the row as planted runs, as a signed offset (m) from the design line at each arc length
    ``s_query``: the mean offset of the bushes within +-window/2 along the row."""
    near = np.abs(s_bush[None, :] - s_query[:, None]) <= 0.5 * window_m
    return (near * n_bush[None, :]).sum(axis=1) / np.maximum(near.sum(axis=1), 1)


def _design_offset_m(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Offset (m, + = left) of points from the curvy row's design line y = 1.5 sin(2 pi x / 24), across the row."""
    k = 2 * math.pi / 24.0
    return (y - 1.5 * np.sin(k * x)) * np.cos(np.arctan(1.5 * k * np.cos(k * x)))


def bush_face_floor(seeds: tuple[int, ...] = (0, 1, 2, 3, 4), windows_m: tuple[float, ...] = (3.0, 6.0, 11.0),
                    jitter_m: float | None = None) -> list[dict[str, float]]:
    """How far the row's visible face itself strays from the plant line, per world: the face the robot sees
    (right side of the row: at each 5 cm station the nearest point of any bush circle) is averaged over a
    window of each length along the row, and the largest deviation of that running mean from the world's
    mean face is reported (m). A follower that knew the row's shape exactly and averaged the face uniformly
    over that length would still be off the plant line by this much, plus its own noise."""
    out = []
    for seed in seeds:
        sc = curvy_row_scenario(seed, jitter_m)
        c = sc.world.circles
        off = _design_offset_m(c[:, 0], c[:, 1])
        st = np.arange(0.0, 48.0, 0.05)
        dx = np.abs(c[None, :, 0] - st[:, None])
        over = dx < c[None, :, 2]
        near = np.where(over, off[None, :] - np.sqrt(np.maximum(c[None, :, 2] ** 2 - dx**2, 0.0)), np.inf).min(axis=1)
        ok = np.isfinite(near)
        mean = float(near[ok & (st > 2.0) & (st < 46.0)].mean())
        row: dict[str, float] = {"seed": seed, "face_mean_m": mean}
        for w in windows_m:
            n = int(round(w / 0.05))
            num = np.convolve(np.where(ok, near, 0.0), np.ones(n), "same")
            den = np.convolve(ok.astype(float), np.ones(n), "same")
            run = num / np.maximum(den, 1.0)
            m = (st > 2.0 + w / 2) & (st < 46.0 - w / 2)
            row[f"w{w:g}"] = float(np.max(np.abs(run[m] - mean)))
        # the bushes' centres themselves (mean of each bush's circles) against the design line, same windows
        bc = bush_centres(sc)
        boff = _design_offset_m(bc[:, 0], bc[:, 1])
        for w in windows_m:
            centre_x = np.arange(2.0 + w / 2, 46.0 - w / 2, 0.05)
            near_b = np.abs(bc[None, :, 0] - centre_x[:, None]) <= w / 2
            run_b = (near_b * boff[None, :]).sum(axis=1) / np.maximum(near_b.sum(axis=1), 1)
            row[f"c{w:g}"] = float(np.max(np.abs(run_b)))
        out.append(row)
    return out


def _row_frames(bc: np.ndarray, stations_x: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The bush centres ``bc`` in the frame of each station on the curvy row's design line (origin on the line,
    x along its tangent): (along, across) per station."""
    for x0 in stations_x:
        y0, th = _on_design_line(float(x0))
        c, s = math.cos(th), math.sin(th)
        dx, dy = bc[:, 0] - x0, bc[:, 1] - y0
        yield c * dx + s * dy, -s * dx + c * dy


def oracle_floor(seeds: tuple[int, ...] = (0, 1, 2, 3, 4), jitter_m: float | None = None
                 ) -> list[tuple[float, str, float, float]]:
    """What a follower could do at best if it knew every bush's true centre (no laser, no visible face, no
    control error): at each station every 0.1 m past x = 2 m, the row's shape is estimated from the bush
    centres within [-back, +ahead] m of it, and the estimate's offset from the design line at the station is
    its error. Two families of shape-agnostic estimators, each tried over a grid of settings: a local
    polynomial (degree 1-4) and a Whittaker smoother on a 0.2 m grid (fourth differences, cut-off 8-12 m).
    Returns (largest error over all seeds and stations in m, estimator, back m, ahead m), best first. The
    settings are picked on the very runs they are scored on, so this is a floor, not a follower."""
    data = [bush_centres(curvy_row_scenario(seed, jitter_m)) for seed in seeds]
    st = np.arange(2.0, 46.0, 0.1)
    out: list[tuple[float, str, float, float]] = []
    for back, ahead, deg in itertools.product((3.0, 5.0, 6.0, 8.0, 10.0), (4.0, 5.5, 8.0), (2, 3, 4)):
        worst = 0.0
        for bc in data:
            for lx, ly in _row_frames(bc, st):
                sel = (lx >= -back) & (lx <= ahead)
                worst = max(worst, abs(float(np.polynomial.polynomial.polyfit(lx[sel], ly[sel], deg)[0])))
        out.append((worst, f"polynomial, degree {deg}", back, ahead))
    h = 0.2
    for back, ahead, cut in itertools.product((10.0, 14.0), (5.5, 8.0), (8.0, 10.0, 12.0)):
        m = int(round((back + ahead) / h)) + 1
        d4 = np.diff(np.eye(m), 4, axis=0)
        pen = (cut / (2 * math.pi * h)) ** 8 * (d4.T @ d4)
        i0 = int(round(back / h))
        worst = 0.0
        for bc in data:
            for lx, ly in _row_frames(bc, st):
                sel = (lx >= -back) & (lx <= ahead)
                idx = np.clip(np.round((lx[sel] + back) / h).astype(int), 0, m - 1)
                f = np.linalg.solve(np.diag(np.bincount(idx, minlength=m).astype(float)) + pen,
                                    np.bincount(idx, ly[sel], minlength=m))
                worst = max(worst, abs(float(f[i0])))
        out.append((worst, f"smoother, cut-off {cut:g} m", back, ahead))
    return sorted(out)


def bench_proximity(seeds: tuple[int, ...] = (0, 1, 2, 3, 4), sil: bool = False,
                    jitter_m: float | None = None) -> list[dict[str, object]]:
    """Proximity following (module docstring). ``sil``: in the SIL (native firmware, radio link, the firmware's
    odometry for the follower's row map; ends within 0.5 m of the path's point at x = 47 m); the follower's own
    estimate is then not compared (NaN). ``jitter_m``: the planting jitter of every row, the calibration rows
    included (None: the scenario's)."""
    from agnav_host.sil.session import run_sil_scenario

    out = []
    # the robot drives 1 m to the right of the row, so the row is on its left
    cals = [curvy_row_scenario(s, jitter_m) for s in PROXIMITY_CALIBRATION_SEEDS]
    assert cals[0].laser is not None
    params = ProximityFollowerParams(side="left", distance_m=1.0, speed_m_s=0.5, mount=cals[0].laser.mount)
    half_width_m = float(np.mean([calibrate_half_width(c, params) for c in cals]))
    for seed in seeds:
        sc = curvy_row_scenario(seed, jitter_m)
        assert sc.laser is not None
        centre = sc.world.row_lines[0]  # the row's design (plant) line, along which the parser laid the bushes
        ctrl = ProximityFollower(replace(params, row_half_width_m=half_width_m))
        own: list[tuple[float, float]] = []  # (t, the follower's own distance estimate)

        class Logged:
            def reset(self) -> None:
                ctrl.reset()

            def step(self, obs: Observation) -> DriveCommand:
                cmd = ctrl.step(obs)
                est = ctrl.distance_estimate_m()
                own.append((obs.t_s, math.nan if est is None else est))
                return cmd

        if sil:
            end = _beside_row(47.0, params.side, params.distance_m)
            sc = replace(sc, goals=[Goal(end.x_m, end.y_m, tolerance_m=0.5)])
            traj = run_sil_scenario(sc, "proximity", seed=seed, controller=Logged(), duration_s=150.0).run.trajectory[:, :4]
            own.clear()  # SIL control steps are stamped in firmware time, not the trajectory's
        else:
            traj = closed_loop(sc, Logged(), seed, 150.0, stop=lambda p: p.x_m > 47.0)
        s_all, n_all = along_and_offset_m(traj[:, 1], traj[:, 2], centre)
        d_all = np.abs(n_all)
        keep = traj[:, 1] > PROXIMITY_SETTLE_X_M
        x = traj[keep, 1]
        d = d_all[keep]
        o = np.asarray(own) if own else np.array([[0.0, math.nan], [1.0, math.nan]])
        d_est = np.interp(traj[keep, 0], o[:, 0], o[:, 1])  # the follower's estimate, between its control steps
        row = {"seed": seed, "world_seed": 7 + seed, "half_width_m": half_width_m, "mean": float(d.mean()),
               "sd": float(d.std()), "min": float(d.min()), "max": float(d.max()),
               "x_min": float(x[np.argmin(d)]), "x_max": float(x[np.argmax(d)]),
               "inside": float(np.mean(np.abs(d - 1.0) <= 0.05)), "length_m": float(traj[-1, 1]),
               "whole_min": float(d_all.min()), "whole_max": float(d_all.max()),
               "est_err_max": float(np.max(np.abs(d_est - d))),
               "ctrl_err_max": float(np.max(np.abs(d_est - 1.0)))}
        # the same run against the row as planted: the bushes' own line, not the design sine they were planted along
        bc = bush_centres(sc)
        s_b, n_b = along_and_offset_m(bc[:, 0], bc[:, 1], centre)
        row["trace"] = (x, d, np.abs(n_all[keep] - planted_row_offset_m(s_all[keep], s_b, n_b, 3.0)))  # type: ignore[assignment]
        for w in PLANTED_WINDOWS_M:
            dp = np.abs(n_all[keep] - planted_row_offset_m(s_all[keep], s_b, n_b, w))
            row[f"planted{w:g}_mean"], row[f"planted{w:g}_sd"] = float(dp.mean()), float(dp.std())
            row[f"planted{w:g}_min"], row[f"planted{w:g}_max"] = float(dp.min()), float(dp.max())
            row[f"planted{w:g}_inside"] = float(np.mean(np.abs(dp - 1.0) <= 0.05))
        out.append(row)
    return out


HOLES_000 = [(2.0, 0.5, 0.8), (0.5, 2.0, 0.8), (0.6, 0.5, 0.6), (7.0, 2.5, 1.0), (3.0, 4.0, 1.0)]  # L x W x D, ref 000 table 5-I


def bench_holes(seeds: tuple[int, ...] = (0, 1, 2)) -> list[dict[str, object]]:
    """Drive straight at each hole (head-on and at 30 deg) with the hole_field robot and tilted laser."""
    base = load_scenario("hole_field")
    assert base.tilted_laser is not None
    tl = base.tilted_laser
    mount = tl.perception_mount()
    results = []
    for (lx, wy, dz) in HOLES_000:
        for approach_deg in (0.0, 30.0):
            for seed in seeds:
                rng = np.random.default_rng(seed)
                world = replace(base.world, holes=[], steps=[], ruts=[])
                # the hole's near edge 6 m ahead of the start, along the approach direction
                a = math.radians(approach_deg)
                hole = Hole(6.0 + lx / 2.0, float(rng.uniform(-0.2, 0.2)), lx, wy, dz)
                world.holes = [hole]
                start = Pose2D(6.0 - 6.0 * math.cos(a), -6.0 * math.sin(a) + hole.y_m, a)
                sc = replace(base, world=world, start=start)
                first: list[float] = []
                robot_r = base.robot_params.radius_m

                class Straight:
                    def reset(self) -> None:
                        pass

                    def step(self, obs: Observation) -> DriveCommand:
                        ts = obs.extras.get("tilted_scan")
                        if ts is not None and not first:
                            g = detect_ground_obstacles(ts, mount, GroundParams())  # type: ignore[arg-type]
                            if len(g.holes_xy):
                                c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
                                wx = obs.pose.x_m + c * g.holes_xy[:, 0] - s * g.holes_xy[:, 1]
                                wy_ = obs.pose.y_m + s * g.holes_xy[:, 0] + c * g.holes_xy[:, 1]
                                inside = hole.height_m(wx, wy_) < 0
                                if inside.any():
                                    # distance from the robot's front to the hole boundary along the heading
                                    first.append(obs.t_s)
                        return DriveCommand(0.5, 0.0)

                def in_hole(p: Pose2D) -> bool:
                    fx, fy = p.x_m + robot_r * math.cos(p.yaw_rad), p.y_m + robot_r * math.sin(p.yaw_rad)
                    return bool(hole.height_m(np.array(fx), np.array(fy)) < 0)

                traj = closed_loop(sc, Straight(), seed, 20.0, stop=in_hole, tilted=True)
                t_reach = float(traj[-1, 0])
                ok = bool(first) and first[0] < t_reach
                results.append({"hole": f"{lx}x{wy}x{dz}", "approach_deg": approach_deg, "seed": seed, "detected": ok,
                                "margin_m": (t_reach - first[0]) * 0.5 if first else float("nan")})
    return results


RUTS_SETTLE_X_M = 3.0  # ruts: samples before the robot passes this x are the capture


def bench_ruts(seeds: tuple[int, ...] = (0, 1, 2, 3, 4), sil: bool = False) -> list[dict[str, object]]:
    """The built-in ``ruts`` scenario in the simulator's runner (tilted laser as a scenario sensor), the rut
    follower in closed loop; seed n starts n * 0.05 m further left (0.15-0.35 m) and draws its own noise.
    Lateral error = signed distance of the robot's reference point from the true midline (the ruts' centre
    polyline in the world), every physics step once the robot is past x = RUTS_SETTLE_X_M.
    ``sil``: the same in the SIL (native firmware, radio link): the follower places its rut points with the
    firmware's odometry instead of the true pose, and drives through the firmware's setpoints."""
    from agnav_host.perception import RutFollower, RutFollowerParams
    from agnav_host.sil.session import run_sil_scenario
    from agnav_host.sim.runner import run_scenario

    base = load_scenario("ruts")
    assert base.tilted_laser is not None
    tl = base.tilted_laser
    mid = np.asarray(base.world.ruts[0].points)
    out = []
    for seed in seeds:
        sc = replace(base, start=replace(base.start, y_m=base.start.y_m + 0.05 * seed))
        ctrl = RutFollower(RutFollowerParams(tilted=tl.perception_mount()))
        res = (run_sil_scenario(sc, "rut_follower", seed=seed, controller=ctrl).run if sil
               else run_scenario(sc, "rut_follower", seed=seed, controller=ctrl))
        tr = res.trajectory
        e = signed_offset_m(tr[:, 1], tr[:, 2], mid)
        keep = tr[:, 1] > RUTS_SETTLE_X_M
        out.append({"seed": seed, "start_e": float(e[0]), "end": res.end_reason, "x_end": float(tr[-1, 1]),
                    "mean_abs": float(np.abs(e[keep]).mean()), "sd": float(e[keep].std()),
                    "max_abs": float(np.abs(e[keep]).max()), "traj": tr})
    return out


def bench_hole_field(seeds: tuple[int, ...] = (0, 1, 2, 3, 4), sil: bool = False) -> list[dict[str, object]]:
    """The built-in ``hole_field`` (three holes of ref 000 in the way to a goal 24 m ahead) in the simulator's
    runner: the goal-seeking stand-in reads only the horizontal laser; wrapped in GroundGuard, the tilted laser's
    holes reach it as posts. Clearance = nearest approach of the robot's disc (radius from the scenario) to each
    hole's rim, from the world's hole shapes. ``sil``: the same in the SIL (native firmware, radio link), the
    holes mapped with the firmware's odometry and the SIL host's goal-seeking parameters."""
    from agnav_host.perception import GroundGuard, GroundGuardParams
    from agnav_host.sil.session import PlannerHost, run_sil_scenario
    from agnav_host.sim.controller import GoalSeek
    from agnav_host.sim.runner import _standin_params, run_scenario

    sc = load_scenario("hole_field")
    assert sc.tilted_laser is not None
    tl = sc.tilted_laser
    r = sc.robot_params.radius_m
    out = []
    for seed in seeds:
        gp = GroundGuardParams(tl.perception_mount())
        if sil:
            plain = run_sil_scenario(sc, "goal_seek", seed=seed).run
            guard = GroundGuard(GoalSeek(PlannerHost.planner_params(sc)), gp)
            res = run_sil_scenario(sc, "goal_seek+ground_guard", seed=seed, controller=guard).run
        else:
            plain = run_scenario(sc, "goal_seek", seed=seed)
            guard = GroundGuard(GoalSeek(_standin_params(sc)), gp)
            res = run_scenario(sc, "goal_seek+ground_guard", seed=seed, controller=guard)
        tr = res.trajectory
        clear = [disc_clearance_to_hole_m(tr[:, 1], tr[:, 2], r, h) for h in sc.world.holes]
        out.append({"seed": seed, "plain_end": plain.end_reason, "plain_x": float(plain.trajectory[-1, 1]),
                    "end": res.end_reason, "t_s": float(tr[-1, 0]), "length_m": float(res.metrics.path_length_m),
                    "clearance_m": clear, "detections": guard.detections, "traj": tr})
    return out


def save_plots(out_dir: str, ruts: list[dict[str, object]] | None, holes: list[dict[str, object]] | None,
               proximity: list[dict[str, object]] | None = None) -> list[str]:
    """Figures of the closed-loop runs (PNG): rut following and hole avoidance with the tilted laser, and the
    proximity following's distance along the row; [] when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    from pathlib import Path

    from agnav_host.viz.world_plot import draw_goals, draw_world

    Path(out_dir).mkdir(parents=True, exist_ok=True)
    written = []

    def save(fig: object, name: str) -> None:
        fig.tight_layout()  # type: ignore[attr-defined]
        fig.savefig(f"{out_dir}/{name}", dpi=110)  # type: ignore[attr-defined]
        plt.close(fig)
        written.append(f"{out_dir}/{name}")
    if ruts:
        sc = load_scenario("ruts")
        rut = sc.world.ruts[0]
        mid = np.asarray(rut.points)
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(9, 6), gridspec_kw={"height_ratios": [2, 1]})
        draw_world(ax, sc, legend_entries=False)
        ax.plot(mid[:, 0], mid[:, 1], "k--", lw=0.8, label="midline (world)")
        for r in ruts:
            tr = r["traj"]  # type: ignore[index]
            ax.plot(tr[:, 1], tr[:, 2], lw=0.8, label=f"seed {r['seed']}")  # type: ignore[index]
            e = signed_offset_m(tr[:, 1], tr[:, 2], mid)  # type: ignore[index]
            ax2.plot(tr[:, 1], 100 * e, lw=0.8)  # type: ignore[index]
        ax2.axvline(RUTS_SETTLE_X_M, color="0.5", lw=0.6)
        ax.legend(fontsize=6, ncol=3)
        ax.set_title("ruts: rut following with the tilted laser (brown: the ruts)")
        ax2.set_xlabel("x, m")
        ax2.set_ylabel("lateral error, cm")
        save(fig, "ruts.png")
    if holes:
        sc = load_scenario("hole_field")
        fig, ax = plt.subplots(figsize=(9, 5))
        draw_world(ax, sc)
        draw_goals(ax, sc.goals, sc.start)
        for r in holes:
            tr = r["traj"]  # type: ignore[index]
            ax.plot(tr[:, 1], tr[:, 2], lw=0.8, label=f"seed {r['seed']} ({r['end']})", zorder=4)  # type: ignore[index]
        ax.legend(fontsize=6, ncol=2)
        ax.set_title("hole_field: goal seeking with GroundGuard")
        save(fig, "hole_field.png")
    if proximity:
        fig, axes = plt.subplots(len(proximity), 1, figsize=(10, 1.6 * len(proximity) + 0.8), sharex=True, squeeze=False)
        for ax, r in zip(axes[:, 0], proximity):
            x, d, dp = r["trace"]  # type: ignore[misc]
            ax.axhspan(95, 105, color="0.9", lw=0)
            ax.plot(x, 100 * d, lw=0.8, label="to the design line")
            ax.plot(x, 100 * dp, lw=0.8, label="to the row as planted (bush centres, 3 m)")
            ax.set_ylabel(f"seed {r['seed']}\ncm", fontsize=8)
            ax.set_ylim(90, 110)
        axes[0, 0].legend(fontsize=7, ncol=2, loc="upper right")
        axes[0, 0].set_title("curvy_row: the robot's distance from the row (grey: 1 m +- 5 cm)")
        axes[-1, 0].set_xlabel("x, m")
        save(fig, "proximity.png")
    return written


def bench_latency(repeats: int = 400) -> dict[str, float]:
    from agnav_host.sim.sensors import Laser2D, laser_preset

    sc = parse_scenario(row_lane_toml(7, laser="tim561"), "<row_lane>")
    las = Laser2D(laser_preset("tim561"), Pose2D(0.2, 0.0, 0.0))
    rng = np.random.default_rng(0)
    scans = [las.scan(sc.world, Pose2D(float(rng.uniform(0.5, 6)), float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-0.05, 0.05))),
                      0.0, rng) for _ in range(40)]
    out = {}
    for m in row_method_names():
        ctrl = RowFollower(RowFollowerParams(method=m, mount=las.mount))
        ctrl.reset()
        times = []
        for i in range(repeats):
            s = scans[i % len(scans)]
            obs = Observation(i / 15.0, Pose2D(), 0.4, 0.0, Goal(0, 0), s)
            t0 = time.perf_counter()
            ctrl.step(obs)
            times.append(time.perf_counter() - t0)
        out[m] = statistics.median(times[20:])
    out["proximity follower"] = bench_proximity_step()
    return out


def bench_proximity_step(n_scans: int = 700, timed_from: int = 400) -> float:
    """Median wall time (s) of one ProximityFollower step (row map, smoother, filter, law) on the curvy row,
    pushed along the 1 m path at 0.5 m/s, 15 scans/s; timed once the map holds its full 11.5 m of travel."""
    sc = curvy_row_scenario(0)
    assert sc.laser is not None
    ctrl = ProximityFollower(ProximityFollowerParams(side="left", distance_m=1.0, speed_m_s=0.5, mount=sc.laser.mount,
                                                     row_half_width_m=0.141))
    ctrl.reset()
    times = []
    for _, obs in _drive_beside_row(sc, "left", 1.0, n_scans, np.random.default_rng(0)):
        t0 = time.perf_counter()
        ctrl.step(obs)
        times.append(time.perf_counter() - t0)
    return statistics.median(times[timed_from:])


def _variants(parts: set[str], name: str) -> list[tuple[bool, str]]:
    """(sil, where) for each of ``name`` (the simulator's runner, true pose) and ``name_sil`` asked for in parts."""
    out = []
    if name in parts:
        out.append((False, "the simulator's runner"))
    if name + "_sil" in parts:
        out.append((True, "the SIL: native firmware, radio link, the firmware's odometry"))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="rows,proximity,proximity_sil,face,oracle,holes,ruts,ruts_sil,hole_field,hole_field_sil,latency")
    ap.add_argument("--methods", default=",".join(row_method_names()))
    ap.add_argument("--plots", default="bench/results/perception", metavar="DIR",
                    help="where the closed-loop figures go (PNG; '' for none)")
    ap.add_argument("--row-jitter", type=float, default=None, metavar="M",
                    help="proximity and face: the curvy row's planting jitter, m (1 sigma per bush; default the "
                         "scenario's 0.05), for how the figures depend on it")
    ns = ap.parse_args(argv)
    if ns.row_jitter is not None and not (0.0 <= ns.row_jitter <= 0.5):
        ap.error(f"--row-jitter must be 0-0.5 m, got {ns.row_jitter:g}")
    parts = set(ns.only.split(","))
    ruts_res: list[dict[str, object]] | None = None
    holes_res: list[dict[str, object]] | None = None
    prox_res: list[dict[str, object]] | None = None
    if "rows" in parts:
        res = bench_rows(ns.methods.split(","))
        print("## Row following, 8 m lane, rows 0.75 m apart, TiM310-like, 10 % gaps, weeds (5 runs)")
        print("| method | mean abs(e) +- sd, m (avg of 5 runs) | runs (mean) | clean runs | ref 004 | better than 004 |")
        print("|---|---|---|---|---|---|")
        for m, runs in res.items():
            mean = statistics.mean(r[0] for r in runs)
            sd = statistics.mean(r[1] for r in runs)
            ref = REF_004.get(m)
            refs = f"{ref[0]:.3f} +- {ref[1]:.3f}" if ref else "-"
            better = ("yes" if mean < ref[0] else "NO") if ref else "-"
            clean = sum(bool(r[2]) for r in runs)
            print(f"| {m} | {mean:.4f} +- {sd:.4f} | {', '.join(f'{r[0]:.4f}' for r in runs)} | {clean}/{len(runs)} | {refs} | {better} |")
        sys.stdout.flush()
    for sil, where in _variants(parts, "proximity"):
        pr = bench_proximity(sil=sil, jitter_m=ns.row_jitter)
        if not sil:
            prox_res = pr
        print(f"\n## Proximity following, curvy_row (50 m), target 1.00 +- 0.05 m from the row centre line; {where}")
        print(f"(every physics step once the robot is past x = {PROXIMITY_SETTLE_X_M:.0f} m; each seed its own bushes; visible "
              f"half-width {pr[0]['half_width_m']:.3f} m, mean of calibration drives on world_seeds "
              f"{', '.join(str(7 + s) for s in PROXIMITY_CALIBRATION_SEEDS)})")
        print("| seed | world_seed | mean, m | sd, m | min (at x), m | max (at x), m | within +-0.05 m "
              "| whole run incl. settling, m | max abs(own estimate - true), m | max abs(own estimate - 1), m |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in pr:
            print(f"| {r['seed']} | {r['world_seed']} | {r['mean']:.3f} | {r['sd']:.3f} "
                  f"| {r['min']:.3f} ({r['x_min']:.1f}) | {r['max']:.3f} ({r['x_max']:.1f}) | {100.0 * r['inside']:.1f} % "
                  f"| {r['whole_min']:.3f}-{r['whole_max']:.3f} | {r['est_err_max']:.3f} | {r['ctrl_err_max']:.3f} |")
        print("\n(the same runs against the row as planted: the bushes' centres averaged over a stretch of row of each "
              f"length, instead of the design sine they were planted along with "
              f"{100 * (0.05 if ns.row_jitter is None else ns.row_jitter):g} cm jitter)")
        print("| seed | " + " | ".join(f"{w:g} m: mean +- sd, min-max, within +-0.05" for w in PLANTED_WINDOWS_M) + " |")
        print("|---|" + "---|" * len(PLANTED_WINDOWS_M))
        for r in pr:
            print(f"| {r['seed']} | " + " | ".join(
                f"{r[f'planted{w:g}_mean']:.3f} +- {r[f'planted{w:g}_sd']:.3f}, {r[f'planted{w:g}_min']:.3f}-"
                f"{r[f'planted{w:g}_max']:.3f}, {100.0 * r[f'planted{w:g}_inside']:.1f} %" for w in PLANTED_WINDOWS_M) + " |")
        sys.stdout.flush()
    if "face" in parts:
        fl = bush_face_floor(jitter_m=ns.row_jitter)
        print("\n(the bushes' face against the plant line: largest deviation of its running mean over 3 / 6 / 11 m of row "
              "from the world's mean face, m; a floor for any follower that sees only the face. The bush centres' columns: "
              "the same for the bushes' centres against the design line - where the plants themselves stand off it)")
        print("| seed | mean face, m from the plant line | face 3 m | 6 m | 11 m | bush centres 3 m | 6 m | 11 m |")
        print("|---|---|---|---|---|---|---|---|")
        for r in fl:
            print(f"| {r['seed']} | {r['face_mean_m']:+.3f} | {r['w3']:.3f} | {r['w6']:.3f} | {r['w11']:.3f} "
                  f"| {r['c3']:.3f} | {r['c6']:.3f} | {r['c11']:.3f} |")
        sys.stdout.flush()
    if "oracle" in parts:
        orc = oracle_floor(jitter_m=ns.row_jitter)
        print("\n(the floor under any shape-agnostic follower: the row estimated from the bushes' true centres, no laser, "
              "no face, no control error; largest offset from the design line over 5 seeds, settings picked on these runs)")
        print("| estimator | back, m | ahead, m | largest error, m |")
        print("|---|---|---|---|")
        within_reach = [o for o in orc if o[3] <= 5.5]
        for worst, name, back, ahead in orc[:3] + [o for o in within_reach[:3] if o not in orc[:3]]:
            print(f"| {name} | {back:g} | {ahead:g} | {worst:.4f} |")
        sys.stdout.flush()
    if "holes" in parts:
        hr = bench_holes()
        print("\n## Holes of ref 000 table 5-I, detected before the robot's front reaches them")
        print("| hole L x W x D, m | approach | detected | margin at detection (min), m |")
        print("|---|---|---|---|")
        keys = sorted({(str(r["hole"]), float(r["approach_deg"])) for r in hr}, key=lambda k: (HOLES_000_ORDER(k[0]), k[1]))
        for h, a in keys:
            rs = [r for r in hr if r["hole"] == h and r["approach_deg"] == a]
            n_ok = sum(bool(r["detected"]) for r in rs)
            print(f"| {h} | {a:.0f} deg | {n_ok}/{len(rs)} | {min(float(r['margin_m']) for r in rs):.2f} |")  # type: ignore[arg-type]
        tot = sum(bool(r["detected"]) for r in hr)
        print(f"| all | | {tot}/{len(hr)} ({100.0 * tot / len(hr):.0f} %) | |")
        sys.stdout.flush()
    for sil, where in _variants(parts, "ruts"):
        res_r = bench_ruts(sil=sil)
        ruts_res = ruts_res or res_r
        print(f"\n## Rut following in closed loop: ruts.toml (two ruts 1.5 m apart along a curvy track), tilted laser; {where}")
        print(f"(lateral error to the true midline, every physics step once the robot is past x = {RUTS_SETTLE_X_M:.0f} m)")
        print("| seed | start offset, m | end | x reached, m | mean abs(e), m | sd, m | max abs(e), m |")
        print("|---|---|---|---|---|---|---|")
        for r in res_r:
            print(f"| {r['seed']} | {r['start_e']:+.3f} | {r['end']} | {r['x_end']:.1f} | {r['mean_abs']:.3f} | {r['sd']:.3f} "
                  f"| {r['max_abs']:.3f} |")
        sys.stdout.flush()
    for sil, where in _variants(parts, "hole_field"):
        res_h = bench_hole_field(sil=sil)
        holes_res = holes_res or res_h
        print(f"\n## Holes in closed loop: hole_field.toml, goal seeking with and without GroundGuard (tilted laser); {where}")
        print("(clearance = nearest approach of the robot's disc to each hole's rim; negative = over the hole)")
        print("| seed | without guard | with guard | time, s | path, m | clearance to holes 1 / 2 / 3, m | scans with a detection |")
        print("|---|---|---|---|---|---|---|")
        for r in res_h:
            cl = " / ".join(f"{c:.2f}" for c in r["clearance_m"])  # type: ignore[attr-defined]
            print(f"| {r['seed']} | {r['plain_end']} at x = {r['plain_x']:.1f} m | {r['end']} | {r['t_s']:.1f} | {r['length_m']:.1f} "
                  f"| {cl} | {r['detections']} |")
        sys.stdout.flush()
    if ns.plots and (ruts_res or holes_res or prox_res):
        for path in save_plots(ns.plots, ruts_res, holes_res, prox_res):
            print(f"\n(figure: {path})")
    if "latency" in parts:
        lat = bench_latency()
        print("\n## Latency: detection + control, one 811-beam TiM561 scan (median)")
        print("(row methods: RowFollower in a row lane; proximity follower: its whole step with the row map full, "
              "curvy row)")
        print("| method | median, ms |")
        print("|---|---|")
        for m, t in lat.items():
            print(f"| {m} | {t * 1e3:.3f} |")
    return 0


def HOLES_000_ORDER(name: str) -> int:  # noqa: N802 - keeps the table in the reference's order
    return [f"{a}x{b}x{c}" for a, b, c in HOLES_000].index(name)


if __name__ == "__main__":
    raise SystemExit(main())
