import math

import numpy as np
import pytest

from agnav_host.planning.fuzzy import RULES, Dist, DistanceSets, Speed, Turn, TurnSets, cla_defuzzify, infer, trapezoid


def test_trapezoid_edges_and_plateau():
    assert trapezoid(0.5, 0, 1, 2, 3) == pytest.approx(0.5)
    assert trapezoid(1.5, 0, 1, 2, 3) == 1.0
    assert trapezoid(2.75, 0, 1, 2, 3) == pytest.approx(0.25)
    assert trapezoid(-0.1, 0, 1, 2, 3) == 0.0 and trapezoid(3.1, 0, 1, 2, 3) == 0.0
    assert trapezoid(-5.0, -math.inf, -math.inf, 0.5, 1.5) == 1.0  # left shoulder


@pytest.mark.parametrize("x", np.linspace(0.0, 6.0, 61))
def test_distance_sets_cover_and_partition(x):
    ds = DistanceSets()
    c, m, f = ds.memberships(float(x))
    assert c + m + f == pytest.approx(1.0)  # a fuzzy partition: no gap, no overlap above 1
    assert max(c, m, f) > 0.0


def test_distance_sets_reject_bad_order():
    with pytest.raises(ValueError):
        DistanceSets(close_full=2.0, medium_full=1.0)


def test_27_rules_cover_every_antecedent_once():
    assert len(RULES) == 27
    keys = {(r.left, r.front, r.right) for r in RULES}
    assert len(keys) == 27
    # table 3-I: left close -> stop; all far -> full speed; otherwise 0.2 Vmax
    for r in RULES:
        if r.left == Dist.CLOSE:
            assert r.speed == Speed.STOP
        elif (r.left, r.front, r.right) == (Dist.FAR,) * 3:
            assert r.speed == Speed.FAST and r.turn == Turn.GOAL
        else:
            assert r.speed == Speed.SLOW
    assert next(r for r in RULES if (r.left, r.front, r.right) == (Dist.CLOSE, Dist.CLOSE, Dist.CLOSE)).turn == Turn.PB
    assert next(r for r in RULES if (r.left, r.front, r.right) == (Dist.FAR, Dist.CLOSE, Dist.FAR)).turn == Turn.GOAL


def test_cla_picks_the_largest_area_not_the_centroid():
    ts = TurnSets()
    x = ts.universe
    mu = np.maximum(np.minimum(ts.triangle(math.radians(-60)), 0.9), np.minimum(ts.triangle(math.radians(60)), 0.5))
    out = cla_defuzzify(x, mu, 0.3)
    assert out == pytest.approx(math.radians(-60), abs=math.radians(3))
    centroid = float((mu * x).sum() / mu.sum())
    assert abs(centroid) < abs(out)  # plain centroid blends towards straight ahead


def test_cla_threshold_limits():
    ts = TurnSets()
    x = ts.universe
    mu = np.minimum(ts.triangle(math.radians(30)), 0.8)
    assert cla_defuzzify(x, mu, 0.0) == pytest.approx(math.radians(30), abs=1e-6)  # centroid
    assert cla_defuzzify(x, mu, 1.0) == pytest.approx(math.radians(30), abs=math.radians(6))  # mean of maxima
    with pytest.raises(ValueError):
        cla_defuzzify(x, mu, 1.5)


def test_cla_tie_goes_to_the_goal_side():
    ts = TurnSets()
    x = ts.universe
    mu = np.maximum(ts.triangle(math.radians(-60)), ts.triangle(math.radians(60)))
    assert cla_defuzzify(x, mu, 0.3, prefer_rad=0.4) > 0
    assert cla_defuzzify(x, mu, 0.3, prefer_rad=-0.4) < 0


def test_infer_all_far_goes_to_goal_at_full_speed():
    inf = infer(10.0, 10.0, 10.0, math.radians(20), 0.6)
    assert inf.speed_fraction == pytest.approx(1.0)
    assert inf.turn_rad == pytest.approx(math.radians(20), abs=math.radians(3))
    assert [i for i, _ in inf.fired] == [26]


def test_infer_product_strength_and_front_blocked_turns_to_goal_side():
    inf = infer(10.0, 0.2, 10.0, math.radians(-5), 0.6)  # far, close, far
    assert inf.speed_fraction == pytest.approx(0.2)
    assert inf.turn_rad < -math.radians(20)  # GOAL with the front blocked: at least NS to the goal's side
    ds = DistanceSets()
    left, front, right = 1.0, 2.0, 3.0
    strengths = dict(infer(left, front, right, 0.0, 0.6).fired)
    exp = ds.memberships(left)[1] * ds.memberships(front)[1] * ds.memberships(right)[1]
    mm = next(i for i, rule in enumerate(RULES) if (rule.left, rule.front, rule.right) == (Dist.MEDIUM,) * 3)
    assert strengths[mm] == pytest.approx(exp)


def test_infer_left_close_turns_right_and_stops():
    inf = infer(0.1, 10.0, 10.0, 0.0, 0.6)
    assert inf.speed_fraction == 0.0
    assert inf.turn_rad < 0.0


def test_cla_hysteresis_holds_the_previous_area_until_another_is_clearly_larger():
    ts = TurnSets()
    x = ts.universe
    left_bigger = np.maximum(np.minimum(ts.triangle(math.radians(-60)), 0.50), np.minimum(ts.triangle(math.radians(60)), 0.56))
    assert cla_defuzzify(x, left_bigger, 0.3) > 0  # no memory: the larger (left) area
    assert cla_defuzzify(x, left_bigger, 0.3, keep_rad=math.radians(-55), keep_bonus=0.25) < 0  # held right
    much_bigger = np.maximum(np.minimum(ts.triangle(math.radians(-60)), 0.4), ts.triangle(math.radians(60)))
    assert cla_defuzzify(x, much_bigger, 0.3, keep_rad=math.radians(-55), keep_bonus=0.25) > 0  # switches


def test_infer_goal_side_overrides_the_sign_of_a_nearly_straight_bearing():
    # front close, sides far, goal 3 deg to the right: the caller holds a left detour
    assert infer(10.0, 0.2, 10.0, math.radians(-3), 0.6).turn_rad < 0
    assert infer(10.0, 0.2, 10.0, math.radians(-3), 0.6, goal_side=1.0).turn_rad > math.radians(20)
