"""AgNav commands over an :class:`~agnav_host.link.endpoint.Endpoint` (SI units in, wire units out).

    robot = AgnavRobot(ep)
    robot.drive(steer_rad=0.1, speed_m_s=0.5)      # AGNAV_DRIVE_SETPOINT, physical mode
    robot.drive_raw(steer_pwm=140, speed_pwm=40)   # calibration mode (raw actuator units)
    robot.estop(); robot.release(); robot.arm()
    robot.set_behaviours(follow_wall=False, goal_seek=True, avoid=True)
    robot.set_goal(3.0, -1.5)                      # SET_POSITION_TARGET_LOCAL_NED (y -> -y)
    robot.param_list(); robot.param_get("MAX_SPEED_MM_S"); robot.param_set("MAX_SPEED_MM_S", 800)
    robot.calib_read(TABLE_STEER); robot.calib_write(table); robot.calib_save()

Commands that the firmware acknowledges (COMMAND_ACK, PARAM_VALUE, AGNAV_CALIB_ACK/TABLE) are
retried on timeout and raise :class:`CommandFailed` / :class:`~.endpoint.LinkTimeout`; setpoints are
fire-and-forget (the firmware's link-loss failsafe covers a lost stream: keep sending at >= 5 Hz).
"""

from __future__ import annotations

import math
import time
from typing import Any

from ..types import DriveCommand
from ..units import rad_to_cdeg, si_to_milli, to_int16
from .calib_wire import CALIB_IN_PROGRESS, RESULT_NAMES, TABLE_NAMES, WireTable, from_message, round_trips, validate
from .endpoint import Endpoint, LinkTimeout

__all__ = ["AgnavRobot", "CommandFailed", "MAV_CMD_AGNAV_ESTOP", "MAV_CMD_AGNAV_SET_BEHAVIOURS",
           "drive_to_wire", "steer_from_drive_command"]

MAV_CMD_AGNAV_ESTOP = 45900
MAV_CMD_AGNAV_SET_BEHAVIOURS = 45901
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_PREFLIGHT_STORAGE = 245
MAV_RESULT_IN_PROGRESS = 5
MAV_RESULT_NAMES = {0: "ACCEPTED", 1: "TEMPORARILY_REJECTED", 2: "DENIED", 3: "UNSUPPORTED", 4: "FAILED",
                    5: "IN_PROGRESS", 6: "CANCELLED"}
CALIB_ACTION_READ, CALIB_ACTION_SAVE, CALIB_ACTION_DEFAULTS = 0, 1, 2
MAV_PARAM_TYPE_INT32 = 6


class CommandFailed(RuntimeError):
    """The robot answered but refused (the message says why)."""


def drive_to_wire(steer_rad: float, speed_m_s: float) -> tuple[int, int]:
    """(steer_cdeg, speed_mm_s), rounded and clamped to int16."""
    if not (math.isfinite(steer_rad) and math.isfinite(speed_m_s)):
        raise ValueError("drive setpoint must be finite")
    return to_int16(rad_to_cdeg(steer_rad)), to_int16(si_to_milli(speed_m_s))


def steer_from_drive_command(cmd: DriveCommand, kinematics: str, wheelbase_m: float, track_m: float,
                             max_steer_rad: float) -> float:
    """Steering angle the firmware takes for a planner command.

    Ackermann: ``steer_rad`` if given, else phi = atan(L * yaw_rate / v). Differential drive: the
    firmware turns the angle back into a yaw rate as omega = v tan(phi) / track (drive.h), so
    phi = atan(track * yaw_rate / v). At v = 0 no angle gives a yaw rate: 0 is returned."""
    if cmd.steer_rad is not None:
        phi = cmd.steer_rad
    elif abs(cmd.speed_m_s) < 1e-3:
        phi = 0.0
    else:
        base = wheelbase_m if kinematics == "ackermann" else track_m
        phi = math.atan(base * cmd.yaw_rate_rad_s / cmd.speed_m_s)
    return max(-max_steer_rad, min(max_steer_rad, phi))


class AgnavRobot:
    """Typed AgNav commands on top of an endpoint (see module docstring)."""

    def __init__(self, ep: Endpoint, timeout_s: float = 1.0, retries: int = 3) -> None:
        self.ep = ep
        self.timeout_s = timeout_s
        self.storage_timeout_s = 10.0  # a save's final answer (the AVR writes ~0.5 KB at 3.3 ms a byte)
        self.retries = retries
        self._seq = 0

    @property
    def mav(self) -> Any:
        return self.ep.mav

    @property
    def state(self) -> Any:
        return self.ep.state

    def _tgt(self) -> tuple[int, int]:
        return self.ep.target_system, self.ep.target_component

    # ---- setpoints ------------------------------------------------------------------------------
    def drive(self, steer_rad: float, speed_m_s: float) -> bool:
        """Physical setpoint for the HOST_COMMAND layer (positive steer = left)."""
        steer, speed = drive_to_wire(steer_rad, speed_m_s)
        self._seq = (self._seq + 1) % 65536
        return self.ep.send(self.mav.agnav_drive_setpoint_encode(*self._tgt(), steer, speed, 0, 0, 0, self._seq))

    def drive_raw(self, steer_pwm: int, speed_pwm: int, reverse: bool = False) -> bool:
        """Calibration mode: table units straight to the outputs (the speed direction is the sign of
        speed_mm_s, so reverse sends -1)."""
        for n, v in (("steer_pwm", steer_pwm), ("speed_pwm", speed_pwm)):
            if not 0 <= int(v) <= 65535:
                raise ValueError(f"{n} {v} outside 0..65535")
        self._seq = (self._seq + 1) % 65536
        return self.ep.send(self.mav.agnav_drive_setpoint_encode(*self._tgt(), 0, -1 if reverse else 0,
                                                                 int(steer_pwm), int(speed_pwm), 1, self._seq))

    def stop(self) -> bool:
        """Zero physical setpoint (the robot brakes to a stop through its tables)."""
        return self.drive(0.0, 0.0)

    # ---- commands -----------------------------------------------------------------------------
    def command(self, command: int, *params: float, what: str = "") -> int:
        """COMMAND_LONG with retries; returns MAV_RESULT, raises CommandFailed unless ACCEPTED."""
        p = (list(params) + [0.0] * 7)[:7]
        attempt = [0]

        def make() -> Any:
            attempt[0] += 1
            return self.mav.command_long_encode(*self._tgt(), command, attempt[0] - 1, *p)

        ack = self._until_final(lambda: self.ep.request(make, "COMMAND_ACK", lambda m: m.command == command,
                                                        self.timeout_s, self.retries, what or f"command {command}"),
                                "COMMAND_ACK", lambda m: m.command == command, MAV_RESULT_IN_PROGRESS,
                                what or f"command {command}")
        if ack.result != 0:
            raise CommandFailed(f"{what or command}: {MAV_RESULT_NAMES.get(ack.result, ack.result)}")
        return int(ack.result)

    def _until_final(self, ask: Any, types: str, match: Any, in_progress: int, what: str) -> Any:
        """``ask()``'s answer, or when it says ``in_progress`` (a save the robot writes in the background), the
        next matching answer that does not, within ``storage_timeout_s``. The request is not repeated meanwhile:
        a repeat would start the write again."""
        with self.ep.subscribe(types, match) as later:
            m = ask()
            end = time.monotonic() + self.storage_timeout_s
            while m.result == in_progress:
                left = end - time.monotonic()
                n = later.get(left) if left > 0 else None
                if n is None:
                    raise LinkTimeout(f"{what}: the robot answered IN_PROGRESS and no result came within "
                                      f"{self.storage_timeout_s:.0f} s")
                m = n
        return m

    def params_store(self) -> int:
        """Write the robot's parameters to its EEPROM (MAV_CMD_PREFLIGHT_STORAGE 1): answered IN_PROGRESS, then
        ACCEPTED once both slots are written and read back (about 2 s on the AVR)."""
        return self.command(MAV_CMD_PREFLIGHT_STORAGE, 1.0, what="param store")

    def estop(self, engage: bool = True) -> int:
        return self.command(MAV_CMD_AGNAV_ESTOP, 1.0 if engage else 0.0, what="estop" if engage else "estop release")

    def release(self) -> int:
        return self.estop(False)

    def arm(self, arm: bool = True) -> int:
        return self.command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0 if arm else 0.0, what="arm" if arm else "disarm")

    def set_behaviours(self, follow_wall: bool = False, goal_seek: bool = False, avoid: bool = True) -> int:
        return self.command(MAV_CMD_AGNAV_SET_BEHAVIOURS, float(follow_wall), float(goal_seek), float(avoid),
                            what="set behaviours")

    def set_goal(self, x_m: float, y_m: float) -> bool:
        """Goal for the firmware's MOVE_TO_GOAL layer, odometry frame (REP-103; sent as NED)."""
        mask = 0b0000_1101_1111_1000  # use x, y, z; ignore velocity, acceleration, yaw, yaw rate
        return self.ep.send(self.mav.set_position_target_local_ned_encode(
            0, *self._tgt(), 1, mask, float(x_m), -float(y_m), 0.0, 0, 0, 0, 0, 0, 0, 0, 0))

    # ---- parameters ----------------------------------------------------------------------------
    def param_get(self, name: str) -> float:
        pid = _param_id(name)
        m = self.ep.request(lambda: self.mav.param_request_read_encode(*self._tgt(), pid, -1),
                            "PARAM_VALUE", lambda m: _pid(m) == name, self.timeout_s, self.retries, f"param get {name}")
        return float(m.param_value)

    def param_set(self, name: str, value: float) -> float:
        """Set and confirm; raises CommandFailed if the robot keeps another value (out of range).

        An answer with another value may be a late answer to an earlier request for the same name (a
        slow radio), so it confirms nothing until the tries are used up: only then is it taken as the
        value the robot kept."""
        pid = _param_id(name)
        m = self.ep.request(lambda: self.mav.param_set_encode(*self._tgt(), pid, float(value), MAV_PARAM_TYPE_INT32),
                            "PARAM_VALUE", lambda m: _pid(m) == name, self.timeout_s, self.retries, f"param set {name}",
                            accept=lambda m: abs(float(m.param_value) - float(value)) <= 0.5)
        if abs(float(m.param_value) - float(value)) <= 0.5:
            return float(m.param_value)
        raise CommandFailed(f"param {name}: robot kept {m.param_value:g} (asked {value:g}; out of range?)")

    def param_list(self, timeout_s: float = 10.0, quiet_s: float = 0.5) -> dict[str, float]:
        """PARAM_REQUEST_LIST, then PARAM_REQUEST_READ by index for any the link lost.

        The firmware paces the list itself (2 per link poll) and drops frames when its UART queue is
        full, so gaps are normal on a radio; they are filled one by one."""
        got: dict[int, tuple[str, float]] = {}
        count: int | None = None
        deadline = time.monotonic() + timeout_s
        with self.ep.subscribe("PARAM_VALUE") as sub:
            self.ep.send(self.mav.param_request_list_encode(*self._tgt()))
            while time.monotonic() < deadline:
                m = sub.get(quiet_s)
                if m is None:
                    break
                count = m.param_count
                got[m.param_index] = (_pid(m), float(m.param_value))
                if count is not None and len(got) >= count:
                    break
            if count is None:
                raise LinkTimeout("param list: no PARAM_VALUE received")
            for idx in range(count):
                while idx not in got and time.monotonic() < deadline:
                    self.ep.send(self.mav.param_request_read_encode(*self._tgt(), b"", idx))
                    end = time.monotonic() + self.timeout_s
                    while time.monotonic() < end and idx not in got:
                        m = sub.get(end - time.monotonic())
                        if m is not None:
                            got[m.param_index] = (_pid(m), float(m.param_value))
            missing = [i for i in range(count) if i not in got]
            if missing:
                raise LinkTimeout(f"param list: indices {missing} never arrived")
        return {got[i][0]: got[i][1] for i in range(count)}

    # ---- calibration tables ----------------------------------------------------------------------
    def calib_read(self, table_id: int) -> WireTable:
        m = self.ep.request(lambda: self.mav.agnav_calib_request_encode(*self._tgt(), table_id, CALIB_ACTION_READ),
                            ["AGNAV_CALIB_TABLE", "AGNAV_CALIB_ACK"], lambda m: m.table_id == table_id,
                            self.timeout_s, self.retries, f"calib read {TABLE_NAMES.get(table_id, table_id)}")
        if m.get_type() == "AGNAV_CALIB_ACK":
            raise CommandFailed(f"calib read {table_id}: {RESULT_NAMES.get(m.result, m.result)}")
        return from_message(m)

    def _calib_ack(self, make: Any, table_id: int, what: str) -> int:
        m = self._until_final(lambda: self.ep.request(make, "AGNAV_CALIB_ACK", lambda m: m.table_id == table_id,
                                                      self.timeout_s, self.retries, what),
                              "AGNAV_CALIB_ACK", lambda m: m.table_id == table_id, CALIB_IN_PROGRESS, what)
        if m.result != 0:
            raise CommandFailed(f"{what}: {RESULT_NAMES.get(m.result, m.result)}")
        return int(m.failsafe_flags)

    def calib_write(self, table: WireTable, check: bool = True) -> int:
        """Write a table (active at once, not saved); returns the robot's failsafe flags."""
        if check:
            code, why = validate(table)
            if code != 0:
                raise CommandFailed(f"calib write {TABLE_NAMES.get(table.table_id)}: {RESULT_NAMES[code]} ({why})")
            if not round_trips(table):
                raise CommandFailed(f"calib write: the robot would split this table differently: {table.describe()}")
        return self._calib_ack(lambda: table.to_message(self.mav, *self._tgt()), table.table_id,
                               f"calib write {TABLE_NAMES.get(table.table_id, table.table_id)}")

    def calib_save(self, table_id: int = 0) -> int:
        """Write all active tables to EEPROM (the robot verifies by read-back)."""
        return self._calib_ack(lambda: self.mav.agnav_calib_request_encode(*self._tgt(), table_id, CALIB_ACTION_SAVE),
                               table_id, "calib save")

    def calib_defaults(self, table_id: int) -> int:
        return self._calib_ack(lambda: self.mav.agnav_calib_request_encode(*self._tgt(), table_id,
                                                                          CALIB_ACTION_DEFAULTS),
                               table_id, "calib defaults")

    def calib_write_verified(self, table: WireTable, save: bool = True) -> WireTable:
        """Write, read back and compare, then (optionally) save. Returns the read-back table."""
        self.calib_write(table)
        back = self.calib_read(table.table_id)
        if back.neutral_pwm != table.neutral_pwm or back.points() != table.points():
            raise CommandFailed(f"calib verify: read-back differs\n  sent {table.describe()}\n  got  {back.describe()}")
        if save:
            self.calib_save(table.table_id)
        return back


def _param_id(name: str) -> bytes:
    """A parameter name as MAVLink carries it: ASCII, 1 to 16 characters. A longer name would be cut to
    16 on the wire and read or set another parameter (AVOID_BACKOFF_MS_X is AVOID_BACKOFF_MS there)."""
    try:
        raw = name.encode("ascii")
    except UnicodeEncodeError:
        raise ValueError(f"parameter name {name!r} is not ASCII") from None
    if not 1 <= len(raw) <= 16:
        raise ValueError(f"parameter name {name!r} has {len(raw)} characters; MAVLink carries 1 to 16")
    return raw


def _pid(m: Any) -> str:
    v = m.param_id
    if isinstance(v, (bytes, bytearray)):
        v = v.decode("ascii", "replace")
    return str(v).split("\x00", 1)[0]
