"""Host-side helpers shared by the SIL test files (native and AVR backends): frame decoding, a
free-running firmware step, and the small host "planners" the scenario tests drive with."""
from __future__ import annotations

import math

from agnav_host.protocol import new_codec
from agnav_host.sil import Firmware, SilSession


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
    """Host logic: pure pursuit at 15 Hz on the firmware's odometry to the scenario's first goal."""

    def __init__(self) -> None:
        self.next = 0

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
        alpha = (math.atan2(dy, dx) - pose.yaw_rad + math.pi) % (2 * math.pi) - math.pi
        steer = math.atan2(2.0 * s.sc.robot_params.track_m * math.sin(alpha), max(d, 0.3))
        s.host.setpoint_si(steer, 0.0 if d < 0.05 else min(0.4, 0.2 + d))
