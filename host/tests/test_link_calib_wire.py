"""Firmware-form calibration tables: validation, lookups and message round trips."""

from __future__ import annotations

import math

import pytest

from agnav_host.calib import default_speed_table, default_steering_table
from agnav_host.link.calib_wire import (TABLE_SPEED, TABLE_STEER, WireTable, from_calib_table, from_message,
                                        validate)
from agnav_host.protocol import new_codec

# the firmware's built-in defaults (firmware/lib/calib/calib.c CALIB_DEFAULTS)
FW_STEER = WireTable(TABLE_STEER, 133, ((133, 0), (170, 2406), (171, 2460)),
                     ((133, 0), (130, -238), (97, -2454), (96, -2460)))
FW_SPEED = WireTable(TABLE_SPEED, 0, ((33, 446), (109, 1995)), ())


def roundtrip(t: WireTable) -> WireTable:
    mav = new_codec()
    buf = t.to_message(mav, 1, 1).pack(mav)
    m = new_codec().parse_char(buf)
    assert m.get_type() == "AGNAV_CALIB_TABLE"
    return from_message(m)


def test_firmware_defaults_are_valid_and_round_trip():
    for t in (FW_STEER, FW_SPEED):
        assert validate(t) == (0, "ok")
        back = roundtrip(t)
        assert back == t
    assert FW_STEER.dead_band == (133, 133)
    assert FW_SPEED.dead_band == (0, 33)


def test_lookups_match_firmware_semantics():
    t = FW_STEER
    assert t.value(133) == 0
    assert t.value(171) == 2460 and t.value(200) == 2460  # saturation
    assert t.value(96) == -2460 and t.value(50) == -2460
    assert t.value(150) == round(2406 * 17 / 37)
    assert t.pwm(0) == 133
    assert t.pwm(2460) == 171 and t.pwm(-2460) == 96
    s = FW_SPEED
    assert s.value(20) == 0 and s.value(33) == 446  # dead band then a jump
    assert s.pwm(300) == 0  # slower than the car can go: stop, not faster
    assert s.pwm(-1000) == s.pwm(1000)  # empty negative side: sign-magnitude


@pytest.mark.parametrize("bad, code", [
    (WireTable(TABLE_STEER, 133, ((133, 0), (170, 2406)), ()), 3),                      # steering needs both sides
    (WireTable(TABLE_STEER, 133, ((140, 500), (150, 400)), ((120, -500), (110, -900))), 1),  # not monotone
    (WireTable(TABLE_STEER, 133, ((140, 500), (150, 5000)), ((120, -500), (110, -900))), 2),  # > 45 deg
    (WireTable(TABLE_STEER, 133, ((140, 500), (150, 900)), ((140, -500), (150, -900))), 4),  # same side
    (WireTable(TABLE_SPEED, 0, ((33, 446),), ()), 3),
    (WireTable(TABLE_SPEED, 0, ((33, 446), (3001, 2000)), ()), 2),
    (WireTable(7, 0, ((33, 446), (109, 1995)), ()), 4),
])
def test_validate_refuses_like_the_firmware(bad, code):
    assert validate(bad)[0] == code


def test_mirrored_servo_orientation_is_allowed():
    t = WireTable(TABLE_STEER, 1500, ((1450, 200), (1000, 2500)), ((1550, -200), (2000, -2500)))
    assert validate(t)[0] == 0
    assert not t.pos_above
    assert t.value(1000) == 2500 and t.value(2000) == -2500
    assert roundtrip(t) == t


def test_from_calib_table_rounds_outward_and_stays_close():
    st = default_steering_table()
    w = from_calib_table(st, TABLE_STEER)
    assert validate(w)[0] == 0
    lo, hi = w.dead_band
    assert lo <= 132 and hi >= 134  # the half-count dead band edges moved outward, not inward
    for p in range(96, 172):
        assert abs(w.value(p) - st.value_from_pwm(p) * 18000 / math.pi) <= 40  # within 0.4 deg
    sp = from_calib_table(default_speed_table(), TABLE_SPEED)
    assert validate(sp)[0] == 0 and sp.neg == ()
    back = sp.to_calib_table()
    assert back.value_from_pwm(80) == pytest.approx(default_speed_table().value_from_pwm(80), abs=0.01)
