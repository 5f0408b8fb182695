"""Bad commands and signing in the SIL: the robot drives (or stands) on host setpoints, and at 3 s
the host starts sending something it should not - absurd numbers, NaN, commands for another robot,
truncated frames, and with a key set: unsigned, wrongly signed and replayed frames. The firmware
must refuse or clamp with a reason (COMMAND_ACK / STATUSTEXT), count what it dropped, and never act
on it: the true robot speed from the world simulator is the judge.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable

from ._core import FaultCase, FaultOutcome
from .link_faults import SPEED_MM_S, TICK_MS, DriveTrace, drive_with_link_faults

if TYPE_CHECKING:
    from ..sil import SilSession

__all__ = ["COMMAND_CASES", "SIGNING_CASES"]

T_BAD_S = 3.0
KEY = bytes(range(1, 33))
OTHER_KEY = bytes([0x5A] * 32)
NOW_S = 1.8e9  # fixed wall clock for signing timestamps: runs are repeatable
MAX_SPEED_MM_S = 1000  # MAX_SPEED_MM_S firmware parameter default


class _Sender:
    """Host logic: heartbeat + a good setpoint every 100 ms until T_BAD_S; from then on ``bad(s)``
    instead of the setpoint (heartbeats continue unless ``bad_replaces_heartbeat``)."""

    def __init__(self, bad: Callable[[SilSession], None], good: bool = True, replace_hb: bool = False,
                 keep_good: bool = False) -> None:
        self.bad = bad
        self.good = good
        self.replace_hb = replace_hb
        self.keep_good = keep_good  # good setpoints go on next to the bad input
        self.next_us = 0
        self.t0_us = 0

    def __call__(self, s: SilSession, t_us: int) -> None:
        if t_us < self.next_us:
            return
        self.next_us = t_us + 100_000
        late = (t_us - self.t0_us) * 1e-6 >= T_BAD_S
        if not (late and self.replace_hb):
            s.host.heartbeat()
        if late:
            self.bad(s)
        if self.good and (not late or self.keep_good):
            s.host.setpoint(0, SPEED_MM_S)


def _run(bad: Callable[[SilSession], None], seconds: float = T_BAD_S + 3.0, good: bool = True,
         replace_hb: bool = False, keep_good: bool = False) -> DriveTrace:
    return drive_with_link_faults(seconds, seed=9, driver=_Sender(bad, good, replace_hb, keep_good))


def _stopped_within(tr: DriveTrace, t_us: int, limit_ms: float) -> float:
    t_stop = tr.first_stop_after(t_us)
    return (t_stop - t_us) / 1000.0 if t_stop is not None and (t_stop - t_us) / 1000.0 <= limit_ms else math.inf


# ---- bad commands ------------------------------------------------------------------------------------
def _case_absurd_speed() -> FaultOutcome:
    tr = _run(lambda s: s.host.setpoint(0, 30000))
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    v_max = max(tr.speeds_after(t_bad))
    stop_ms = _stopped_within(tr, t_bad, 200.0)
    txt = tr.texts_after(t_bad)
    moved_after = any(tr.moving[tr.index_at(t_bad) + 60:])  # 120 ms after the first bad frame
    ok = v_max <= SPEED_MM_S / 1000 * 1.05 and stop_ms < math.inf and not moved_after and bool(txt)
    return FaultOutcome(f"refused: STATUSTEXT \"{txt[0] if txt else 'NONE'}\", outputs neutral {stop_ms:.0f} ms "
                        f"after the first bad setpoint and kept there; top speed afterwards {v_max:.2f} m/s", ok)


def _case_clamped_speed() -> FaultOutcome:
    tr = _run(lambda s: s.host.setpoint(0, 5000), seconds=T_BAD_S + 6.0)
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    v_max = max(tr.speeds_after(t_bad))
    ok = v_max <= MAX_SPEED_MM_S / 1000 * 1.05 and v_max > SPEED_MM_S / 1000 * 1.2
    return FaultOutcome(f"5 m/s asked: robot accelerated to {v_max:.2f} m/s and no further "
                        f"(MAX_SPEED_MM_S {MAX_SPEED_MM_S})", ok)


def _case_nan_command() -> FaultOutcome:
    tr = _run(lambda s: s.host.command_long(45900, float("nan")), keep_good=True)  # MAV_CMD_AGNAV_ESTOP, param1 NaN
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    res = [(a.command, a.result, getattr(a, "result_param2", None)) for a in tr.acks if a.command == 45900]
    still_driving = not any(not m for m in tr.moving[tr.index_at(t_bad):])
    ok = bool(res) and all(r[1] == 2 for r in res) and still_driving  # MAV_RESULT_DENIED
    return FaultOutcome(f"{len(res)} x COMMAND_ACK result {res[0][1] if res else '-'} (DENIED) reason "
                        f"{res[0][2] if res else '-'}; e-stop not engaged, robot "
                        f"{'kept driving' if still_driving else 'STOPPED'}", ok)


def _case_unknown_command() -> FaultOutcome:
    tr = _run(lambda s: s.host.command_long(31999, 1.0))
    res = [a.result for a in tr.acks if a.command == 31999]
    ok = bool(res) and all(r == 3 for r in res)  # MAV_RESULT_UNSUPPORTED
    return FaultOutcome(f"{len(res)} x COMMAND_ACK result {res[0] if res else '-'} (UNSUPPORTED)", ok)


def _case_nan_goal() -> FaultOutcome:
    def bad(s: SilSession) -> None:
        d = s.host._d  # noqa: SLF001
        s.host._send(d.MAVLink_set_position_target_local_ned_message(  # noqa: SLF001
            0, s.host.target_system, s.host.target_component, d.MAV_FRAME_LOCAL_NED, 0b110111111000,
            float("nan"), 2.0, 0, 0, 0, 0, 0, 0, 0, 0, 0))

    tr = _run(bad)
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    txt = tr.texts_after(t_bad)
    ok = bool(txt) and any("goal" in t.lower() or "position" in t.lower() for t in txt)
    return FaultOutcome(f"STATUSTEXT \"{txt[0] if txt else 'NONE'}\"; no goal taken", ok)


def _case_other_system() -> FaultOutcome:
    def bad(s: SilSession) -> None:
        h = s.host
        h.target_system = 7
        h.setpoint(0, SPEED_MM_S)
        h.target_system = 1

    tr = _run(bad, good=False)  # never a setpoint for us: heartbeats, then setpoints for system 7
    moved = any(tr.moving)
    dist = tr.x_m[-1] - tr.x_m[0]
    ok = not moved and abs(dist) < 1e-3
    return FaultOutcome(f"3 s of setpoints addressed to system 7: robot (system 1) {'MOVED' if moved else 'stayed still'} "
                        f"({dist * 1000:.1f} mm)", ok)


def _case_truncated() -> FaultOutcome:
    """A setpoint whose payload is cut to 4 bytes (steer, speed only) with a valid CRC: MAVLink 2
    zero-fills it, so it reads as a broadcast and must be refused."""
    def bad(s: SilSession) -> None:
        from ..protocol import dialect

        d = dialect()
        mav = d.MAVLink(None, srcSystem=255, srcComponent=190)
        msg = d.MAVLink_agnav_drive_setpoint_message(0, 0, 0, 3000, 0, 0, 0, 1)
        buf = bytearray(msg.pack(mav))
        # re-frame with a 4-byte payload: header(10) + payload + crc(2)
        from pymavlink.generator.mavcrc import x25crc

        hdr = bytearray(buf[:10])
        hdr[1] = 4
        payload = bytes(buf[10:14])
        crc = x25crc(bytes(hdr[1:]) + payload)
        crc.accumulate(bytes([msg.crc_extra]))
        s.up.send(s.t_us, bytes(hdr) + payload + crc.crc.to_bytes(2, "little"))

    tr = _run(bad, good=False)
    moved = any(tr.moving)
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    txt = tr.texts_after(t_bad)
    ok = not moved and bool(txt)
    return FaultOutcome(f"truncated setpoint frames (valid CRC): robot {'MOVED' if moved else 'stayed still'}; "
                        f"STATUSTEXT \"{txt[0] if txt else 'NONE'}\"", ok)


COMMAND_CASES = (
    FaultCase("setpoint of 30 m/s", "command", "refused with a STATUSTEXT; the robot stops and stays stopped",
              _case_absurd_speed),
    FaultCase("setpoint of 5 m/s (above MAX_SPEED_MM_S)", "command", "clamped to MAX_SPEED_MM_S (1 m/s)",
              _case_clamped_speed),
    FaultCase("e-stop command with a NaN parameter", "command", "COMMAND_ACK DENIED (NOT_FINITE); nothing done",
              _case_nan_command),
    FaultCase("unknown command id 31999", "command", "COMMAND_ACK UNSUPPORTED", _case_unknown_command),
    FaultCase("goal with x = NaN (SET_POSITION_TARGET_LOCAL_NED)", "command", "refused with a STATUSTEXT",
              _case_nan_goal),
    FaultCase("setpoints for another system id", "command", "ignored: the robot does not move", _case_other_system),
    FaultCase("setpoint frame truncated to 4 payload bytes", "command",
              "reads as a broadcast: refused with a STATUSTEXT, the robot does not move", _case_truncated),
)


# ---- signing ---------------------------------------------------------------------------------------------
def _sign(codec: Any, key: bytes | None, t_s: float) -> None:
    if key is None:
        codec.signing.secret_key = None
        codec.signing.sign_outgoing = False
        return
    codec.signing.secret_key = key
    codec.signing.sign_outgoing = True
    codec.signing.link_id = 1
    codec.signing.timestamp = int((t_s - 1420070400) * 100_000)


def _provision(s: SilSession) -> None:
    """The key goes in over the unsigned provisioning window after power-on; from then on the host
    signs everything."""
    from ..link.keys import setup_signing_message

    h = s.host
    h._send(setup_signing_message(h._d, KEY, 1, unix_s=NOW_S))  # noqa: SLF001
    s.up.send(s.t_us, h.take_tx())
    _sign(h._mav, KEY, NOW_S + 1)  # noqa: SLF001


def _signing_case(kind: str) -> FaultOutcome:
    recorded: list[bytes] = []
    state = {"switched": False}

    def bad(s: SilSession) -> None:
        h = s.host
        if kind == "unsigned" and not state["switched"]:
            _sign(h._mav, None, 0)  # noqa: SLF001
        state["switched"] = True
        if kind == "replayed":
            s.up.send(s.t_us, recorded[len(recorded) // 2])  # an old, validly signed setpoint
        elif kind == "wrong key":  # an impostor with its own key (the host keeps reading telemetry with ours)
            d = h._d  # noqa: SLF001
            if "codec" not in state:
                state["codec"] = d.MAVLink(None, srcSystem=255, srcComponent=190)
                _sign(state["codec"], OTHER_KEY, NOW_S + 100)
            c = state["codec"]
            frames = d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, d.MAV_STATE_ACTIVE, 3).pack(c)
            frames += d.MAVLink_agnav_drive_setpoint_message(1, 1, 0, SPEED_MM_S, 0, 0, d.AGNAV_DRIVE_PHYSICAL, 1).pack(c)
            s.up.send(s.t_us, frames)
        else:
            h.heartbeat()
            h.setpoint(0, SPEED_MM_S)

    class _Rec(_Sender):
        def __call__(self, s: SilSession, t_us: int) -> None:
            before = t_us < self.next_us
            super().__call__(s, t_us)
            if not before and (t_us - self.t0_us) * 1e-6 < T_BAD_S:
                tx = s.host.take_tx()
                recorded.append(tx)
                s.up.send(s.t_us, tx)

    drv = _Rec(bad, True, replace_hb=True)
    tr = drive_with_link_faults(T_BAD_S + 3.0, seed=10, driver=drv, events=[(0.0, _provision)])
    t_bad = tr.t0_us + int(T_BAD_S * 1e6)
    drove_before = any(tr.moving[tr.index_at(tr.t0_us + 1_000_000):tr.index_at(t_bad)])
    t_stop = tr.first_stop_after(t_bad)
    stop_ms = (t_stop - t_bad) / 1000.0 if t_stop is not None else math.inf
    moved_after = any(tr.moving[tr.index_at(t_bad + 700_000):])
    counters = tr.sys_status_counters
    idx = {"unsigned": 1, "wrong key": 2, "replayed": 3}[kind]
    counted = counters[idx] if counters else 0
    ok = drove_before and stop_ms <= 500.0 + TICK_MS + 2.0 + 100.0 and not moved_after and counted >= 10
    return FaultOutcome(f"signed setpoints drove the robot; {kind} ones from 3 s: outputs neutral after "
                        f"{stop_ms:.0f} ms (link-loss timeout: they never count as the host), "
                        f"{'MOVED AGAIN' if moved_after else 'stayed stopped'}; SYS_STATUS counts {counted} "
                        f"{kind} frames dropped", ok)


SIGNING_CASES = (
    FaultCase("unsigned setpoints with a key set", "signing",
              "dropped and counted (SYS_STATUS errors_count2); robot stops on link-loss timeout",
              lambda: _signing_case("unsigned")),
    FaultCase("setpoints signed with the wrong key", "signing",
              "dropped and counted (errors_count3); robot stops on link-loss timeout",
              lambda: _signing_case("wrong key")),
    FaultCase("replayed signed setpoints", "signing",
              "dropped and counted (errors_count4); robot stops on link-loss timeout",
              lambda: _signing_case("replayed")),
)
