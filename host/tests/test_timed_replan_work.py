"""The work a replanning call does: the shortcuts that make it cheap give the same answers as the
long way round, and leave out the work they say they leave out."""

from __future__ import annotations

import math
import types

import numpy as np
import pytest

from agnav_host.planning.timed import BoundaryState, TimedLimits
from agnav_host.planning.timed import _candidates as C
from agnav_host.planning.timed import _families as F
from agnav_host.planning.timed import _path as P
from agnav_host.planning.timed._obstacles import first_blocked_s, path_prefix_blocked
from agnav_host.planning.timed._plan import plan_timed, via_state

LIM = TimedLimits()
KMAX = C._kmax(LIM)


def _newton_16(word: str, gx: float, gy: float, gth: float, kmax: float, sigma: float,
               guesses: tuple[float, ...]) -> tuple[float, float, float] | None:
    """The plain Newton solve: 16 full steps from every guess, no early exits."""
    a, b = (1 if word[0] == "L" else -1), (1 if word[2] == "L" else -1)
    for g in guesses:
        d1 = min(max(g, 0.0), F.TWO_PI - 1e-9)
        for _ in range(16):
            f, ell, d2 = F._csc_residual(d1, a, b, gx, gy, gth, kmax, sigma)
            if abs(f) < 1e-10:
                break
            f2, _, _ = F._csc_residual(d1 + 1e-7, a, b, gx, gy, gth, kmax, sigma)
            df = (f2 - f) / 1e-7
            if df == 0.0 or not math.isfinite(df):
                break
            d1 = min(max(d1 - max(-0.5, min(0.5, f / df)), 0.0), F.TWO_PI - 1e-9)
        f, ell, d2 = F._csc_residual(d1, a, b, gx, gy, gth, kmax, sigma)
        if abs(f) < 1e-8 and ell >= -1e-9:
            return d1, max(ell, 0.0), d2
    return None


def _problems(n: int, seed: int) -> list[tuple[str, float, float, float, float]]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        r = rng.uniform(0.2, 3.0)
        b = rng.uniform(-math.pi, math.pi)
        sigma = C.sharpness_for(LIM, float(rng.choice([2.0, 1.0, 0.6, 0.45])))
        out.append((str(rng.choice(F.CSC_WORDS)), r * math.cos(b), r * math.sin(b), float(rng.uniform(-math.pi, math.pi)), sigma))
    return out


def test_newton_finds_every_root_the_sixteen_step_solve_finds():
    found = 0
    for word, gx, gy, gth, sigma in _problems(600, 1):
        sol = F._csc_closed(word, gx, gy, gth, KMAX, sigma)
        guesses = ((sol[0],) if sol is not None else ()) + (1e-3, math.pi)
        ref = _newton_16(word, gx, gy, gth, KMAX, sigma, guesses)
        got = F._csc_numeric(word, gx, gy, gth, KMAX, sigma, guesses)
        assert (got is None) == (ref is None), (word, gx, gy, gth, sigma)
        if ref is not None:
            found += 1
            assert got == pytest.approx(ref, abs=1e-9)
    assert found > 300  # most problems have a root: the comparison is not empty


def test_newton_gives_up_early_on_a_word_without_a_root(monkeypatch):
    # the first random problem where no guess converges (Newton bounces round a minimum of |cross| above 0)
    args = next((w, gx, gy, gth, KMAX, sg, (1e-3, math.pi)) for w, gx, gy, gth, sg in _problems(600, 2)
                if F._csc_closed(w, gx, gy, gth, KMAX, sg) is None and _newton_16(w, gx, gy, gth, KMAX, sg, (1e-3, math.pi)) is None)
    calls = {"n": 0}
    make = F._csc_residual_fn

    def counting(*a: object) -> object:
        resid = make(*a)  # type: ignore[arg-type]

        def r(d1: float) -> tuple[float, float, float]:
            calls["n"] += 1
            return resid(d1)
        return r
    monkeypatch.setattr(F, "_csc_residual_fn", counting)
    assert F._csc_numeric(*args) is None
    # the sixteen-step solve evaluates the residual up to 33 times per guess
    assert calls["n"] <= 2 * (2 * (F.NEWTON_STALL_STEPS + 3) + 1)


def test_words_that_must_loop_are_left_out_with_the_same_paths_kept(monkeypatch):
    limit = C.NO_LOOP_TURN_RAD
    solved: list[str] = []
    words = F._words

    def recording(start, goal, kmax, sigma, family, ws=F.ALL_WORDS):  # type: ignore[no-untyped-def]
        if family == "clothoid":
            solved.extend(ws)
        return words(start, goal, kmax, sigma, family, ws)
    monkeypatch.setattr(F, "_words", recording)
    rng = np.random.default_rng(3)
    left_out = 0
    for _ in range(300):
        goal = (float(rng.uniform(-2, 3)), float(rng.uniform(-2, 2)), float(rng.uniform(-math.pi, math.pi)))
        sigma = C.sharpness_for(LIM, float(rng.choice([2.0, 1.0, 0.6])))
        solved.clear()
        every = [p for p in F.cc_paths((0.0, 0.0, 0.0), goal, KMAX, sigma, C.PRUNE_M, F.CSC_WORDS)
                 if F.turning_rad(p) <= limit]
        n_every = len(solved)
        solved.clear()
        fast = [p for p in F.cc_paths((0.0, 0.0, 0.0), goal, KMAX, sigma, C.PRUNE_M, F.CSC_WORDS, max_turn_rad=limit)
                if F.turning_rad(p) <= limit]
        assert [(p.word, p.segs) for p in fast] == [(p.word, p.segs) for p in every]
        left_out += n_every - len(solved)
    assert left_out > 50  # the looping LSL / RSR words were not solved for paths


def test_the_shape_of_a_leg_bounds_its_sampled_peak_curvature():
    rng = np.random.default_rng(5)
    n = 0
    ratios: list[float] = []
    for _ in range(300):
        a = BoundaryState(0.0, 0.0, float(rng.uniform(-1.2, 1.2)), float(rng.uniform(-0.3, 0.3)))
        b = BoundaryState(float(rng.uniform(0.3, 4.0)), float(rng.uniform(-2.0, 2.0)), float(rng.uniform(-1.5, 1.5)))
        try:
            floor = P.leg_kappa_floor(a, b, LIM.wheelbase_m)
        except ValueError:
            with pytest.raises(ValueError):
                P.build_path([a, b], LIM.wheelbase_m)
            continue
        peak = P.build_path([a, b], LIM.wheelbase_m).max_abs_kappa
        assert floor <= peak * (1.0 + 1e-12)
        ratios.append(floor / peak)
        n += 1
    assert n > 200
    assert np.median(ratios) > 0.9  # the 21 samples at u = k/20 see most of the peak, as a bound it is useful


def test_a_leg_refused_on_its_shape_is_never_sampled(monkeypatch):
    # 1 m ahead and 1 m to the side with the heading unchanged: the polynomial needs far more than 17 deg
    a, b = BoundaryState(0.0, 0.0, 0.0), BoundaryState(1.0, 1.0, 0.0)
    path, why = C.poly_candidate([a, b], LIM)
    assert path is None and "steering" in why
    monkeypatch.setattr(P, "_build_leg", lambda *args: pytest.fail("sampled"))
    P._LEGS.clear()
    assert C.poly_candidate([a, b], LIM, quick=True)[0] is None


def test_first_blocked_s_is_the_same_with_and_without_the_prefilter(monkeypatch):
    plan = plan_timed(BoundaryState(0.0, 0.0, 0.0), BoundaryState(4.0, 0.5, 0.0), 0.0, 10.0, LIM)
    rng = np.random.default_rng(7)
    for _ in range(40):
        pts = np.column_stack((rng.uniform(-0.5, 4.5, 60), rng.uniform(-1.0, 1.5, 60)))
        res = []
        for direct in (0, 1000):
            monkeypatch.setattr("agnav_host.planning.timed._obstacles._DIRECT_POINTS", direct)
            res.append(first_blocked_s(plan, pts, 0.3, 3.5, 0.05))
        a, b = res
        assert (a is None) == (b is None)
        if a is not None:
            assert a[0] == b[0] and np.array_equal(a[1], b[1])


def test_a_deviation_whose_first_leg_is_blocked_is_not_built_further(monkeypatch):
    start = BoundaryState(0.0, 0.0, 0.0, 0.0, 0.8)
    goal = BoundaryState(5.0, 0.0, 0.0)
    via = via_state((0.0, 0.0), (2.0, 0.6), (5.0, 0.0))
    first_leg = C.via_candidate([start, via], LIM, LIM.v_max_m_s)
    assert first_leg is not None
    xy = first_leg.xy[len(first_leg.s) // 2]
    pts = np.array([[xy[0], xy[1]]])  # a return on the first leg
    whole = C.via_candidate([start, via, goal], LIM, LIM.v_max_m_s)
    assert whole is not None
    shim = types.SimpleNamespace(path=whole, limits=LIM)
    assert first_blocked_s(shim, pts, 0.0, 4.5, 0.08) is not None  # the whole path is blocked too
    legs_built: list[tuple[float, float]] = []
    shape = P._leg_shape

    def recording(a: BoundaryState, b: BoundaryState, wb: float) -> object:
        legs_built.append((b.x_m, b.y_m))
        return shape(a, b, wb)
    monkeypatch.setattr(P, "_leg_shape", recording)
    P._SHAPES.clear()
    P._LEGS.clear()
    out = C.via_candidate([start, via, goal], LIM, LIM.v_max_m_s,
                          lambda g: path_prefix_blocked(g, LIM, pts, 4.5, 0.08))
    assert out is None
    assert (goal.x_m, goal.y_m) not in legs_built  # the leg into the goal was never built


def test_a_path_through_via_points_is_no_faster_than_its_slowest_leg(monkeypatch):
    """The speed cap of a path through via points is the lowest cap of its legs, whichever leg needs the
    sharper (slower) clothoids."""
    rng = np.random.default_rng(7)
    poly, cc = C.poly_candidate, C.cc_candidate
    mixed = 0
    for _ in range(60):
        start = BoundaryState(0.0, 0.0, 0.0, 0.0, 0.8)
        vx, vy = rng.uniform(0.6, 3.0), rng.uniform(-1.5, 1.5)
        gx, gy = vx + rng.uniform(0.5, 3.0), rng.uniform(-1.5, 1.5)
        via = via_state((0.0, 0.0), (vx, vy), (gx, gy))
        goal = BoundaryState(gx, gy, float(rng.uniform(-math.pi, math.pi)))
        legs: list[float] = []
        whole_poly: list[bool] = []

        def rec_poly(states, lim, quick=False, legs=legs, whole_poly=whole_poly):
            out = poly(states, lim, quick=quick)
            if len(states) == 2 and out[0] is not None:
                legs.append(out[0].speed_cap_m_s)
            elif len(states) > 2 and out[0] is not None:
                whole_poly.append(True)
            return out

        def rec_cc(a, b, lim, v_cap_m_s, legs=legs, **kw):
            out = cc(a, b, lim, v_cap_m_s, **kw)
            if out is not None:
                legs.append(out.speed_cap_m_s)
            return out
        monkeypatch.setattr(C, "poly_candidate", rec_poly)
        monkeypatch.setattr(C, "cc_candidate", rec_cc)
        P._SHAPES.clear()
        P._LEGS.clear()
        out = C.via_candidate([start, via, goal], LIM, LIM.v_max_m_s)
        if out is None or whole_poly:
            continue
        assert len(legs) == 2
        assert out.speed_cap_m_s == min(legs)
        mixed += legs[0] != legs[1]
    assert mixed >= 3  # legs of different caps were among the cases


def test_a_replanning_call_never_runs_the_garbage_collector(monkeypatch):
    """Automatic collection is held off inside every replanning call of a run among unknown boxes (a
    collection falling due there would add up to a few ms to the call) and is back on after each."""
    import gc

    from agnav_host.planning.timed import TimedPlanner
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import load_scenario

    inside: list[bool] = []
    collections_inside: list[int] = []
    after: list[bool] = []
    in_call = [False]

    def on_gc(phase: str, info: dict) -> None:
        if phase == "start" and in_call[0]:
            collections_inside.append(info["generation"])
    replan = TimedPlanner._maybe_replan

    def recording(self, *a, **k):
        inside.append(gc.isenabled())
        in_call[0] = True
        try:
            return replan(self, *a, **k)
        finally:
            in_call[0] = False
    step = TimedPlanner.step

    def stepping(self, *a, **k):
        out = step(self, *a, **k)
        after.append(gc.isenabled())
        return out
    monkeypatch.setattr(TimedPlanner, "_maybe_replan", recording)
    monkeypatch.setattr(TimedPlanner, "step", stepping)
    gc.callbacks.append(on_gc)
    try:
        r = run_scenario(load_scenario("timed_static"), "timed", seed=1)
    finally:
        gc.callbacks.remove(on_gc)
    assert r.end_reason == "arrived"
    assert len(inside) >= 5 and not any(inside)
    assert collections_inside == []
    assert after and all(after)
