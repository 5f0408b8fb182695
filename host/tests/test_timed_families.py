"""Path families of the timed planner: Dubins, continuous-curvature (clothoid) and Reeds-Shepp paths
reach every pose the car can reach within its steering limit, each timed to the requested arrival,
and the earliest arrival over them is the car's minimum time (checked against a brute-force search)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agnav_host import cli
from agnav_host.planning.timed import BoundaryState, TimedLimits, plan_timed, resolve
from agnav_host.planning.timed._candidates import dubins_candidate, geo_from_family, sharpness_for
from agnav_host.planning.timed._families import (Seg, cc_paths, dubins_paths, reeds_shepp_paths, sample_segments, seg_end,
                                                 shortest_dubins_m)

LIM = TimedLimits()
KMAX = LIM.plan_kappa_max


def _goals(n: int, seed: int, radius_m: float = 6.0) -> list[tuple[float, float, float]]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        r = radius_m * math.sqrt(rng.uniform(0.0025, 1.0))
        b = rng.uniform(-math.pi, math.pi)
        out.append((r * math.cos(b), r * math.sin(b), rng.uniform(-math.pi, math.pi)))
    return out


def _end(fp) -> tuple[float, float, float]:
    x, y, th = fp.start
    for g in fp.segs:
        x, y, th = seg_end(x, y, th, g, 16)
    return x, y, th


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@pytest.mark.parametrize("family", ["dubins", "clothoid", "reeds-shepp"])
def test_every_family_path_ends_on_its_goal_within_the_steering_limit(family):
    sigma = sharpness_for(LIM, LIM.v_max_m_s)
    for g in _goals(150, 11):
        s = (0.3, -0.2, 0.4)
        if family == "dubins":
            paths = dubins_paths(s, g, KMAX)
        elif family == "clothoid":
            paths = cc_paths(s, g, KMAX, sigma)
        else:
            paths = reeds_shepp_paths(s, g, KMAX)
        if family != "reeds-shepp":
            assert paths, f"no {family} path to {g}"
        for fp in paths:
            x, y, th = _end(fp)
            assert math.hypot(x - g[0], y - g[1]) < 1e-6 and abs(_wrap(th - g[2])) < 1e-6, (fp.word, g)
            xy, yaw, kappa, sarc, _ = sample_segments(fp.start, fp.segs)
            assert np.hypot(*(xy[-1] - g[:2])) < 1e-6, "the sampled path ends on the goal too"
            assert np.abs(kappa).max() <= KMAX * (1 + 1e-9)
            if family == "clothoid":  # continuous curvature, never sharper than the servo's rate allows
                dk = np.abs(np.diff(kappa)) / np.maximum(np.diff(sarc), 1e-12)
                assert dk.max() <= sigma * (1 + 1e-6), fp.word
            if family != "reeds-shepp":
                assert fp.reverse_m == 0.0


def test_the_goals_of_the_report_are_planned_not_refused():
    """A goal 2.8 m ahead facing back and one beside the car facing across need more steering than the
    polynomial has for the distance; the families drive them at the shortest-path length / 0.8 m/s + 3 s."""
    for g in [(2.8, 0.0, math.pi), (0.0, 1.0, math.pi / 2), (0.0, -0.6, -math.pi / 2), (0.5, 0.5, math.pi)]:
        L = shortest_dubins_m((0.0, 0.0, 0.0), g, KMAX)
        p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(*g), 0.0, L / 0.8 + 3.0, LIM)
        assert p.feasible, (g, p.reason)
        assert p.max_steering_rad <= LIM.plan_steer_rad + 1e-9
        assert p.path.kind.split(" ")[0] in ("clothoid", "polynomial") and p.path.reverse_m == 0.0
        assert p.arrival_s == pytest.approx(L / 0.8 + 3.0, abs=1e-6)
        x, y, yaw, _ = p.path.sample(p.path.length_m)
        assert math.hypot(float(x) - g[0], float(y) - g[1]) < 1e-6 and abs(_wrap(float(yaw) - g[2])) < 1e-6


def _numeric_min_time_s(fp, cap_m_s: float, lim: TimedLimits, ds: float = 0.01) -> float:
    """Minimum time over a path on a 1 cm grid, the car model written out independently of the planner:
    from rest, |a| <= accel, v <= v_max everywhere and v <= the steering-rate cap on the clothoids only,
    into the stop (v_min over the creep, then the speed controller's lag stop; arrival within 5 cm)."""
    A, vmin = lim.accel_m_s2, lim.v_min_m_s
    S = fp.length_m
    d_tail = vmin * lim.stop_lag_s
    d_creep = min(lim.creep_m, max(0.0, S - 3.0 * d_tail))
    Sm = S - d_tail - d_creep
    n = max(2, int(math.ceil(Sm / ds)))
    s = np.linspace(0.0, Sm, n + 1)
    h = Sm / n
    cap = np.full(n + 1, lim.v_max_m_s)
    acc = 0.0
    for g in fp.segs:
        if g.sigma != 0.0:
            cap[(s >= acc - 1e-12) & (s <= acc + g.length_m + 1e-12)] = min(cap_m_s, lim.v_max_m_s)
        acc += g.length_m
    v = np.empty(n + 1)
    v[0] = 0.0
    for i in range(n):
        v[i + 1] = min(cap[i + 1], math.sqrt(v[i] ** 2 + 2.0 * A * h))
    if v[n] < vmin - 1e-9:
        return math.inf
    v[n] = vmin
    for i in range(n - 1, -1, -1):
        v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2.0 * A * h))
    a_stop = vmin / (2.0 * lim.stop_lag_s)
    settle = math.sqrt(2.0 * min(lim.arrive_tol_m, d_tail) / a_stop)
    return float(np.sum(2.0 * h / (v[:-1] + v[1:]))) + d_creep / vmin + 2.0 * lim.stop_lag_s - settle


def test_earliest_arrival_is_within_two_percent_of_a_brute_force_search():
    """Brute force: every continuous-curvature word at 25 sharpnesses (top speeds 0.44-2 m/s), each timed
    on a 1 cm grid with the steering-rate cap on its clothoids only. The planner's earliest arrival is
    within 2 % of the best of those, and never below the physical bound (the shortest path driven at the
    acceleration and speed limits)."""
    ratios = []
    for g in _goals(10, 5):
        early = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(*g), 0.0, 0.01, LIM)
        assert not early.feasible and early.earliest_arrival_s is not None
        best = math.inf
        for cap in np.linspace(LIM.v_min_m_s + 0.005, LIM.v_max_m_s, 25):
            for fp in cc_paths((0.0, 0.0, 0.0), g, KMAX, sharpness_for(LIM, float(cap))):
                best = min(best, _numeric_min_time_s(fp, float(cap), LIM))
        ratios.append(early.earliest_arrival_s / best)
        L = shortest_dubins_m((0.0, 0.0, 0.0), g, KMAX)
        a, v = LIM.accel_m_s2, LIM.v_max_m_s
        bound = L / v + v / a if L >= v * v / a else 2.0 * math.sqrt(L / a)
        assert early.earliest_arrival_s >= bound
        again = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(*g), 0.0, early.earliest_arrival_s + 1e-3, LIM)
        assert again.feasible, again.reason
    assert max(ratios) <= 1.02, ratios
    assert min(ratios) >= 0.98, ratios


def test_a_dubins_plan_stops_at_each_curvature_jump_and_turns_its_wheels_there():
    start, goal = BoundaryState(0.0, 0.0, 0.0), BoundaryState(3.0, 2.5, math.pi)
    geo = dubins_candidate(start, goal, LIM, 0.2)
    assert geo is not None and geo.kind.startswith("dubins") and geo.stops
    p = plan_timed(start, goal, 0.0, 20.0, LIM, path=geo)
    assert p.feasible, p.reason
    t = np.linspace(0.0, p.profile.duration_s, 40001)
    s, v = p.profile.eval(t)
    for s_stop, turn_s in geo.stops:
        rest = (np.abs(s - s_stop) < 1e-6) & (v <= 1e-9)  # at rest on the joint ...
        assert rest.any() and t[rest].max() - t[rest].min() >= turn_s - 1e-3, "... long enough to turn the wheels"
    assert p.profile.max_speed_m_s <= LIM.v_max_m_s + 1e-9


def test_reverse_paths_only_where_the_calibration_has_a_reverse_side():
    goal = BoundaryState(-1.5, 0.6, 0.0)
    fwd = plan_timed(BoundaryState(0.0, 0.0, 0.0), goal, 0.0, 12.0, LIM)
    assert fwd.feasible and fwd.path.reverse_m == 0.0
    rev_lim = TimedLimits(reverse_v_max_m_s=0.8)
    rev = plan_timed(BoundaryState(0.0, 0.0, 0.0), goal, 0.0, 12.0, rev_lim)
    assert rev.feasible, rev.reason
    assert rev.path.kind.startswith("reeds-shepp") and rev.path.reverse_m > 0.5
    assert rev.path.length_m * 1.5 < fwd.path.length_m
    assert rev.summary()["reverse_m"] == pytest.approx(rev.path.reverse_m, abs=1e-3)
    # at rest at every cusp; no faster than the reverse side allows while reversing
    t = np.linspace(0.0, rev.profile.duration_s, 20001)
    s, v = rev.profile.eval(t)
    d = np.interp(s, rev.path.s, rev.path.direction)
    assert v[d < -0.5].max() <= 0.8 + 1e-9
    for s_stop, _ in rev.path.stops:
        assert ((np.abs(s - s_stop) < 1e-6) & (v <= 1e-9)).any(), "at rest on the cusp"
    x, y, yaw, _ = rev.path.sample(rev.path.length_m)
    assert math.hypot(float(x) + 1.5, float(y) - 0.6) < 1e-6 and abs(_wrap(float(yaw))) < 1e-6


def test_reverse_side_of_a_speed_table():
    from types import SimpleNamespace

    from agnav_host.calib import default_speed_table

    assert TimedLimits().with_reverse_from(default_speed_table()).reverse_v_max_m_s == 0.0  # the ref-003 car
    table = SimpleNamespace(neg_value=(0.45, 0.9, 1.2), value_max=2.0)  # a speed controller with a reverse side
    assert TimedLimits().with_reverse_from(table).reverse_v_max_m_s == pytest.approx(1.2)


def test_a_steering_angle_at_the_start_is_wound_out_without_a_jump():
    k0 = math.tan(math.radians(12.0)) / LIM.wheelbase_m
    p = plan_timed(BoundaryState(0.0, 0.0, 0.0, math.radians(12.0), 0.8), BoundaryState(1.0, -1.2, -math.pi / 2), 0.0, 8.0, LIM,
                   auto_via=False)
    assert p.feasible and p.path.kind.startswith("clothoid"), p.reason
    assert p.path.kappa[0] == pytest.approx(k0)
    sigma = sharpness_for(LIM, p.path.speed_cap_m_s)  # the sharpness the plan's top speed allows
    assert np.max(np.abs(np.diff(p.path.kappa)) / np.diff(p.path.s)) <= sigma * (1 + 1e-6)
    assert p.profile.max_speed_m_s <= p.path.speed_cap_m_s + 1e-9


def test_deviation_and_catch_up_use_the_families():
    """A deviation point the polynomial cannot reach within the steering limit gets a continuous-curvature leg."""
    start, goal = BoundaryState(0.0, 0.0, 0.0, 0.0, 0.8), BoundaryState(8.0, 0.0, 0.0)
    res = resolve(start, goal, 0.0, 14.0, LIM, (), [], np.zeros((0, 2)), extra_vias_xy=[("sharp", (1.2, 1.3))],
                  try_yield=False, try_base=False)
    assert res.plan is not None and res.action == "sharp", res.action
    assert "clothoid" in res.plan.path.kind and res.plan.feasible
    assert res.plan.max_steering_rad <= LIM.plan_steer_rad + 1e-9
    # a catch-up from off the route, facing back: no polynomial fits, a clothoid path without a loop does
    late = plan_timed(BoundaryState(5.0, 2.0, math.radians(-150), 0.0, 0.6), goal, 0.0, 8.0, LIM, auto_via=False)
    assert late.feasible and late.path.kind.startswith("clothoid"), late.reason


def test_a_forward_path_to_every_random_goal_at_the_slack_time():
    for g in _goals(60, 23):
        L = shortest_dubins_m((0.0, 0.0, 0.0), g, KMAX)
        p = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(*g), 0.0, L / 0.8 + 3.0, LIM)
        assert p.feasible, (g, p.reason)
        assert p.path.reverse_m == 0.0


def test_geo_from_family_keeps_the_cusps_as_stops():
    seg = (Seg(0.5, 0.0), Seg(0.4, 0.0, 0.0, -1))
    geo = geo_from_family(type("F", (), {"start": (0.0, 0.0, 0.0), "segs": seg, "word": "S+S-", "family": "reeds-shepp"})(),
                          TimedLimits(reverse_v_max_m_s=1.0), math.inf)
    assert geo.stops == ((0.5, 0.0),) and geo.reverse_m == pytest.approx(0.4)


def test_plan_cli_path_type_and_reverse_length(capsys):
    rc = cli.main(["plan", "--start", "0,0,0", "--goal", "2.8,0,180", "--arrive-in", "8", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["feasible"] is True
    assert out["path_type"].startswith("clothoid") and out["reverse_m"] == 0.0 and out["max_steering_deg"] <= 17.0
    rc = cli.main(["plan", "--start", "0,0,0", "--goal", "-2,0,0", "--arrive-in", "6", "--reverse-speed", "1", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["path_type"].startswith("reeds-shepp") and out["reverse_m"] == pytest.approx(2.0, abs=1e-3)


def test_plan_cli_refuses_a_goal_no_path_reaches_with_exit_2(capsys):
    rc = cli.main(["plan", "--start", "1,2,30", "--goal", "1,2,30", "--arrive-in", "8"])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot be reached" in err and "Traceback" not in err
    # the same position facing the other way is a loop, not a refusal
    assert cli.main(["plan", "--start", "1,2,30", "--goal", "1,2,210", "--arrive-in", "12"]) == 0
    assert cli.main(["plan", "--start", "0,0,0", "--goal", "1,1,0", "--reverse-speed", "0.2"]) == 2  # below the band
