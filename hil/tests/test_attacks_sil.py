"""After every kind of failsafe the SIL robot moves again only on a fresh command from its host.

The real firmware (native SIL) drives the ``fault_yard`` robot on its own goal seek or on host
setpoints (HOST_TIMEOUT_MS 5000, so the last setpoint is still younger than the setpoint timeout when
the failsafe ends). Then a link loss, an e-stop, a sonar fault or a watchdog reset stops it; the
failsafe ends (heartbeats again; release and arm; the sensor recovers and the host arms; the host
arms after the reset) and 3 s of heartbeats follow. The world simulator's true pose must not move in
them. A fresh command (a new goal, a new setpoint) then drives again. The raw-PWM and bad-frame
attacks at the end run the same way (the TCP attacks of ``make attacks`` are in test_attacks.py)."""

from __future__ import annotations

import math

import pytest

from agnav_host.protocol import dialect
from agnav_host.sil import SilConfig, SilSession
from agnav_host.sim import load_scenario

D = dialect()
LAYER_FAILSAFE, LAYER_IDLE, LAYER_HOST, LAYER_GOAL = 1, 0, 5, 6


class Host:
    """Heartbeats (and a setpoint, when set) every 100 ms; silent while ``silent``."""

    def __init__(self) -> None:
        self.next_us = 0
        self.setpoint: tuple[int, int] | None = None
        self.raw: tuple[int, int] | None = None
        self.silent = False

    def __call__(self, s: SilSession, t_us: int) -> None:
        if self.silent or t_us < self.next_us:
            return
        self.next_us = t_us + 100_000
        s.host.heartbeat()
        if self.raw is not None:
            s.host._seq = (s.host._seq + 1) & 0xFFFF  # noqa: SLF001 -- the endpoint's setpoint count
            s.host._send(D.MAVLink_agnav_drive_setpoint_message(1, 1, 0, 0, *self.raw, D.AGNAV_DRIVE_RAW_PWM,  # noqa: SLF001
                                                                s.host._seq))  # noqa: SLF001
        elif self.setpoint is not None:
            s.host.setpoint(*self.setpoint)


def _session(**params: int) -> tuple[SilSession, Host]:
    logic = Host()
    s = SilSession(load_scenario("fault_yard"), 0, SilConfig(world_dt_s=0.01, firmware_params=tuple(params.items())),
                   logic)
    s.provision()
    return s, logic


def _goal(s: SilSession, x_m: float) -> None:
    s.host._send(D.MAVLink_set_position_target_local_ned_message(  # noqa: SLF001
        0, 1, 1, D.MAV_FRAME_LOCAL_NED, 0b0000_1101_1111_1000, x_m, 0.0, 0, 0, 0, 0, 0, 0, 0, 0, 0))


def _release_and_arm(s: SilSession) -> None:
    s.host.command_long(D.MAV_CMD_AGNAV_ESTOP, 0.0)
    s.host.arm()


def _travel(s: SilSession, seconds: float) -> tuple[float, float]:
    """Run; (true path length m, top true speed m/s) over the time."""
    end = s.t_us + int(seconds * 1e6)
    d, v = 0.0, 0.0
    p = s.pose
    while s.t_us < end:
        s.step()
        q = s.pose
        d += math.hypot(q.x_m - p.x_m, q.y_m - p.y_m)
        v = max(v, abs(s.plant.robot.speed_m_s))
        p = q
    return d, v


def _failsafe(s: SilSession, logic: Host, kind: str) -> None:
    """Stop the robot by ``kind`` for 2.2 s (it coasts to a standstill) and end the failsafe."""
    if kind == "link loss":
        logic.silent = True
        _travel(s, 2.2)
        logic.silent = False
    elif kind == "e-stop":
        s.host.command_long(D.MAV_CMD_AGNAV_ESTOP, 1.0)
        _travel(s, 2.2)
        _release_and_arm(s)
    elif kind == "sonar fault":
        s.fw.fault_sonar(0, "timeout")
        _travel(s, 2.2)
        s.fw.fault_sonar(0, "none")
        _travel(s, 0.5)
        _release_and_arm(s)
    else:
        s.fw.fault_reset("watchdog")
        _travel(s, 2.2)
        _release_and_arm(s)


FAILSAFES = ["link loss", "e-stop", "sonar fault", "watchdog reset"]


@pytest.mark.parametrize("kind", FAILSAFES)
def test_a_goal_stored_before_a_failsafe_is_not_sought_after_it(kind):
    s, logic = _session()
    try:
        _release_and_arm(s)
        s.host.set_behaviours(False, True, True)
        _goal(s, 8.0)
        d, _ = _travel(s, 2.0)
        assert d > 0.3 and s.host.status.layer == LAYER_GOAL, "the robot seeks its goal"
        _failsafe(s, logic, kind)
        if kind == "watchdog reset":
            s.host.set_behaviours(False, True, True)  # the reset forgot them: the host's behaviours, no goal
        d, _ = _travel(s, 3.0)
        assert d < 0.001, f"{kind}: moved {d * 1000:.1f} mm on heartbeats with a goal from before the failsafe"
        assert s.host.status.layer == LAYER_IDLE
        _goal(s, 8.0)  # the host sends its goal again
        d, _ = _travel(s, 1.5)
        assert d > 0.1, f"{kind}: a new goal did not drive"
    finally:
        s.close()


@pytest.mark.parametrize("kind", FAILSAFES)
def test_a_setpoint_from_before_a_failsafe_is_not_obeyed_after_it(kind):
    s, logic = _session(HOST_TIMEOUT_MS=5000)
    try:
        _release_and_arm(s)
        logic.setpoint = (0, 300)
        d, _ = _travel(s, 2.0)
        assert d > 0.3, "the robot drives on the host's setpoints"
        logic.setpoint = None  # the host's last setpoint stays 5 s "fresh"
        _failsafe(s, logic, kind)
        d, _ = _travel(s, 3.0)
        assert d < 0.001, f"{kind}: moved {d * 1000:.1f} mm on a setpoint from before the failsafe"
        logic.setpoint = (0, 300)
        d, _ = _travel(s, 1.5)
        assert d > 0.1, f"{kind}: a new setpoint did not drive"
    finally:
        s.close()


def test_raw_pwm_full_throttle_is_held_to_the_speed_cap_and_reported_as_it_drives():
    s, logic = _session(MAX_SPEED_MM_S=200)
    try:
        logic.raw = (0, 255)
        _travel(s, 1.0)
        _, v = _travel(s, 3.0)
        assert v <= 0.22, f"raw full throttle drove {v:.2f} m/s with MAX_SPEED_MM_S 200"
        assert v >= 0.15
        st = s.host.status
        assert st.layer == LAYER_HOST and st.speed_mm_s == 200, f"BEHAVIOUR_STATUS says {st}"
    finally:
        s.close()


def test_raw_pwm_within_the_cap_drives_its_outputs_unchanged():
    s, logic = _session()
    try:
        logic.raw = (0, 60)  # 996 mm/s on the fault_yard tables, under MAX_SPEED_MM_S 1000
        _travel(s, 1.0)
        o = s.fw.outputs()
        assert o.duty_left == 60 and o.duty_right == 60, f"raw duty {o.duty_left}/{o.duty_right}"
        assert 0 < s.host.status.speed_mm_s <= 1000
    finally:
        s.close()


def test_unknown_calibration_actions_get_a_refusal_and_are_counted():
    s, _ = _session()
    try:
        _travel(s, 1.2)
        before = s.host.sys_status.errors_count1
        n = len(s.host.calib_acks)
        for action in (3, 4, 200):
            s.host.calib_request(1, action)
        _travel(s, 2.5)
        acks = s.host.calib_acks[n:]
        assert [(a.table_id, a.result) for a in acks] == [(1, D.AGNAV_CALIB_OUT_OF_RANGE)] * 3
        assert s.host.sys_status.errors_count1 - before == 3
    finally:
        s.close()
