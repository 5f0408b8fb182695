"""Host side of the link: the MAVLink endpoint the host planner uses (sim or real radio alike).

It only turns calls into bytes and bytes into state: :meth:`HostEndpoint.feed` takes what the
radio delivered, :meth:`HostEndpoint.take_tx` returns what to put on the radio. Units on the
wire are the firmware's (cdeg, mm/s, mm); helpers take SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

from ..protocol import dialect, new_codec

__all__ = ["HostEndpoint", "Odometry", "BehaviourStatus", "SonarRingFrame"]

MAV_CMD_AGNAV_SET_BEHAVIOURS = 45901


@dataclass(frozen=True)
class Odometry:
    t_us: int  # host receive time
    time_boot_ms: int
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    yaw_rate_rad_s: float


@dataclass(frozen=True)
class BehaviourStatus:
    t_us: int
    time_boot_ms: int
    layer: int
    reason: int
    failsafe_flags: int
    steer_cdeg: int
    speed_mm_s: int


@dataclass(frozen=True)
class SonarRingFrame:
    t_us: int
    time_boot_ms: int
    ranges_mm: tuple[int, ...]
    status: tuple[int, ...]
    seq: int


class LeanMessage:
    """A decoded message of the lean path: ``get_type()`` and the fields as attributes (the
    values pymavlink's decoder gives: ints, floats, lists for arrays)."""

    __slots__ = ("_type", "__dict__")

    def __init__(self, msg_type: str, fields: dict[str, Any]) -> None:
        self._type = msg_type
        self.__dict__ = fields

    def get_type(self) -> str:
        return self._type

    def to_dict(self) -> dict[str, Any]:
        return {"mavpackettype": self._type, **self.__dict__}

    def __repr__(self) -> str:
        return f"{self._type} {self.__dict__}"


# pymavlink's objects are kept for these (callers may use their headers); text fields need
# pymavlink's string handling: both never take the lean path
_KEEP_PYMAVLINK = frozenset({"COMMAND_ACK", "AGNAV_CALIB_ACK", "PARAM_VALUE", "STATUSTEXT"})


def _lean_decoders(d: Any) -> dict[int, Callable[[bytes, int, int], LeanMessage | None]]:
    """msg id -> decoder(buf, start, end) of one unsigned MAVLink 2 frame, for every message of
    the dialect without text fields that the endpoint does not keep as pymavlink objects. The
    decoder returns None on a CRC mismatch (pymavlink then reports the frame as bad data)."""
    try:
        from fastcrc.crc16 import mcrf4xx  # what pymavlink's x25crc uses when installed

        def crc16(b: bytes) -> int:
            return mcrf4xx(b, 0xFFFF)
    except ImportError:  # pymavlink's own implementation
        def crc16(b: bytes) -> int:
            return int(d.x25crc(b).crc)
    out: dict[int, Callable[[bytes, int, int], LeanMessage | None]] = {}
    for msgid, cls in d.mavlink_map.items():
        if cls.msgname in _KEEP_PYMAVLINK or "char" in cls.fieldtypes:
            continue
        out[msgid] = _make_decoder(cls, crc16)
    return out


def _make_decoder(cls: Any, crc16: Callable[[bytes], int]) -> Callable[[bytes, int, int], LeanMessage | None]:
    unpack = cls.unpacker.unpack
    size = cls.unpacker.size
    extra = bytes([cls.crc_extra])
    name = cls.msgname
    names = tuple(cls.fieldnames)
    lens = cls.lengths
    # pymavlink's decode(): wire tuple -> field values in declaration order, arrays as lists
    picks = []
    for order in cls.orders:
        tip = sum(lens[:order])
        picks.append((tip, lens[order]))
    plain = all(n == 1 for _, n in picks)
    idx = tuple(tip for tip, _ in picks)

    def decode(buf: bytes, i: int, end: int) -> LeanMessage | None:
        if crc16(buf[i + 1:end - 2] + extra) != buf[end - 2] | buf[end - 1] << 8:
            return None
        payload = buf[i + 10:end - 2]
        if len(payload) < size:
            payload += bytes(size - len(payload))  # MAVLink 2 drops trailing zero bytes
        t = unpack(payload[:size])
        if plain:
            return LeanMessage(name, dict(zip(names, [t[k] for k in idx])))
        return LeanMessage(name, dict(zip(names, [t[tip] if n == 1 else list(t[tip:tip + n]) for tip, n in picks])))

    return decode


@dataclass
class HostEndpoint:
    """MAVLink endpoint of the host (system 255, component 190 by default)."""

    target_system: int = 1
    target_component: int = 1
    sysid: int = 255
    compid: int = 190
    keep_history: bool = True
    odometry: Odometry | None = None
    status: BehaviourStatus | None = None
    sonar: SonarRingFrame | None = None
    heartbeat_seen_us: int | None = None
    sys_status: Any = None  # the latest SYS_STATUS (health bits, refusal and signing counters)
    odometry_log: list[Odometry] = field(default_factory=list)
    status_log: list[BehaviourStatus] = field(default_factory=list)
    sonar_log: list[SonarRingFrame] = field(default_factory=list)
    acks: list[Any] = field(default_factory=list)
    calib_acks: list[Any] = field(default_factory=list)
    params: dict[str, int] = field(default_factory=dict)
    statustexts: list[tuple[int, str]] = field(default_factory=list)
    rx_counts: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._mav = new_codec(self.sysid, self.compid)
        self._d = dialect()
        self._tx = bytearray()
        self._seq = 0
        self._lean = _lean_decoders(self._d)

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, msg: Any) -> None:
        self._tx += msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256

    def take_tx(self) -> bytes:
        out = bytes(self._tx)
        self._tx.clear()
        return out

    def heartbeat(self) -> None:
        d = self._d
        self._send(d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, d.MAV_STATE_ACTIVE, 3))

    def setpoint(self, steer_cdeg: int, speed_mm_s: int) -> None:
        d = self._d
        self._seq = (self._seq + 1) & 0xFFFF
        s = max(-32767, min(32767, int(round(steer_cdeg))))
        v = max(-32767, min(32767, int(round(speed_mm_s))))
        self._send(d.MAVLink_agnav_drive_setpoint_message(self.target_system, self.target_component, s, v, 0, 0,
                                                          d.AGNAV_DRIVE_PHYSICAL, self._seq))

    def setpoint_si(self, steer_rad: float, speed_m_s: float) -> None:
        self.setpoint(math.degrees(steer_rad) * 100.0, speed_m_s * 1000.0)

    def command_long(self, command: int, *params: float) -> None:
        p = [float(x) for x in params] + [0.0] * (7 - len(params))
        self._send(self._d.MAVLink_command_long_message(self.target_system, self.target_component, command, 0, *p[:7]))

    def set_behaviours(self, follow_wall: bool, goal_seek: bool = False, avoid: bool = True) -> None:
        self.command_long(MAV_CMD_AGNAV_SET_BEHAVIOURS, int(follow_wall), int(goal_seek), int(avoid))

    def arm(self) -> None:
        self.command_long(self._d.MAV_CMD_COMPONENT_ARM_DISARM, 1)

    def param_set(self, name: str, value: int) -> None:
        d = self._d
        self._send(d.MAVLink_param_set_message(self.target_system, self.target_component, name.encode(), float(value),
                                               d.MAV_PARAM_TYPE_INT32))

    def calib_table(self, table_id: int, pwm: list[int], value: list[int], neutral_pwm: int) -> None:
        n = len(pwm)
        pw = list(pwm) + [0] * (16 - n)
        va = list(value) + [0] * (16 - n)
        self._send(self._d.MAVLink_agnav_calib_table_message(self.target_system, self.target_component, table_id, n, pw, va,
                                                             neutral_pwm, neutral_pwm, neutral_pwm))

    def calib_request(self, table_id: int, action: int) -> None:
        """AGNAV_CALIB_REQUEST: 0 read, 1 save all tables to EEPROM, 2 load defaults."""
        self._send(self._d.MAVLink_agnav_calib_request_message(self.target_system, self.target_component, table_id, action))

    # ---- receiving -------------------------------------------------------------------------------------
    def feed(self, t_us: int, data: bytes) -> list[Any]:
        """Decode what the radio delivered and update the state; returns the messages.

        Unsigned MAVLink 2 frames of the telemetry the endpoint only reads (odometry, status, sonar,
        heartbeat, ...) are decoded here, as pymavlink decodes them (CRC with CRC_EXTRA, trailing
        zero bytes restored) but returned as light :class:`LeanMessage` objects; every other frame
        (acknowledgements, parameters, text, MAVLink 1, signed, corrupt or stray bytes, a partial
        frame) goes to pymavlink as before."""
        if not data:
            return []
        mav = self._mav
        if mav.buf_len() > 0:  # pymavlink holds part of a frame: it continues the stream
            msgs = mav.parse_buffer(data) or []
            for m in msgs:
                self._handle(t_us, m)
            return msgs
        out: list[Any] = []
        lean = self._lean
        n = len(data)
        i = 0
        while i < n:
            if data[i] != 0xFD or n - i < 12 or data[i + 2] != 0:
                break  # not a complete unsigned MAVLink 2 header here: pymavlink from this byte on
            end = i + 12 + data[i + 1]
            if end > n:
                break
            dec = lean.get(data[i + 7] | data[i + 8] << 8 | data[i + 9] << 16)
            m = dec(data, i, end) if dec is not None else None
            if m is None:  # a message kept as pymavlink's object, or a bad CRC: pymavlink decides
                ms = mav.parse_buffer(data[i:end]) or []
                for x in ms:
                    self._handle(t_us, x)
                out += ms
            else:
                self._handle(t_us, m)
                out.append(m)
            i = end
        if i < n:
            ms = mav.parse_buffer(data[i:]) or []
            for x in ms:
                self._handle(t_us, x)
            out += ms
        return out

    def _handle(self, t_us: int, m: Any) -> None:
        kind = m.get_type()
        self.rx_counts[kind] = self.rx_counts.get(kind, 0) + 1
        if kind == "AGNAV_ODOMETRY":
            o = Odometry(t_us, m.time_boot_ms, m.x_mm * 1e-3, m.y_mm * 1e-3, math.radians(m.yaw_cdeg / 100.0),
                         m.speed_mm_s * 1e-3, math.radians(m.yaw_rate_cdeg_s / 100.0))
            self.odometry = o
            if self.keep_history:
                self.odometry_log.append(o)
        elif kind == "AGNAV_BEHAVIOUR_STATUS":
            s = BehaviourStatus(t_us, m.time_boot_ms, m.active_layer, m.reason, m.failsafe_flags, m.steer_cdeg, m.speed_mm_s)
            self.status = s
            if self.keep_history:
                self.status_log.append(s)
        elif kind == "AGNAV_SONAR_RING":
            f = SonarRingFrame(t_us, m.time_boot_ms, tuple(m.ranges_mm), tuple(m.status), m.seq)
            self.sonar = f
            if self.keep_history:
                self.sonar_log.append(f)
        elif kind == "HEARTBEAT":
            self.heartbeat_seen_us = t_us
        elif kind == "COMMAND_ACK":
            self.acks.append(m)
        elif kind == "SYS_STATUS":
            self.sys_status = m
        elif kind == "AGNAV_CALIB_ACK":
            self.calib_acks.append(m)
        elif kind == "PARAM_VALUE":
            pid = m.param_id if isinstance(m.param_id, str) else m.param_id.decode()
            self.params[pid] = int(round(m.param_value))
        elif kind == "STATUSTEXT":
            txt = m.text if isinstance(m.text, str) else m.text.decode(errors="replace")
            self.statustexts.append((t_us, txt.rstrip("\x00")))
