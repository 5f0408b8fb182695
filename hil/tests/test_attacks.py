"""The attacks of ``make attacks`` (agnav_host.faults.attacks): `agnav sil fault_yard` served on TCP
in a subprocess, attacked by a MAVLink client of its own; the judge of motion is the world
simulator's true pose. Each attack must meet its target: 0 m on heartbeats, replays and stale
commands after a failsafe; true speed within MAX_SPEED_MM_S + 10 % for every motion source; every
bad-field frame counted; every unknown calibration action answered with a refusal."""

from __future__ import annotations

import pytest

from agnav_host.faults.attacks import ATTACKS, STILL_M, bad_field_frames, run_attacks


@pytest.mark.parametrize("name", [a.name for a in ATTACKS])
def test_attack_meets_its_target(name):
    (r,) = run_attacks([name])
    assert r.crashed == 0, r
    assert r.tries > 0 and r.refused == r.tries, r
    assert r.met, r
    if "moved_m" in r.figures:
        assert r.figures["moved_m"] < STILL_M * r.tries, r


def test_the_bad_field_frames_cover_every_message_the_firmware_acts_on():
    names = {n for n, frames in bad_field_frames() if frames}
    assert names >= {"AGNAV_DRIVE_SETPOINT", "RC_CHANNELS_OVERRIDE", "MANUAL_CONTROL", "SET_POSITION_TARGET_LOCAL_NED",
                     "COMMAND_LONG", "PARAM_SET", "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "AGNAV_CALIB_TABLE",
                     "AGNAV_CALIB_REQUEST", "SETUP_SIGNING"}
    assert sum(len(f) for _, f in bad_field_frames()) >= 130
