"""Perception controllers in the SIL: the real firmware (native build, simulated HAL) drives, the radio
link carries the setpoints and the odometry, and the controllers place what the tilted laser sees with
the firmware's odometry, not the simulator's true pose. Every assertion prints the measured value."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from agnav_host.perception import GroundGuard, GroundGuardParams, RutFollower, RutFollowerParams, TiltedMount
from agnav_host.sil import run_sil_scenario
from agnav_host.sil.session import PlannerHost
from agnav_host.sim import load_scenario
from agnav_host.sim.controller import GoalSeek
from agnav_host.sim.metrics import disc_clearance_to_hole_m, signed_offset_m
from agnav_host.types import DriveCommand, Observation


def _mount(sc) -> TiltedMount:
    tl = sc.tilted_laser
    assert tl is not None, f"{sc.name} has no [tilted_laser]"
    return tl.perception_mount()


def test_rut_follower_on_firmware_odometry_keeps_to_the_midline():
    """ruts.toml from 0.14 m off the midline: arrives, and past x = 3 m the robot stays within 3 cm of the
    ruts' true midline (ideal runner: max 0.017-0.021 m)."""
    sc = load_scenario("ruts")
    res = run_sil_scenario(sc, "rut_follower", seed=0, controller=RutFollower(RutFollowerParams(tilted=_mount(sc))))
    tr = res.run.trajectory
    e = signed_offset_m(tr[:, 1], tr[:, 2], np.asarray(sc.world.ruts[0].points))
    keep = tr[:, 1] > 3.0
    mean, worst = float(np.abs(e[keep]).mean()), float(np.abs(e[keep]).max())
    print(f"end {res.run.end_reason} at x = {tr[-1, 1]:.1f} m; |e| mean {mean:.4f} m, max {worst:.4f} m")
    assert res.run.end_reason == "arrived", f"ended {res.run.end_reason} at x = {tr[-1, 1]:.1f} m"
    assert mean < 0.015 and worst < 0.03, f"lateral error mean {mean:.4f} m, max {worst:.4f} m"


def test_ground_guard_on_firmware_odometry_steers_round_holes_the_plain_planner_falls_into():
    """hole_field.toml: the goal seeker alone falls into the first hole; wrapped in GroundGuard (holes from
    the tilted laser, mapped with the firmware's odometry) it arrives with the disc clear of every rim."""
    sc = load_scenario("hole_field")
    plain = run_sil_scenario(sc, "goal_seek", seed=1)
    guard = GroundGuard(GoalSeek(PlannerHost.planner_params(sc)), GroundGuardParams(_mount(sc)))
    res = run_sil_scenario(sc, "goal_seek+ground_guard", seed=1, controller=guard)
    tr = res.run.trajectory
    gaps = [disc_clearance_to_hole_m(tr[:, 1], tr[:, 2], sc.robot_params.radius_m, h) for h in sc.world.holes]
    print(f"plain: {plain.run.end_reason} at x = {plain.run.trajectory[-1, 1]:.1f} m; guarded: {res.run.end_reason} "
          f"in {tr[-1, 0]:.1f} s, {guard.detections} scans with a detection, disc-to-rim clearances {[round(g, 2) for g in gaps]}")
    assert plain.run.end_reason == "fell_in_hole", f"the plain planner ended {plain.run.end_reason}"
    assert res.run.end_reason == "arrived", f"guarded run ended {res.run.end_reason} at x = {tr[-1, 1]:.1f} m"
    assert guard.detections > 0
    assert min(gaps) > 0.0, f"the disc came within {min(gaps):.3f} m of a hole's rim"


def test_tilted_scan_is_placed_with_the_believed_pose():
    """The SIL host hands the tilted scan over with the pose the host believes (the firmware's odometry) -
    the same pose as the observation's - and only to controllers that ask for it."""
    sc = load_scenario("ruts")
    seen: list[tuple[object, object]] = []

    class Probe:
        uses_tilted_laser = True

        def reset(self) -> None:
            pass

        def step(self, obs: Observation) -> DriveCommand:
            seen.append((obs.pose, obs.extras.get("tilted_scan")))
            return DriveCommand(0.3, 0.1)

    class Blind(Probe):
        uses_tilted_laser = False

    run_sil_scenario(replace(sc, duration_s=3.0), "probe", seed=0, controller=Probe())
    assert len(seen) > 10, f"{len(seen)} control steps in 3 s"
    tl = sc.tilted_laser
    assert tl is not None
    for pose, ts in seen[5:]:
        assert ts is not None and ts.pose is not None
        want = pose.compose(tl.mount)
        assert abs(ts.pose.x_m - want.x_m) < 1e-9 and abs(ts.pose.y_m - want.y_m) < 1e-9 and abs(ts.pose.yaw_rad - want.yaw_rad) < 1e-9
    seen.clear()
    run_sil_scenario(replace(sc, duration_s=1.0), "probe", seed=0, controller=Blind())
    assert seen and all(ts is None for _, ts in seen), "a controller that does not read the tilted laser got its scan"
