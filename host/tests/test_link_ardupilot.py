"""Stock ArduPilot Rover mapping (ref 001's greenhouse robot), unit and against a fake Rover."""

from __future__ import annotations

import math
import time

import pytest

from agnav_host.link import Endpoint
from agnav_host.link.ardupilot import (MAV_FRAME_BODY_NED, VELOCITY_TYPE_MASK, ArduRover, ArduRoverConfig,
                                       rc_from_drive, velocity_target_from_drive)
from agnav_host.link.fake import FakeRobot
from agnav_host.types import DriveCommand


def wait_until(pred, timeout=3.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


def test_rc_mapping_signs_and_limits():
    cfg = ArduRoverConfig(mode="rc", max_steer_rad=math.radians(20), max_speed_m_s=1.0)
    ch = rc_from_drive(DriveCommand(speed_m_s=0.5, steer_rad=math.radians(10)), cfg)
    assert len(ch) == 18
    assert ch[0] == 1300  # left turn (positive) = stick left = below trim on ch1
    assert ch[2] == 1700  # half speed forward
    assert ch[1] == 65535 and ch[3] == 65535 and ch[8] == 0  # others ignored
    ch = rc_from_drive(DriveCommand(speed_m_s=-5.0, steer_rad=-1.0), cfg)
    assert ch[0] == 1900 and ch[2] == 1100  # saturated
    rev = rc_from_drive(DriveCommand(speed_m_s=0.0, steer_rad=math.radians(10)),
                        ArduRoverConfig(mode="rc", reverse_steer=True, max_steer_rad=math.radians(20)))
    assert rev[0] == 1700
    with pytest.raises(ValueError):
        ArduRoverConfig(steer_channel=3, throttle_channel=3)


def test_velocity_mapping_converts_to_ned():
    cfg = ArduRoverConfig(wheelbase_m=0.5, max_speed_m_s=1.0)
    f = velocity_target_from_drive(DriveCommand(speed_m_s=0.8, yaw_rate_rad_s=0.3), cfg)
    assert f["vx"] == 0.8 and f["yaw_rate"] == pytest.approx(-0.3)  # CCW left turn = negative NED rate
    f = velocity_target_from_drive(DriveCommand(speed_m_s=2.0, steer_rad=math.atan(0.25)), cfg)
    assert f["vx"] == 1.0 and f["yaw_rate"] == pytest.approx(-1.0 * 0.25 / 0.5)


def test_against_fake_rover_velocity_and_rc():
    with FakeRobot(autopilot="ardupilot") as fr:
        with Endpoint(fr.device) as ep:
            hb = ep.wait_heartbeat(3.0)
            assert hb.autopilot == 3  # MAV_AUTOPILOT_ARDUPILOTMEGA
            rover = ArduRover(ep, ArduRoverConfig(mode="velocity"))
            rover.start()
            assert fr.mode == 15 and fr.armed  # GUIDED, armed
            rover.drive_command(DriveCommand(speed_m_s=0.5, yaw_rate_rad_s=0.2))
            assert wait_until(lambda: fr.received_of("SET_POSITION_TARGET_LOCAL_NED"))
            m = fr.received_of("SET_POSITION_TARGET_LOCAL_NED")[-1]
            assert m.coordinate_frame == MAV_FRAME_BODY_NED and m.type_mask == VELOCITY_TYPE_MASK
            assert m.vx == pytest.approx(0.5) and m.yaw_rate == pytest.approx(-0.2)
            rc = ArduRover(ep, ArduRoverConfig(mode="rc"))
            rc.start()
            assert fr.mode == 0  # MANUAL
            rc.drive(math.radians(-24.6), 1.0)  # hard right, full speed
            assert wait_until(lambda: fr.received_of("RC_CHANNELS_OVERRIDE"))
            o = fr.received_of("RC_CHANNELS_OVERRIDE")[-1]
            assert (o.chan1_raw, o.chan3_raw) == (1900, 1900)
            rc.estop()
            assert not fr.armed and fr.mode == 4  # HOLD and force-disarmed
            disarm = [c for c in fr.received_of("COMMAND_LONG") if c.command == 400 and c.param1 == 0]
            assert disarm and disarm[-1].param2 == 21196
            assert wait_until(lambda: ep.state.pose is not None)
