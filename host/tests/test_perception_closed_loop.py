"""Tilted laser in the simulator's closed loop: rut following on ``ruts`` and hole avoidance on ``hole_field``."""

import math

import numpy as np
import pytest

from agnav_host.sim.metrics import signed_offset_m
from agnav_host.perception import (
    GroundGuard,
    GroundGuardParams,
    GroundParams,
    RutFollower,
    RutFollowerParams,
    TiltedMount,
    detect_ground_obstacles,
    scan_with_virtual_obstacles,
)
from agnav_host.sim.controller import GoalSeek
from agnav_host.sim.runner import _standin_params, run_scenario
from agnav_host.sim.scenario import Scenario, load_scenario
from agnav_host.sim.sensors import TiltedLaser, laser_preset
from agnav_host.sim.world import Rut, World
from agnav_host.types import DriveCommand, LaserScan, Observation, Pose2D


def _mount(sc: Scenario) -> TiltedMount:
    tl = sc.tilted_laser
    assert tl is not None
    return tl.perception_mount()


class _Recorder:
    def __init__(self, uses: bool) -> None:
        self.uses_tilted_laser = uses
        self.seen: list[object] = []

    def reset(self) -> None:
        self.seen = []

    def step(self, obs: Observation) -> DriveCommand:
        self.seen.append(obs.extras.get("tilted_scan"))
        return DriveCommand(0.3, 0.0)


def test_runner_scans_the_tilted_laser_only_for_controllers_that_use_it():
    sc = load_scenario("ruts")
    yes, no = _Recorder(True), _Recorder(False)
    run_scenario(sc, "recorder", seed=1, duration_s=0.5, controller=yes)
    run_scenario(sc, "recorder", seed=1, duration_s=0.5, controller=no)
    assert len(yes.seen) >= 7 and all(isinstance(s, LaserScan) for s in yes.seen)
    assert all(s is None for s in no.seen)
    first = yes.seen[0]
    assert isinstance(first, LaserScan) and len(first.ranges_m) == 101  # fov_deg = 100 at 1 deg in ruts.toml
    # the ruts cross the scan line: the ground profile dips by the rut depth (0.12 m)
    tl = sc.tilted_laser
    assert tl is not None
    z = tl.ground_points(first)[:, 2]
    assert z.min() == pytest.approx(-0.12, abs=0.03) and np.median(z) == pytest.approx(0.0, abs=0.01)


def test_rut_follower_keeps_to_the_ruts_midline_in_closed_loop():
    sc = load_scenario("ruts")
    ctrl = RutFollower(RutFollowerParams(tilted=_mount(sc)))
    res = run_scenario(sc, "rut_follower", seed=0, duration_s=22.0, controller=ctrl)
    tr = res.trajectory
    assert res.end_reason == "timeout" and tr[-1, 1] > 7.0  # about 8 m along the curvy track
    e = signed_offset_m(tr[:, 1], tr[:, 2], np.asarray(sc.world.ruts[0].points))
    # starts 0.15 m left of the midline in y, where the track runs at atan(2 pi / 16) = 21 deg
    assert e[0] == pytest.approx(0.15 * math.cos(math.atan(2 * math.pi / 16)), abs=0.005)
    settled = tr[:, 1] > 3.0
    assert np.abs(e[settled]).max() < 0.04, f"max lateral error {np.abs(e[settled]).max():.3f} m past x = 3 m"


def test_virtual_posts_shorten_only_the_beams_that_meet_them():
    n = 181
    scan = LaserScan(-math.pi / 2, math.pi / 180, np.full(n, 5.0), 8.0, 0.0, Pose2D(1.0, 0.0, 0.0))
    out = scan_with_virtual_obstacles(scan, Pose2D(1.0, 0.0, 0.0), np.array([[3.0, 0.0], [1.0, -20.0]]), 0.1)
    r = out.ranges_m
    assert r[90] == pytest.approx(1.9, abs=1e-9)  # straight ahead: the post's near side
    hit = np.flatnonzero(r < 5.0)
    assert set(hit) == {88, 89, 90, 91, 92}  # asin(0.1 / 2) = 2.87 deg either side: the beams at 0, +-1, +-2 deg
    assert np.all(r[hit] >= 1.9) and np.all(r[hit] < 2.0)
    assert np.array_equal(scan.ranges_m, np.full(n, 5.0))  # the input is not changed


def test_min_hole_depth_keeps_shallow_ruts_out_of_the_holes():
    tl = TiltedLaser(laser_preset("lms200"), 0.8, math.radians(20.0), Pose2D(0.3, 0.0, 0.0))
    tm = tl.perception_mount()
    rut = Rut(((-1.0, 0.5), (6.0, 0.5)), width_m=0.3, depth_m=0.12, count=1)  # along the path, 0.5 m to the left
    scan = tl.scan(World(ruts=[rut]), Pose2D(), 0.0, None)
    assert detect_ground_obstacles(scan, tm).hole.any()  # ref 000's range rule alone flags a 12 cm rut
    assert not detect_ground_obstacles(scan, tm, GroundParams(min_hole_depth_m=0.15)).hole.any()


def test_hole_field_without_the_tilted_laser_falls_into_the_first_hole():
    sc = load_scenario("hole_field")
    res = run_scenario(sc, "goal_seek", seed=0, duration_s=30.0)
    assert res.end_reason == "fell_in_hole" and res.trajectory[-1, 1] < 6.5


def test_ground_guard_drives_round_every_hole_to_the_goal():
    sc = load_scenario("hole_field")
    guard = GroundGuard(GoalSeek(_standin_params(sc)), GroundGuardParams(_mount(sc)))
    res = run_scenario(sc, "goal_seek+ground_guard", seed=0, controller=guard)
    assert res.end_reason == "arrived"
    assert guard.detections > 0
    tr = res.trajectory
    r = sc.robot_params.radius_m
    for h in sc.world.holes:
        # the robot's disc never overlaps the hole: no sample point of the disc rim is over it
        ang = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
        rx = tr[:, 1, None] + r * np.cos(ang)[None, :]
        ry = tr[:, 2, None] + r * np.sin(ang)[None, :]
        assert not (h.height_m(rx, ry) < 0).any(), f"robot over the hole at ({h.x_m}, {h.y_m})"
