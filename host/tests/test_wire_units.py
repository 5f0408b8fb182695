"""Wire units (the firmware's mm, mm/s, ms, cdeg, cdeg/s) and SI, converted in one module: the link's state, the
SIL's host endpoint and the setpoints the host sends read and write the same numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.link.robot import drive_to_wire
from agnav_host.link.state import RobotState
from agnav_host.protocol import dialect, new_codec
from agnav_host.sil.host import HostEndpoint
from agnav_host.units import cdeg_to_rad, milli_to_si, rad_to_cdeg, si_to_milli, to_int16


def test_conversions_and_their_inverses():
    assert milli_to_si(1234) == 1.234 and si_to_milli(1.234) == pytest.approx(1234)
    assert cdeg_to_rad(18000) == pytest.approx(math.pi) and rad_to_cdeg(math.pi / 2) == pytest.approx(9000)
    a = np.array([-4500.0, 0.0, 9000.0])
    assert np.allclose(rad_to_cdeg(cdeg_to_rad(a)), a) and isinstance(cdeg_to_rad(a), np.ndarray)
    assert np.allclose(si_to_milli(milli_to_si(a)), a)
    assert (to_int16(1e9), to_int16(-1e9), to_int16(2.5), to_int16(-0.6)) == (32767, -32768, 2, -1)


def test_a_setpoint_goes_on_the_wire_in_cdeg_and_mm_s():
    assert drive_to_wire(math.radians(-12.34), -0.5) == (-1234, -500)
    assert drive_to_wire(math.radians(400.0), 99.0) == (32767, 32767)  # clamped to the int16 field


def _telemetry() -> list[bytes]:
    robot = new_codec(1, 1)
    frames = []
    for k in range(20):
        frames.append(robot.agnav_odometry_encode(100 * k, 1500 + k, -2500 - k, -9000 + 7 * k, -321, 4500).pack(robot))
        frames.append(robot.agnav_behaviour_status_encode(100 * k, 5, 12, 0, -1234, 567).pack(robot))
        frames.append(robot.agnav_sonar_ring_encode(100 * k, [2000 + i for i in range(12)], [0] * 12, 12, k).pack(robot))
    return frames


def test_the_sil_host_endpoint_and_the_link_state_read_a_frame_to_the_same_si_values():
    frames = _telemetry()
    host = HostEndpoint()
    host.feed(0, b"".join(frames))
    state = RobotState()
    for m in new_codec().parse_buffer(b"".join(frames)):
        state.update(m, 0.0)
    o, p = host.odometry, state.pose
    assert (o.x_m, o.y_m, o.heading_rad, o.speed_m_s, o.yaw_rate_rad_s) == (p.x_m, p.y_m, p.yaw_rad, p.speed_m_s,
                                                                          p.yaw_rate_rad_s)
    assert (o.x_m, o.y_m, o.speed_m_s) == (1.519, -2.519, -0.321)
    assert o.heading_rad == pytest.approx(math.radians(-90.0 + 0.07 * 19)) and o.yaw_rate_rad_s == pytest.approx(math.pi / 4)


def test_the_sil_host_endpoint_decodes_frames_split_over_deliveries_and_skips_garbage():
    frames = _telemetry()
    stream = b"".join(f + (b"\x00\x11garbage" if i % 7 == 3 else b"") for i, f in enumerate(frames))
    rng = np.random.default_rng(5)
    cuts = sorted(int(c) for c in rng.integers(1, len(stream), 40))
    host = HostEndpoint()
    got = []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):
        got += host.feed(a, stream[a:b])
    kinds = [m.get_type() for m in got if m.get_type() != "BAD_DATA"]
    assert kinds.count("AGNAV_ODOMETRY") == 20 and kinds.count("AGNAV_BEHAVIOUR_STATUS") == 20
    assert kinds.count("AGNAV_SONAR_RING") == 20
    assert [o.x_m for o in host.odometry_log] == [milli_to_si(1500 + k) for k in range(20)]
    assert host.status.steer_cdeg == -1234 and host.sonar.ranges_mm[11] == 2011


def test_the_sil_host_endpoint_sends_si_setpoints_in_wire_units():
    host = HostEndpoint()
    host.setpoint_si(math.radians(-5.0), -0.25)
    (m,) = new_codec().parse_buffer(host.take_tx())
    assert m.get_type() == "AGNAV_DRIVE_SETPOINT" and (m.steer_cdeg, m.speed_mm_s) == (-500, -250)
    assert m.mode == dialect().AGNAV_DRIVE_PHYSICAL

