"""The host loop shared by the simulator, the SIL and `agnav run`: what it hands the controller, when it holds
the robot, when it leaves the last command standing, and the firmware setpoint it makes; `agnav run` with a
replayed laser against the fake robot."""

from __future__ import annotations

import json
import math

import numpy as np

from agnav_host import cli
from agnav_host.hostloop import HostLoop, SensorFrame, firmware_setpoint
from agnav_host.lasers import LaserMount
from agnav_host.lasers.log import LaserLogWriter
from agnav_host.link.fake import FakeRobot
from agnav_host.sim.metrics import SUMMARY_KEYS
from agnav_host.types import DriveCommand, Goal, LaserScan, Pose2D


class Recording:
    """A controller that records what it was given."""

    def __init__(self) -> None:
        self.seen: list = []

    def reset(self) -> None:
        self.seen = []

    def step(self, obs):
        self.seen.append(obs)
        return DriveCommand(0.3, 0.1)


def _scan(t: float, r: float = 2.0) -> LaserScan:
    rng = np.random.default_rng(int(t * 1000))
    return LaserScan(-1.0, 0.01, r + 0.01 * rng.standard_normal(201), 10.0, t)


def test_the_scan_is_placed_with_the_planned_pose_and_the_mount():
    c = Recording()
    loop = HostLoop(c, [Goal(5.0, 0.0)], laser_mount=Pose2D(0.2, 0.0, 0.0))
    d = loop.step(SensorFrame(0.0, Pose2D(1.0, 2.0, math.pi / 2), scan=_scan(0.0)))
    assert d.command == DriveCommand(0.3, 0.1)
    sp = c.seen[0].scan.pose
    assert math.isclose(sp.x_m, 1.0, abs_tol=1e-12) and math.isclose(sp.y_m, 2.2) and c.seen[0].extras["goal_index"] == 0


def test_between_two_scans_the_controller_is_not_stepped_and_the_last_command_stands():
    c = Recording()
    loop = HostLoop(c, [Goal(5.0, 0.0)], laser_mount=Pose2D())
    loop.step(SensorFrame(0.0, Pose2D(), scan=_scan(0.0)))
    d = loop.step(SensorFrame(0.05, Pose2D(), scan=None))
    assert d.command is None and d.idle == "no new scan" and not d.hold and len(c.seen) == 1


def test_a_silent_laser_holds_the_robot_and_says_why_once():
    c = Recording()
    loop = HostLoop(c, [Goal(5.0, 0.0)], laser_mount=Pose2D())
    loop.step(SensorFrame(0.0, Pose2D(), scan=_scan(0.0)))
    said = [d.event for d in (loop.step(SensorFrame(0.1 * k, Pose2D(), scan=None)) for k in range(1, 12)) if d.event]
    d = loop.step(SensorFrame(1.3, Pose2D(), scan=None))
    assert d.hold.startswith("laser fault: no scan for") and d.command == DriveCommand()
    assert len(said) == 1 and "holding the robot" in said[0]


def test_on_a_robot_the_loop_judges_the_goals_itself():
    c = Recording()
    loop = HostLoop(c, [Goal(1.0, 0.0, tolerance_m=0.2), Goal(2.0, 0.0, tolerance_m=0.2)])
    assert not loop.step(SensorFrame(0.0, Pose2D(0.9, 0.0))).arrived and loop.goal_index == 1
    d = loop.step(SensorFrame(0.1, Pose2D(1.95, 0.05)))
    assert d.arrived and d.command == DriveCommand() and "goal reached" in d.event


def test_a_tilted_scan_reaches_the_controller_once():
    c = Recording()
    c.uses_tilted_laser = True
    loop = HostLoop(c, [Goal(5.0, 0.0)], laser_mount=Pose2D(), tilted_mount=Pose2D(0.3, 0.0, 0.0))
    loop.step(SensorFrame(0.0, Pose2D(1.0, 0.0, 0.0), scan=_scan(0.0), tilted_scan=_scan(0.0, 1.0)))
    assert c.seen[0].extras["tilted_scan"].pose == Pose2D(1.3, 0.0, 0.0)
    loop.step(SensorFrame(0.07, Pose2D(1.1, 0.0, 0.0), scan=_scan(0.07)))
    assert "tilted_scan" not in c.seen[1].extras


def test_no_pose_no_command():
    d = HostLoop(Recording(), [Goal(1.0, 0.0)]).step(SensorFrame(0.0, None))
    assert d.command is None and d.idle == "no pose yet"


def test_firmware_setpoint_turns_a_spin_into_a_backwards_arc_and_limits_the_speed():
    steer, v = firmware_setpoint(DriveCommand(0.0, 1.0), "diff_drive", 0.4, 0.174, math.radians(45))
    assert math.isclose(steer, -math.radians(45)) and v < 0
    steer, v = firmware_setpoint(DriveCommand(3.0, 0.0, 0.1), "ackermann", 0.19, 0.174, math.radians(30), 1.0)
    assert steer == 0.1 and v == 1.0
    steer, v = firmware_setpoint(DriveCommand(0.5, 0.5), "diff_drive", 0.4, 0.174, math.radians(45))
    assert math.isclose(math.tan(steer) * 0.5 / 0.4, 0.5)


def test_agnav_run_drives_a_laser_planner_on_a_replayed_log(tmp_path, capsys):
    log = tmp_path / "scans.alog"
    with LaserLogWriter(log) as w:
        w.declare(0, "tim5xx://test", "tim5xx", "TiM561", LaserMount(0.2), _scan(0.0), "device", 0.0)
        for k in range(60):
            w.write(0, _scan(k / 15.0, 8.0), k / 15.0, None)  # open ground, a wall 8 m off
    out = tmp_path / "run"
    with FakeRobot() as fr:
        rc = cli.main(["run", "--device", fr.device, "--laser", f"replay:{log}?x=0.2", "--planner", "him",
                       "--goal", "3,0", "--duration", "2", "--out", str(out), "--no-plot"])
        sps = fr.received_of("AGNAV_DRIVE_SETPOINT")
    err = capsys.readouterr()
    assert rc == 0, err
    assert any(s.speed_mm_s > 0 for s in sps) and sps[-1].speed_mm_s == 0
    assert list(json.loads((out / "summary.json").read_text())) == list(SUMMARY_KEYS)
    info = json.loads((out / "run_info.json").read_text())
    assert info["lasers"][0]["kind"] == "replay" and info["laser_to_command"]["scans"] > 10
    assert "laser to command: median" in err.out
