"""Laser localisation in the host loop without surveyed posts: scan matching against a map built online (or
a saved one) with the wheel odometry as prior; the lost state (slow, then hold, with the reason) and the
re-localisation by the wide search."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _localisation_helpers import run_on_replayed_scans

from agnav_host.hostloop import SLOW_SHARE, HostLoop, SensorFrame
from agnav_host.localisation.occupancy import occupancy_from_scans, save_map
from agnav_host.localisation.scan_localiser import ScanLocaliser, scan_localiser_for
from agnav_host.localisation.scan_match import scan_points
from agnav_host.sim.runner import make_localiser, run_scenario
from agnav_host.sim.scenario import load_scenario
from agnav_host.types import DriveCommand, Goal, LaserScan, Pose2D


@pytest.fixture(scope="module")
def lab():
    return load_scenario("greenhouse_cycles")


def _err(a: Pose2D, b: Pose2D) -> float:
    return math.hypot(a.x_m - b.x_m, a.y_m - b.y_m)


def _drive(loc: ScanLocaliser, sc, poses, t0: float, odo_offset: Pose2D = Pose2D(), blank: bool = False,
           rng=None) -> float:
    """Feed odometry (the true pose in the odometry frame, shifted by ``odo_offset``) and a scan per pose, 15 Hz."""
    rng = rng or np.random.default_rng(0)
    t = t0
    for p in poses:
        odo = odo_offset.compose(Pose2D(p.x_m - sc.start.x_m, p.y_m - sc.start.y_m, p.yaw_rad))
        loc.odometry(odo.x_m, odo.y_m, odo.yaw_rad, t, 0.0, 0.0)
        s = sc.laser.scan(sc.world, p, t, rng)
        r = np.full_like(s.ranges_m, np.nan) if blank else s.ranges_m
        loc.scan(r, s.angles_rad, t, s.range_max_m)
        t += 1 / 15
    return t


def _line(x0: float, x1: float, y: float, n: int) -> list[Pose2D]:
    return [Pose2D(x, y, 0.0) for x in np.linspace(x0, x1, n)]


def test_a_sim_run_of_the_ten_cycle_lab_without_posts_stays_on_the_true_pose(lab):
    """The first 120 s of greenhouse_cycles (about two of its cycles) on drifting odometry and scan matching."""
    scan = run_scenario(lab, "him", 0, 120.0, localise="scan")
    odo = run_scenario(lab, "him", 0, 120.0, localise="odometry")
    believed, true = scan.believed
    assert scan.trajectory[-1, 7] >= 6  # it went round the benches more than once
    assert _err(believed, true) < 0.05
    assert abs(math.remainder(believed.yaw_rad - true.yaw_rad, 2 * math.pi)) < math.radians(2.0)
    b_odo, t_odo = odo.believed
    assert _err(b_odo, t_odo) > 0.2  # the odometry alone drifts off


def test_the_laser_blanked_makes_the_localiser_slow_then_lost_and_it_relocalises(lab):
    loc = ScanLocaliser(lab.start, lab.laser.mount)
    t = _drive(loc, lab, _line(1.0, 4.0, 1.0, 90), 0.0)
    assert loc.status()[0] == "ok" and _err(loc.pose_at(t - 1 / 15), Pose2D(4.0, 1.0)) < 0.05
    states = []
    # blanked for 5.5 m there and back: the odometry carries the pose, and it slips 0.3 m and 8 deg
    slip = Pose2D(0.3, -0.2, math.radians(8.0))
    for p in _line(4.0, 8.0, 1.0, 80) + _line(8.0, 6.5, 1.0, 30):
        t = _drive(loc, lab, [p], t, odo_offset=slip, blank=True)
        states.append(loc.status()[0])
    assert states[:20] == ["ok"] * 20 and "slow" in states and states[-1] == "lost"
    assert "laser returns" in loc.status()[1] and "odometry alone" in loc.status()[1]
    t = _drive(loc, lab, [Pose2D(6.5, 1.0, 0.0)] * 3, t, odo_offset=slip)
    assert loc.status()[0] == "ok" and loc.relocalised == 1
    assert _err(loc.pose_at(t - 1 / 15), Pose2D(6.5, 1.0)) < 0.05


def test_a_saved_map_localises_from_the_first_scan_and_is_not_extended(lab, tmp_path):
    rng = np.random.default_rng(1)
    poses = [Pose2D(x, y, yaw) for x in (2.0, 5.0, 8.0) for y in (1.0, 4.0, 7.0) for yaw in (0.0, math.pi)]
    pts, origins = [], []
    for p in poses:
        s = lab.laser.scan(lab.world, p, 0.0, rng)
        mount = np.array([lab.laser.mount.x_m, lab.laser.mount.y_m, lab.laser.mount.yaw_rad])
        pts.append(scan_points(s.ranges_m, s.angle_min_rad, s.angle_increment_rad, mount, max_range_m=s.range_max_m - 0.01))
        origins.append(mount[:2])
    grid = occupancy_from_scans(np.array([[p.x_m, p.y_m, p.yaw_rad] for p in poses]), pts, origins)
    yaml, _ = save_map(grid, tmp_path / "lab.yaml")
    # the start is 0.15 m and 3 deg off the truth: the saved map pulls the pose onto it
    start = Pose2D(lab.start.x_m + 0.15, lab.start.y_m - 0.1, math.radians(3.0))
    loc = scan_localiser_for(start, lab.laser.mount, str(yaml))
    size = loc.map_size
    t = 0.0
    for p in _line(1.0, 3.0, 1.0, 60):
        odo = Pose2D(p.x_m - 1.0, 0.0, 0.0)
        loc.odometry(odo.x_m, odo.y_m, odo.yaw_rad, t, 0.0, 0.0)
        s = lab.laser.scan(lab.world, p, t, rng)
        loc.scan(s.ranges_m, s.angles_rad, t, s.range_max_m)
        t += 1 / 15
    assert _err(loc.pose_at(t - 1 / 15), Pose2D(3.0, 1.0)) < 0.05
    assert loc.map_size == size


class _StubLocaliser:
    def __init__(self) -> None:
        self.state, self.why = "ok", ""

    def odometry(self, *a) -> None: ...

    def scan(self, *a, **k) -> int:
        return 0

    def pose_at(self, t_s: float) -> Pose2D:
        return Pose2D(1.0, 2.0, 0.0)

    def status(self) -> tuple[str, str]:
        return self.state, self.why

    sigma = (0.01, 0.02, 0.003)


class _Const:
    def reset(self) -> None: ...

    def step(self, obs):
        return DriveCommand(0.4, 0.2)


def test_the_host_loop_slows_then_holds_a_lost_robot_says_why_and_drives_on_when_relocalised():
    loc = _StubLocaliser()
    loop = HostLoop(_Const(), [Goal(10.0, 0.0)], laser_mount=Pose2D(), localiser=loc)

    def step(t: float):
        return loop.step(SensorFrame(t, Pose2D(), scan=LaserScan(-1.0, 0.01, np.full(201, 2.0), 10.0, t),
                                     goal_index=0))

    d = step(0.0)
    assert d.command == DriveCommand(0.4, 0.2) and d.pose_sigma == (0.01, 0.02, 0.003) and d.localisation == "ok"
    loc.state, loc.why = "slow", "scan match poor"
    d = step(0.1)
    assert d.command == DriveCommand(0.4 * SLOW_SHARE, 0.2 * SLOW_SHARE) and "slowing down" in d.event
    assert step(0.2).event == ""
    loc.state = "lost"
    d = step(0.3)
    assert d.command == DriveCommand() and d.hold.startswith("localisation lost")
    assert "scan match poor" in d.event and "holding" in d.event
    loc.state = "ok"
    d = step(0.4)
    assert d.command == DriveCommand(0.4, 0.2) and not d.hold and "recovered" in d.event


def test_unknown_or_impossible_localisers_are_refused(lab):
    with pytest.raises(ValueError, match="unknown localiser"):
        make_localiser(lab, "gps")
    with pytest.raises(ValueError, match="meta.landmarks"):
        make_localiser(lab, "posts")
    with pytest.raises(ValueError):
        make_localiser(lab, "scan", "/nonexistent/map.yaml")
    assert make_localiser(lab, "odometry") is None


def test_agnav_run_localises_on_scans_and_writes_the_pose_sigma(tmp_path, capsys):
    def wall(t: float) -> LaserScan:  # a wall 3 m ahead, seen over +-57 deg
        a = -1.0 + 0.01 * np.arange(201)
        return LaserScan(-1.0, 0.01, 3.0 / np.cos(a), 10.0, t)

    rc, rows = run_on_replayed_scans(tmp_path, wall, "TiM561", 0.2, "scan")
    assert rc == 0, capsys.readouterr()
    assert rows[0] == "t_s,state,sigma_x_m,sigma_y_m,sigma_yaw_rad" and len(rows) > 5
    assert all(r.split(",")[1] in ("ok", "slow", "lost") for r in rows[1:])


@pytest.mark.parametrize("extra, message", [(["--map", "/nonexistent/lab.yaml", "--localise", "scan"], "--map"),
                                            (["--localise", "posts"], "--landmarks"),
                                            (["--map", "x.yaml"], "--localise scan")])
def test_agnav_run_refuses_an_impossible_localiser_before_driving(extra, message, capsys):
    from agnav_host import cli

    rc = cli.main(["run", "--device", "/dev/null", "--laser", "replay:/nonexistent.alog", "--planner", "him",
                   "--goal", "1,0", *extra])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err


def test_a_curved_row_driven_once_drifts_less_than_half_a_percent_of_the_distance():
    """The 50 m curvy row (a hedge of overlapping bushes seen from one side, no revisit) on drifting odometry."""
    sc = load_scenario("curvy_row")
    run = run_scenario(sc, "proximity", 0, 200.0, localise="scan")
    believed, true = run.believed
    driven = float(np.hypot(*np.diff(run.trajectory[:, 1:3], axis=0).T).sum())
    assert run.end_reason == "arrived" and driven > 45.0
    assert _err(believed, true) < 0.005 * driven
    odo = run_scenario(sc, "proximity", 0, 200.0, localise="odometry")
    assert _err(*odo.believed) > 0.005 * driven  # the odometry alone does not


def test_a_saved_map_without_occupied_cells_is_refused(lab, tmp_path):
    from agnav_host.localisation.occupancy import MapFileError, OccupancyGrid

    grid = OccupancyGrid(np.zeros((20, 20), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    yaml, _ = save_map(grid, tmp_path / "empty.yaml")
    with pytest.raises(MapFileError, match="nothing to localise against"):
        scan_localiser_for(lab.start, lab.laser.mount, str(yaml))
