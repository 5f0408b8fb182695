"""Host-side helpers shared by the SIL test files (native and AVR backends): frame decoding, a
free-running firmware step, and the small host "planners" the scenario tests drive with."""
from __future__ import annotations

import math

from agnav_host.protocol import new_codec
from agnav_host.sil import Firmware, SilSession
from agnav_host.types import norm_angle_rad


def decode(data: bytes):
    return new_codec().parse_buffer(data) or []


def run(fw: Firmware, us: int) -> bytes:
    """Run us microseconds (triggers unanswered), draining the UART every 50 ms as a radio would."""
    end = fw.time_us + us
    out = bytearray()
    while fw.time_us < end:
        fw.step_to(min(end, fw.time_us + 50_000))
        fw.take_triggers()
        out += fw.uart_read()
    return bytes(out)


class Heartbeats:
    """Host logic: heartbeats (and optionally a fixed setpoint) every ``period_s``; optional
    behaviour enable sent once at start."""

    def __init__(self, period_s: float = 0.1, setpoint: tuple[int, int] | None = None,
                 follow_wall: bool = False) -> None:
        self.period_us = int(period_s * 1e6)
        self.next = 0
        self.setpoint = setpoint
        self.follow_wall = follow_wall
        self.enabled = False

    def __call__(self, s: SilSession, t_us: int) -> None:
        if self.follow_wall and not self.enabled:
            s.host.set_behaviours(follow_wall=True)
            self.enabled = True
        if t_us >= self.next:
            self.next += self.period_us
            s.host.heartbeat()
            if self.setpoint is not None:
                s.host.setpoint(*self.setpoint)


class PurePursuit:
    """Host logic: pure pursuit at 15 Hz on the firmware's odometry to the scenario's first goal.

    Once the odometry is within ``STOP_M`` of the goal the host commands a stop (speed 0, steering
    centred) and keeps it while the odometry stays within the goal's tolerance. Braking from the
    approach speed (0.2 + d m/s) and the loop's delays (100 ms odometry period, 66 ms host period,
    link and 20 ms control tick) carry the robot some centimetres past the point where the stop
    was decided, sometimes past ``STOP_M``; driving on from there at >= 0.2 m/s with a lookahead of
    at least 0.3 m would circle the goal instead of reaching it."""

    STOP_M = 0.05

    def __init__(self) -> None:
        self.next = 0
        self.stopped = False

    def __call__(self, s: SilSession, t_us: int) -> None:
        if t_us < self.next:
            return
        self.next += 66_000  # 15 Hz
        s.host.heartbeat()
        pose = s.believed_pose()
        if pose is None:
            return
        g = s.sc.goals[0]
        dx, dy = g.x_m - pose.x_m, g.y_m - pose.y_m
        d = math.hypot(dx, dy)
        if d < self.STOP_M:
            self.stopped = True
        elif d > g.tolerance_m:
            self.stopped = False
        if self.stopped:
            s.host.setpoint_si(0.0, 0.0)
            return
        alpha = norm_angle_rad(math.atan2(dy, dx) - pose.yaw_rad)
        steer = math.atan2(2.0 * s.sc.robot_params.track_m * math.sin(alpha), max(d, 0.3))
        s.host.setpoint_si(steer, min(0.4, 0.2 + d))
