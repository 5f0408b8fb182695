import math

import numpy as np
import pytest

from agnav_host.calib import CalibError, CalibTable, default_speed_table, default_steering_table, table_from_dict


def test_default_steering_matches_ref003_fits():
    t = default_steering_table()
    # left (PWM above centre): 0.6502*PWM - 86.477; right: -0.6717*PWM + 89.698 (deg)
    for pwm in (140, 150, 160, 165):
        assert math.degrees(t.value_from_pwm(pwm)) == pytest.approx(0.6502 * pwm - 86.477, abs=1e-9)
    for pwm in (100, 110, 120, 130):
        assert math.degrees(t.value_from_pwm(pwm)) == pytest.approx(-(-0.6717 * pwm + 89.698), abs=1e-9)
    assert t.value_from_pwm(133) == 0.0
    assert math.degrees(t.value_from_pwm(255)) == pytest.approx(24.6)
    assert math.degrees(t.value_from_pwm(0)) == pytest.approx(-24.6)


def test_default_speed_matches_ref003_fit_and_dead_band():
    t = default_speed_table()
    assert t.value_from_pwm(64) == pytest.approx((2.038 * 64 - 22.636) / 100)
    assert t.value_from_pwm(20) == 0.0
    assert t.value_from_pwm(200) == pytest.approx(2.0)


def test_forward_is_monotone_and_inverse_round_trips():
    for t in (default_steering_table(), default_speed_table()):
        pwm = np.linspace(t.pwm_min, t.pwm_max, 2001)
        assert np.all(np.diff(t.value_from_pwm(pwm)) >= 0)
    t = default_steering_table()
    for deg in (-20, -5, 3, 12, 24):
        assert math.degrees(t.value_from_pwm(t.pwm_from_value(math.radians(deg)))) == pytest.approx(deg, abs=0.7)


def _table(**kw):
    base = dict(name="t", unit="rad", neutral_pwm=100.0, pos_pwm=(101.0, 150.0), pos_value=(0.0, 0.4),
                neg_pwm=(99.0, 50.0), neg_value=(0.0, 0.4), pwm_min=0.0, pwm_max=255.0, value_max=0.4)
    base.update(kw)
    return CalibTable(**base)


@pytest.mark.parametrize("kw, match", [
    (dict(pos_value=(0.3, 0.2)), "pos_value not strictly increasing"),
    (dict(pos_pwm=(140.0, 120.0)), "pos_pwm not strictly increasing"),
    (dict(neg_pwm=(50.0, 99.0)), "neg_pwm not strictly decreasing"),
    (dict(pos_pwm=(101.0, 300.0)), "outside the PWM range"),
    (dict(pos_value=(0.0, 0.5)), "exceeds value_max"),
    (dict(neg_value=(-0.1, 0.4)), "negative"),
    (dict(pos_pwm=(101.0,), pos_value=(0.0,)), "at least 2"),
    (dict(pos_pwm=(90.0, 150.0)), "below neutral_pwm"),
])
def test_bad_tables_are_refused_with_a_reason(kw, match):
    with pytest.raises(CalibError, match=match):
        _table(**kw)


def test_table_dict_round_trip_and_unknown_key():
    t = default_steering_table()
    assert table_from_dict("steering", "rad", t.to_dict()) == t
    with pytest.raises(CalibError, match="unknown key"):
        table_from_dict("s", "rad", {**t.to_dict(), "bogus": 1})
