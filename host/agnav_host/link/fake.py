"""A fake robot that speaks the AgNav protocol over TCP on 127.0.0.1, for tests and demos.

It mirrors what firmware/lib/telemetry and firmware/lib/link/link.c do on the wire (its telemetry rates:
AGNAV_BEHAVIOUR_STATUS 50 Hz; AGNAV_ODOMETRY, AGNAV_ENCODER_STATUS, AGNAV_SONAR_RING 10 Hz;
HEARTBEAT and NAMED_VALUE_INT 1 Hz; PARAM_*, COMMAND_LONG, calibration requests) and drives a
kinematic Ackermann car (ref-003 geometry) whose *true* actuator response is a pair of
:class:`~agnav_host.calib.CalibTable` (possibly miscalibrated), while its *active* tables (what it
believes, written over AGNAV_CALIB_TABLE) map physical setpoints to PWM, as the firmware does.
Two rear-wheel encoders report the true wheel speeds; odometry yaw rate, as in the firmware's
Ackermann odometry, is computed from the *commanded* steering angle.

``autopilot="ardupilot"`` makes it a stock ArduPilot Rover instead: heartbeat of
MAV_AUTOPILOT_ARDUPILOTMEGA, LOCAL_POSITION_NED + ATTITUDE telemetry, and it records
RC_CHANNELS_OVERRIDE / SET_POSITION_TARGET_LOCAL_NED / COMMAND_LONG (acknowledged).

Fault injection: :meth:`FakeRobot.drop_client` (cable pulled: the TCP connection is closed),
:meth:`FakeRobot.stop_listening` / :meth:`FakeRobot.start_listening` (peer gone and back on the same
port), ``mute`` (radio silence: nothing sent), ``drop_param_indices`` (PARAM_VALUE lost on air).
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..calib import CalibTable, default_speed_table, default_steering_table
from ..protocol import dialect
from ..types import norm_angle_rad
from ..units import cdeg_to_rad, milli_to_si, rad_to_cdeg, si_to_milli
from .calib_wire import TABLE_SPEED, TABLE_SPEED_RIGHT, TABLE_STEER, WireTable, from_calib_table, from_message, validate

__all__ = ["FakeRobot", "FIRMWARE_PARAMS"]

#: name -> (default, min, max): the firmware's parameter rows (firmware/lib/<module>/<module>_params.c)
FIRMWARE_PARAMS: dict[str, tuple[int, int, int]] = {
    "SYSID_THISMAV": (1, 1, 250), "DRIVE_KIND": (0, 0, 1), "ENC_COUNT": (2, 1, 4), "ENC_MODE": (1, 0, 1),
    "ENC_NM_PER_CNT": (13550000, 1000, 16000000), "TRACK_MM": (191, 50, 2000), "WHEELBASE_MM": (174, 50, 2000),
    "SONAR_COUNT": (12, 0, 12), "BHV_MODES": (4, 0, 7), "LINK_TIMEOUT_MS": (500, 100, 5000),
    "MAX_SPEED_MM_S": (1000, 0, 3000), "MAX_STEER_CDEG": (2460, 0, 4500), "AVOID_STOP_MM": (400, 50, 3000),
    "AVOID_BACKOFF_MM": (150, 0, 500), "AVOID_WAIT_MS": (1000, 0, 10000), "WALL_R0_MM": (400, 0, 1000),
    "WALL_SPEED_MM_S": (300, 0, 2000), "WALL_CANYON_MS": (2000, 0, 10000), "GOAL_SPEED_MM_S": (400, 0, 2000),
    "GOAL_TOL_MM": (200, 10, 2000),
}


@dataclass
class _Car:
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    v: float = 0.0
    phi: float = 0.0
    yaw_rate: float = 0.0
    odom_x: float = 0.0
    odom_y: float = 0.0
    odom_yaw: float = 0.0
    odom_rate: float = 0.0
    counts: list[float] = field(default_factory=lambda: [0.0, 0.0])
    wheel_v: list[float] = field(default_factory=lambda: [0.0, 0.0])


class FakeRobot:
    """See the module docstring. Use as a context manager; ``port`` is the ephemeral TCP port."""

    def __init__(self, *, true_steer: CalibTable | None = None, true_speed: CalibTable | None = None,
                 autopilot: str = "agnav", sysid: int = 1, compid: int = 1, key: bytes | None = None,
                 rate_scale: float = 1.0, wheelbase_m: float = 0.174, track_m: float = 0.191,
                 speed_noise_m_s: float = 0.0, seed: int = 0, sonar: bool = True) -> None:
        self.d = dialect()
        self.mav = self.d.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        self.key = key
        if key is not None:
            s = self.mav.signing
            s.secret_key, s.sign_outgoing, s.link_id = key, False, 0
            s.allow_unsigned_callback = None  # verify: unsigned frames are rejected
        self.autopilot = autopilot
        self.sysid, self.compid = sysid, compid
        self.true_steer = true_steer or default_steering_table()
        self.true_speed = true_speed or default_speed_table()
        self.tables: dict[int, WireTable] = {
            TABLE_STEER: from_calib_table(default_steering_table(), TABLE_STEER),
            TABLE_SPEED: from_calib_table(default_speed_table(), TABLE_SPEED),
            TABLE_SPEED_RIGHT: from_calib_table(default_speed_table(), TABLE_SPEED_RIGHT),
        }
        self.saved_tables: dict[int, WireTable] | None = None
        self.params = {k: v[0] for k, v in FIRMWARE_PARAMS.items()}
        self.param_names = list(FIRMWARE_PARAMS)
        self.L, self.track = wheelbase_m, track_m
        self.rate_scale = rate_scale
        self.speed_noise = speed_noise_m_s
        self.rng = np.random.default_rng(seed)
        self.has_sonar = sonar
        # link state (as link_state_t)
        self.estop = False
        self.armed = True
        self.behaviours = 4
        self.setpoint: Any = None
        self.setpoint_rx = -1e9
        self.host_hb_rx = -1e9
        self.goal: tuple[float, float] | None = None
        self.mode = 0  # ArduPilot custom mode
        self.link_timeout_s = 0.5
        self.received: list[Any] = []
        self.rejected = 0
        self.mute = False
        self.drop_param_indices: set[int] = set()
        self.car = _Car()
        self.tx_bytes = 0
        self.connections = 0
        self._lock = threading.Lock()
        self._srv: socket.socket | None = None
        self._cli: socket.socket | None = None
        self.port = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = time.monotonic()
        self._param_next: int | None = None

    # ---- life cycle ----------------------------------------------------------------------------
    def start(self) -> "FakeRobot":
        self.start_listening()
        self._thread = threading.Thread(target=self._run, name="fake-robot", daemon=True)
        self._thread.start()
        return self

    def start_listening(self) -> None:
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        srv.bind(("127.0.0.1", self.port))
        srv.listen(1)
        srv.setblocking(False)
        self.port = srv.getsockname()[1]
        self._srv = srv

    def stop_listening(self) -> None:
        """The peer disappears: close the listening socket and the client connection."""
        with self._lock:
            srv, self._srv = self._srv, None
            if srv is not None:
                srv.close()
        self.drop_client()

    def drop_client(self) -> None:
        with self._lock:
            cli, self._cli = self._cli, None
            if cli is not None:
                try:
                    cli.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                cli.close()

    @property
    def connected(self) -> bool:
        return self._cli is not None

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.stop_listening()

    def __enter__(self) -> "FakeRobot":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def device(self) -> str:
        return f"tcp:127.0.0.1:{self.port}"

    def now(self) -> float:
        return time.monotonic() - self._t0

    def received_of(self, mtype: str) -> list[Any]:
        with self._lock:
            return [m for m in self.received if m.get_type() == mtype]

    # ---- main loop -------------------------------------------------------------------------------
    def _run(self) -> None:
        last = self.now()
        nxt = {"50": 0.0, "10": 0.0, "1": 0.0}
        while not self._stop.is_set():
            self._accept()
            self._read()
            t = self.now()
            dt, last = t - last, t
            self._step(min(dt, 0.05))
            if self._param_next is not None:
                for _ in range(2):
                    if self._param_next is not None and self._param_next < len(self.param_names):
                        self._send_param(self._param_next)
                        self._param_next += 1
                    else:
                        self._param_next = None
            for key, period in (("50", 0.02), ("10", 0.1), ("1", 1.0)):
                if t >= nxt[key]:
                    nxt[key] = t + period / self.rate_scale
                    self._telemetry(key, t)
            time.sleep(0.002)

    def _accept(self) -> None:
        with self._lock:
            srv = self._srv
            if srv is None or self._cli is not None:
                return
            try:
                cli, _ = srv.accept()
            except (BlockingIOError, OSError):
                return
            cli.setblocking(False)
            cli.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._cli = cli
            self.connections += 1

    def _read(self) -> None:
        cli = self._cli
        if cli is None:
            return
        try:
            r, _, _ = select.select([cli], [], [], 0.0)
            if not r:
                return
            data = cli.recv(4096)
        except (OSError, ValueError):
            data = b""
        if not data:
            self.drop_client()
            return
        for m in self.mav.parse_buffer(data) or []:
            if m.get_type() == "BAD_DATA":
                self.rejected += 1
                continue
            with self._lock:
                self.received.append(m)
            self._handle(m)

    def _send(self, msg: Any) -> None:
        if self.mute:
            return
        buf = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        cli = self._cli
        if cli is None:
            return
        try:
            cli.sendall(buf)
            self.tx_bytes += len(buf)
        except OSError:
            self.drop_client()

    # ---- protocol --------------------------------------------------------------------------------
    def _ack(self, command: int, result: int, m: Any) -> None:
        self._send(self.mav.command_ack_encode(command, result, 0, 0, m.get_srcSystem(), m.get_srcComponent()))

    def _send_param(self, idx: int) -> None:
        if idx in self.drop_param_indices:
            self.drop_param_indices.discard(idx)  # lost once on air
            return
        name = self.param_names[idx]
        self._send(self.mav.param_value_encode(name.encode(), float(self.params[name]), 6, len(self.param_names), idx))

    def _calib_ack(self, table_id: int, result: int) -> None:
        flags = 32 if self.saved_tables is None else 0
        self._send(self.mav.agnav_calib_ack_encode(table_id, result, 255, flags))

    def _handle(self, m: Any) -> None:
        t = m.get_type()
        now = self.now()
        d = self.d
        if t == "HEARTBEAT":
            self.host_hb_rx = now
        elif t == "AGNAV_DRIVE_SETPOINT":
            self.setpoint, self.setpoint_rx, self.host_hb_rx = m, now, now
        elif t == "COMMAND_LONG":
            c = m.command
            if c == 45900:
                self.estop = m.param1 > 0.5
                self._ack(c, 0, m)
            elif c == 400:
                self.armed = m.param1 > 0.5
                if not self.armed:
                    self.setpoint = None
                self._ack(c, 0, m)
            elif c == 45901 and self.autopilot == "agnav":
                self.behaviours = (1 if m.param1 > 0.5 else 0) | (2 if m.param2 > 0.5 else 0) | (4 if m.param3 > 0.5 else 0)
                self._ack(c, 0, m)
            elif c == d.MAV_CMD_DO_SET_MODE and self.autopilot == "ardupilot":
                self.mode = int(m.param2)
                self._ack(c, 0, m)
            else:
                self._ack(c, 3, m)
        elif t == "PARAM_REQUEST_LIST":
            self._param_next = 0
        elif t == "PARAM_REQUEST_READ":
            idx = m.param_index
            name = m.param_id if isinstance(m.param_id, str) else m.param_id.decode()
            if idx < 0 and name in self.params:
                idx = self.param_names.index(name)
            if 0 <= idx < len(self.param_names):
                self._send_param(idx)
        elif t == "PARAM_SET":
            name = m.param_id if isinstance(m.param_id, str) else m.param_id.decode()
            if name not in self.params:
                self._send(self.mav.statustext_encode(4, b"PARAM_SET: unknown parameter"))
                return
            v = int(round(m.param_value))
            _, lo, hi = FIRMWARE_PARAMS[name]
            if lo <= v <= hi:
                self.params[name] = v
            else:
                self._send(self.mav.statustext_encode(4, b"PARAM_SET: value out of range, refused"))
            self._send_param(self.param_names.index(name))
        elif t == "AGNAV_CALIB_TABLE":
            try:
                tab = from_message(m)
            except ValueError:
                self._calib_ack(m.table_id, 4)
                return
            code, _ = validate(tab)
            if code == 0:
                self.tables[tab.table_id] = tab
            self._calib_ack(m.table_id, code)
        elif t == "AGNAV_CALIB_REQUEST":
            if m.table_id not in self.tables:
                self._calib_ack(m.table_id, 4)
            elif m.action == 1:
                self.saved_tables = dict(self.tables)
                self._calib_ack(m.table_id, 0)
            elif m.action == 2:
                dflt = default_steering_table() if m.table_id == TABLE_STEER else default_speed_table()
                self.tables[m.table_id] = from_calib_table(dflt, m.table_id)
                self._calib_ack(m.table_id, 0)
            else:
                self._send(self.tables[m.table_id].to_message(self.mav))
        elif t == "SET_POSITION_TARGET_LOCAL_NED":
            self.goal = (m.x, -m.y)
        elif t in ("RC_CHANNELS_OVERRIDE", "MANUAL_CONTROL"):
            self.host_hb_rx = now

    # ---- behaviour + plant -----------------------------------------------------------------------
    def arbitration(self) -> tuple[int, int, int, float, float, tuple[int, int, bool] | None]:
        """(layer, reason, flags, steer_rad, speed_m_s, raw) like the firmware's behaviour output."""
        now = self.now()
        flags = (1 if self.estop else 0) | (32 if self.saved_tables is None else 0)
        fresh = self.setpoint is not None and now - self.setpoint_rx < self.link_timeout_s
        lost = now - self.host_hb_rx > self.link_timeout_s
        if self.estop:
            return 1, 1, flags, 0.0, 0.0, None
        if lost:
            return 1, 2, flags | 2, 0.0, 0.0, None
        if fresh and self.armed:
            sp = self.setpoint
            if sp.mode == 1:
                return 5, 12, flags, 0.0, 0.0, (sp.steer_pwm, sp.speed_pwm, sp.speed_mm_s < 0)
            return 5, 12, flags, cdeg_to_rad(sp.steer_cdeg), milli_to_si(sp.speed_mm_s), None
        return 0, 15, flags, 0.0, 0.0, None

    def _step(self, dt: float) -> None:
        c = self.car
        if self.autopilot == "ardupilot":
            return
        layer, reason, flags, steer, speed, raw = self.arbitration()
        if raw is not None:
            steer_pwm, speed_pwm, rev = raw
            odom_steer = 0.0
        else:
            steer_pwm = self.tables[TABLE_STEER].pwm(int(round(rad_to_cdeg(steer))))
            speed_pwm = self.tables[TABLE_SPEED].pwm(int(round(si_to_milli(abs(speed)))))
            rev = speed < 0
            odom_steer = steer
        phi = float(self.true_steer.value_from_pwm(steer_pwm))
        v = float(self.true_speed.value_from_pwm(speed_pwm)) * (-1.0 if rev else 1.0)
        c.phi, c.v = phi, v
        c.yaw_rate = v * math.tan(phi) / self.L
        c.x += v * math.cos(c.yaw) * dt
        c.y += v * math.sin(c.yaw) * dt
        c.yaw = norm_angle_rad(c.yaw + c.yaw_rate * dt)
        half = self.track / 2.0 * math.tan(phi) / self.L
        c.wheel_v = [v * (1 - half), v * (1 + half)]
        nm = self.params["ENC_NM_PER_CNT"] * 1e-9
        for i in range(2):
            c.counts[i] += c.wheel_v[i] * dt / nm
        # firmware odometry: distance from the encoders, heading from the commanded steering angle
        c.odom_rate = v * math.tan(odom_steer) / self.L
        c.odom_x += v * math.cos(c.odom_yaw) * dt
        c.odom_y += v * math.sin(c.odom_yaw) * dt
        c.odom_yaw = norm_angle_rad(c.odom_yaw + c.odom_rate * dt)

    def _telemetry(self, key: str, t: float) -> None:
        ms = int(si_to_milli(t)) & 0xFFFFFFFF
        c = self.car
        if self.autopilot == "ardupilot":
            if key == "1":
                self._send(self.mav.heartbeat_encode(self.d.MAV_TYPE_GROUND_ROVER, self.d.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                                     self.d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                                                     | (self.d.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0),
                                                     self.mode, self.d.MAV_STATE_ACTIVE))
            elif key == "10":
                self._send(self.mav.local_position_ned_encode(ms, c.x, -c.y, 0.0, c.v * math.cos(c.yaw),
                                                              -c.v * math.sin(c.yaw), 0.0))
                self._send(self.mav.attitude_encode(ms, 0.0, 0.0, -c.yaw, 0.0, 0.0, -c.yaw_rate))
            return
        layer, reason, flags, steer, speed, _ = self.arbitration()
        if key == "50":
            self._send(self.mav.agnav_behaviour_status_encode(ms, layer, reason, flags,
                                                              int(round(rad_to_cdeg(steer))),
                                                              int(round(si_to_milli(speed)))))
        elif key == "10":
            self._send(self.mav.agnav_odometry_encode(ms, int(si_to_milli(c.odom_x)), int(si_to_milli(c.odom_y)),
                                                      int(round(rad_to_cdeg(c.odom_yaw))),
                                                      int(round(si_to_milli(c.v))),
                                                      int(round(rad_to_cdeg(c.odom_rate)))))
            noise = self.rng.normal(0.0, self.speed_noise, 2) if self.speed_noise > 0 else (0.0, 0.0)
            sp = [int(round(si_to_milli(c.wheel_v[i] + noise[i]))) for i in range(2)]
            self._send(self.mav.agnav_encoder_status_encode(ms, [int(c.counts[0]), int(c.counts[1]), 0, 0],
                                                            sp + [0, 0], [0, 0, 0, 0], 2))
            if self.has_sonar:
                ranges = [int(2000 + 100 * i) for i in range(12)]
                self._send(self.mav.agnav_sonar_ring_encode(ms, ranges, [0] * 12, 12, int(t * 10) & 0xFFFF))
        else:
            self._send(self.mav.named_value_int_encode(ms, b"T_control", 250))
            state = self.d.MAV_STATE_CRITICAL if flags & 3 else self.d.MAV_STATE_ACTIVE
            self._send(self.mav.heartbeat_encode(self.d.MAV_TYPE_GROUND_ROVER, self.d.MAV_AUTOPILOT_GENERIC,
                                                 self.d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, layer, state))
