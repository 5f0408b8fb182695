"""Localisation on poles learnt online (``--localise poles``): pole detection in a scan, learning only what
stands still, the state when no pole is in sight, and a whole timed run in the simulator without the survey."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from _localisation_helpers import run_on_replayed_scans

from agnav_host.localisation.pole_slam import PoleSlam, PoleSlamParams, detect_poles
from agnav_host.sim.runner import make_localiser, run_scenario
from agnav_host.sim.scenario import load_scenario
from agnav_host.types import Pose2D


def _ray_circles(circles: list[tuple[float, float, float]], angles: np.ndarray, range_max: float = 4.0) -> np.ndarray:
    """Ranges from the origin to the nearest of ``circles`` (x, y, r) along each beam; NaN where none is hit."""
    out = np.full(len(angles), np.nan)
    for cx, cy, r in circles:
        ux, uy = np.cos(angles), np.sin(angles)
        b = ux * cx + uy * cy
        disc = b**2 - (cx**2 + cy**2 - r**2)
        hit = disc >= 0
        t = np.where(hit, b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        t = np.where((t > 0) & (t < range_max), t, np.inf)
        out = np.where(t < np.nan_to_num(out, nan=np.inf), t, out)
    return np.where(np.isfinite(out), out, np.nan)


ANGLES = np.radians(np.arange(-135.0, 135.5, 1.0))  # a TiM310's 1 deg beams


@pytest.mark.parametrize("d", [1.0, 2.0, 3.5])
def test_a_pole_is_found_at_its_centre_and_radius_at_any_range(d):
    seen = detect_poles(_ray_circles([(d, 0.3, 0.08)], ANGLES), ANGLES, 4.0)
    assert len(seen) == 1
    s = seen[0]
    cx, cy = s.range_m * math.cos(s.bearing_rad), s.range_m * math.sin(s.bearing_rad)
    assert math.hypot(cx - d, cy - 0.3) < 0.015 and abs(s.radius_m - 0.08) < 0.02


def test_a_wall_a_crate_and_a_pole_against_a_wall_are_not_poles():
    a = ANGLES
    wall = np.where(np.abs(a) < np.radians(60), 2.0 / np.cos(a), np.nan)  # a wall 2 m ahead
    assert detect_poles(wall, a, 4.0) == []
    crate = _ray_circles([(2.0, 0.0, 0.3)], a)  # 0.6 m across
    assert detect_poles(crate, a, 4.0) == []
    leaning = np.fmin(np.nan_to_num(_ray_circles([(1.9, 0.0, 0.08)], a), nan=np.inf), np.nan_to_num(wall, nan=np.inf))
    assert detect_poles(np.where(np.isfinite(leaning), leaning, np.nan), a, 4.0) == []  # 0.1 m in front of the wall


def test_a_barrel_narrower_than_the_width_bound_is_no_pole():
    """A 0.34 m barrel at 2 m spans under max_width_m between its edge returns, but its radius comes out above
    the largest pole's: no sighting (a centre fitted with a clamped radius would stand in front of the barrel's)."""
    barrel = _ray_circles([(2.0, 0.3, 0.17)], ANGLES)
    p = PoleSlamParams()
    hit = np.flatnonzero(np.isfinite(barrel))
    ends = [(barrel[i] * math.cos(ANGLES[i]), barrel[i] * math.sin(ANGLES[i])) for i in (hit[0], hit[-1])]
    assert math.dist(*ends) <= p.max_width_m
    assert detect_poles(barrel, ANGLES, 4.0, p) == []
    assert len(detect_poles(_ray_circles([(2.0, 0.3, 0.12)], ANGLES), ANGLES, 4.0, p)) == 1  # a 0.24 m trunk is one


def test_a_far_sighting_of_few_returns_is_fitted_with_the_learnt_radius():
    """A pole learnt close by keeps the mean radius of its sightings; seen again far off by two beams
    (its scan radius then a beam's width at that range) it is fitted with that radius, which takes the radius's
    share out of its range error (what is left: two returns stand behind the pole's front)."""
    loc = PoleSlam(Pose2D())
    _drive(loc, lambda t: [(2.5, 0.4, 0.05)], 40)  # 1.3 m towards a 10 cm pole: learnt, radius from many returns
    assert len(loc.poles) == 1 and abs(float(loc.poles[0, 2]) - 0.05) < 0.005
    b = math.radians(0.5)  # half-way between two beams: the pole (1.5 beams wide at 3.9 m) is hit by two
    far = detect_poles(_ray_circles([(3.9 * math.cos(b), 3.9 * math.sin(b), 0.05)], ANGLES), ANGLES, 4.0)
    assert len(far) == 1 and far[0].returns == 2
    own, fitted = far[0], far[0].with_radius(float(loc.poles[0, 2]))
    assert own.radius_m > 0.065 and own.range_m - 3.9 > 0.025  # a beam's width at 3.9 m: 3 cm too far
    assert abs(fitted.range_m - 3.9) < 0.6 * (own.range_m - 3.9) and abs(fitted.bearing_rad - b) < math.radians(0.2)
    # in the localiser: backing away from the pole to 3.9 m on exact odometry, the pose stays nearer the truth than
    # with every sighting taken at its own radius
    errs = []
    for params in (PoleSlamParams(), PoleSlamParams(radius_min_sightings=10**6)):
        loc = PoleSlam(Pose2D(), params=params)
        t = _drive(loc, lambda t: [(2.5, 0.4, 0.05)], 40)
        x = 0.5 * t
        for _ in range(78):  # 2.6 m back: the pole from 1.3 m to 3.9 m off
            x -= 0.5 / 15
            t += 1 / 15
            loc.odometry(x, 0.0, 0.0, t, -0.5, 0.0)
            loc.scan(_ray_circles([(2.5 - x, 0.4, 0.05)], ANGLES), ANGLES, t, 4.0)
        errs.append(abs(loc.pose_at(t).x_m - x))
    assert errs[0] < 0.8 * errs[1]  # 9 mm against 12 mm


def _drive(loc: PoleSlam, poles_at, n: int, speed: float = 0.5, t0: float = 0.0) -> float:
    """Drive along x at ``speed`` from x = speed * t0, 15 Hz: odometry exact, a scan of ``poles_at(t)``
    (circles in the world) from the true pose."""
    t = t0
    for _ in range(n):
        x = speed * t
        loc.odometry(x, 0.0, 0.0, t, speed, 0.0)
        rel = [(cx - x, cy, r) for cx, cy, r in poles_at(t)]
        loc.scan(_ray_circles(rel, ANGLES), ANGLES, t, 4.0)
        t += 1 / 15
    return t


def test_poles_that_stand_still_are_learnt_and_a_walker_is_not():
    loc = PoleSlam(Pose2D())
    still = [(2.0, 1.0, 0.08), (3.0, -1.2, 0.08)]
    _drive(loc, lambda t: still + [(1.5 + 0.6 * t, -0.6, 0.1)], 30)  # a walker going the same way
    learnt = loc.poles
    assert len(learnt) == 2
    for x, y, _ in still:
        assert np.min(np.hypot(learnt[:, 0] - x, learnt[:, 1] - y)) < 0.03
    assert loc.status()[0] == "ok" and loc.sighted > 0


def test_no_pole_in_sight_slows_then_loses_the_robot_and_a_known_pole_brings_it_back():
    loc = PoleSlam(Pose2D(), params=PoleSlamParams(slow_after_m=1.0, lost_after_m=2.0))
    pole = [(1.5, 1.0, 0.08)]
    t = _drive(loc, lambda t: pole, 20)  # 0.67 m with the pole in sight: learnt
    assert len(loc.poles) == 1 and loc.status()[0] == "ok"
    states = []
    for _ in range(90):  # 3 m more with the laser blind
        x = 0.5 * t
        loc.odometry(x, 0.0, 0.0, t, 0.5, 0.0)
        loc.scan(np.full(len(ANGLES), np.nan), ANGLES, t, 4.0)
        states.append(loc.status()[0])
        t += 1 / 15
    assert "slow" in states and states[-1] == "lost" and "without a pole" in loc.status()[1]
    # back where the pole is in sight (the odometry drove back): the first match ends the lost state
    loc.odometry(0.5, 0.0, 0.0, t, 0.0, 0.0)
    loc.scan(_ray_circles([(1.0, 1.0, 0.08)], ANGLES), ANGLES, t, 4.0)
    assert loc.status()[0] == "ok" and len(loc.poles) == 1


def test_a_timed_run_without_the_survey_learns_the_posts_and_ends_on_the_true_pose():
    """timed_static in the simulator on drifting odometry, localised on the posts it learns as it drives; the
    surveyed positions (meta.landmarks) are used only to check what it learnt."""
    sc = load_scenario("timed_static")
    locs = []

    import agnav_host.sim.runner as runner

    make = runner.make_localiser

    def keep(*a, **k):  # type: ignore[no-untyped-def]
        loc = make(*a, **k)
        locs.append(loc)
        return loc

    runner.make_localiser = keep
    try:
        run = run_scenario(sc, "timed", 0, localise="poles")
    finally:
        runner.make_localiser = make
    believed, true = run.believed
    assert run.end_reason == "arrived"
    assert math.hypot(believed.x_m - true.x_m, believed.y_m - true.y_m) < 0.05
    survey = np.asarray(sc.meta["landmarks"])[:, :2]
    learnt = locs[0].poles
    near = [float(np.min(np.hypot(survey[:, 0] - x, survey[:, 1] - y))) for x, y, _ in learnt]
    assert sum(d < 0.05 for d in near) >= 6  # most posts beside the route, each within 5 cm
    odo = run_scenario(sc, "timed", 0, localise="odometry")
    b, p = odo.believed
    assert math.hypot(b.x_m - p.x_m, b.y_m - p.y_m) > 0.05  # the odometry alone does not


def test_the_poles_localiser_is_picked_by_name_and_on_the_command_line(tmp_path, capsys):
    from agnav_host import cli

    sc = load_scenario("timed_static")
    assert isinstance(make_localiser(sc, "poles"), PoleSlam)
    out = tmp_path / "run"
    assert cli.main(["sim", "timed_static", "--planner", "timed", "--localise", "poles", "--no-plot",
                     "--out", str(out)]) == 0
    assert json.loads((out / "run_info.json").read_text())["end_reason"] == "arrived"
    assert "localisation (poles)" in capsys.readouterr().out


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="gate_m"):
        PoleSlamParams(gate_m=0.0)
    with pytest.raises(ValueError, match="radius_m"):
        PoleSlamParams(radius_m=(0.2, 0.1))


def test_agnav_run_refuses_poles_without_a_laser_before_driving(capsys):
    from agnav_host import cli

    rc = cli.main(["run", "--device", "/dev/null", "--planner", "him", "--goal", "1,0", "--localise", "poles"])
    err = capsys.readouterr().err
    assert rc == 2 and "needs" in err and "laser" in err and "Traceback" not in err


def test_a_straight_wall_is_found_as_a_line_and_a_row_of_poles_is_not_one():
    from agnav_host.localisation.pole_slam import detect_walls

    a = ANGLES
    rng = np.random.default_rng(3)
    wall = np.where(np.abs(a - 0.3) < np.radians(40), 2.0 / np.cos(a - 0.3), np.nan) + rng.normal(0, 0.01, len(a))
    seen = detect_walls(wall, a, 4.0)
    assert len(seen) == 1
    assert abs(seen[0].rho_m - 2.0) < 0.01 and abs(math.remainder(seen[0].alpha_rad - 0.3, 2 * math.pi)) < math.radians(0.5)
    fence = _ray_circles([(2.0, y, 0.05) for y in np.arange(-1.5, 1.6, 0.4)], a)
    assert detect_walls(fence, a, 4.0) == []


def test_a_wall_beside_the_route_is_learnt_and_holds_the_distance_to_it():
    """No pole at all: a wall 1.5 m to the left of a straight drive; the odometry creeps 2 cm to the left per
    metre that the robot does not."""
    loc = PoleSlam(Pose2D())
    a = ANGLES
    t = 0.0
    for _ in range(180):  # 6 m at 0.5 m/s
        x = 0.5 * t
        loc.odometry(x, 0.02 * x, 0.0, t, 0.5, 0.0)
        r = np.where((a > 0.2) & (a < math.pi - 0.2), 1.5 / np.maximum(np.sin(a), 1e-9), np.nan)  # from (x, 0, 0)
        loc.scan(np.where(r < 4.0, r, np.nan), a, t, 4.0)
        t += 1 / 15
    assert len(loc.walls) == 1 and len(loc.poles) == 0
    assert abs(loc.pose_at(t - 1 / 15).y_m) < 0.06  # half the odometry's 0.12 m


def test_agnav_run_localises_on_poles_and_writes_the_pose_sigma(tmp_path, capsys):
    from agnav_host.types import LaserScan

    def yard(t: float) -> LaserScan:  # two poles ahead, seen by a 1 deg laser
        return LaserScan(float(ANGLES[0]), float(ANGLES[1] - ANGLES[0]),
                         _ray_circles([(2.5, 0.8, 0.08), (3.0, -0.9, 0.08)], ANGLES), 4.0, t)

    rc, rows = run_on_replayed_scans(tmp_path, yard, "TiM310", 0.0, "poles")
    assert rc == 0, capsys.readouterr()
    assert rows[0] == "t_s,state,sigma_x_m,sigma_y_m,sigma_yaw_rad" and len(rows) > 5
    assert all(r.split(",")[1] == "ok" for r in rows[1:])
