"""Sensor and controller faults injected into the SIL firmware's simulated hardware (hil/sil/sil_api.h
"FAULT INJECTION"): the robot drives straight at 0.4 m/s on host setpoints (as in
:mod:`.link_faults`) and at 3 s an encoder sticks, a sonar dies, the core resets, the EEPROM
rots, or an interrupt storm arrives. The firmware must notice, tell the host, and stop (or, for
health-only faults, carry on with defaults and say so).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable

from ._core import FaultCase, FaultOutcome
from .link_faults import DT_S, TICK_MS, DriveTrace, drive_with_link_faults

if TYPE_CHECKING:
    from ..sil import SilSession

#: something done to the running session at a set time (a fault injected, a value read back)
SessionEvent = Callable[["SilSession"], object]

__all__ = ["FIRMWARE_CASES"]

LAYER_FAILSAFE = 1
REASON_SENSOR_FAULT, REASON_WATCHDOG_BOOT = 3, 4
FS_ENCODER_FAULT, FS_SONAR_FAULT, FS_WATCHDOG_RESET, FS_CALIB_DEFAULTED = 4, 8, 16, 32
T_INJECT_S = 3.0


def _stop_summary(tr: DriveTrace, t_inj: int) -> tuple[float, float, float, bool]:
    """(ms from the fault to neutral outputs, ms to standstill, metres travelled meanwhile, stayed
    stopped to the end of the run)."""
    t_stop = tr.first_stop_after(t_inj)
    if t_stop is None:
        return math.inf, math.inf, math.inf, False
    i_inj = tr.index_at(t_inj)
    i_stop = tr.index_at(t_stop)
    i_still = next((i for i in range(i_stop, len(tr.t_us)) if abs(tr.speed_m_s[i]) < 1e-3), len(tr.t_us) - 1)
    stayed = not any(tr.moving[i_stop:])
    return ((t_stop - t_inj) / 1000.0, (tr.t_us[i_still] - t_inj) / 1000.0, tr.x_m[i_still] - tr.x_m[i_inj], stayed)


def _sensor_case(inject: SessionEvent, flag: int, limit_ms: float) -> Callable[[], FaultOutcome]:
    def run() -> FaultOutcome:
        tr = drive_with_link_faults(T_INJECT_S + 4.0, seed=5, events=[(T_INJECT_S, inject)])
        t_inj = tr.t0_us + int(T_INJECT_S * 1e6)
        before = [st for st in tr.statuses if tr.t0_us + 1_000_000 <= st[0] < t_inj]
        clean_before = bool(before) and not any(st[3] & flag for st in before)
        seen = next((st for st in tr.statuses_after(t_inj) if st[1] == LAYER_FAILSAFE and st[2] == REASON_SENSOR_FAULT
                     and st[3] & flag), None)
        detect_ms = (seen[0] - t_inj) / 1000.0 if seen else math.inf
        stop_ms, still_ms, dist, stayed = _stop_summary(tr, t_inj)
        txt = tr.texts_after(t_inj)
        ok = clean_before and detect_ms <= limit_ms and stop_ms <= limit_ms + TICK_MS + DT_S * 1000 and stayed and bool(txt)
        msg = (f"{'no false alarm before; ' if clean_before else 'FLAG SET BEFORE THE FAULT; '}"
               f"host saw SENSOR_FAULT after {detect_ms:.0f} ms, outputs neutral after {stop_ms:.0f} ms, "
               f"standstill after {still_ms:.0f} ms ({dist:.3f} m); {'stayed stopped' if stayed else 'MOVED AGAIN'}; "
               f"STATUSTEXT \"{txt[0] if txt else 'NONE'}\"")
        return FaultOutcome(msg, ok, {"detect_ms": detect_ms, "stop_ms": stop_ms, "stop_distance_m": dist})
    return run


def _reset_case(cause: str) -> FaultOutcome:
    """Core reset at 3 s while the host streams setpoints; the host arms the robot at 5 s."""
    t_arm = T_INJECT_S + 2.0
    tr = drive_with_link_faults(T_INJECT_S + 4.0, seed=6,
                                events=[(T_INJECT_S, lambda s: s.fw.fault_reset(cause)), (t_arm, lambda s: s.host.arm())])
    t_inj = tr.t0_us + int(T_INJECT_S * 1e6)
    t_arm_us = tr.t0_us + int(t_arm * 1e6)
    i_inj, i_arm = tr.index_at(t_inj), tr.index_at(t_arm_us)
    moved_before_arm = any(tr.moving[i_inj + 1:i_arm])
    seen = next((st for st in tr.statuses_after(t_inj) if st[1] == LAYER_FAILSAFE and st[2] == REASON_WATCHDOG_BOOT), None)
    restart = [t for t in tr.starts() if t >= t_arm_us]
    resume_ms = (restart[0] - t_arm_us) / 1000.0 if restart else math.inf
    stop_ms, still_ms, dist, _ = _stop_summary(tr, t_inj)
    txt = tr.texts_after(t_inj)
    ok = (not moved_before_arm and seen is not None and resume_ms < 200.0 and stop_ms <= DT_S * 1000 + 1e-6 and bool(txt))
    msg = (f"outputs neutral {stop_ms:.0f} ms after the reset (booted stopped), standstill after {still_ms:.0f} ms "
           f"({dist:.3f} m); {'MOVED' if moved_before_arm else 'stayed stopped'} for 2 s of host setpoints; reason "
           f"{'WATCHDOG_BOOT' if seen else 'NOT REPORTED'}; STATUSTEXT \"{txt[0] if txt else 'NONE'}\"; "
           f"moving {resume_ms:.0f} ms after the host's ARM")
    return FaultOutcome(msg, ok, {"stop_ms": stop_ms, "resume_after_arm_ms": resume_ms})


def _eeprom_case(record: str) -> FaultOutcome:
    """A bit flipped in both slots of an EEPROM record, then an external reset (the reset button) at 3 s."""
    stored: dict[str, int] = {}
    reloaded: dict[str, int] = {}

    def inject(s: SilSession) -> None:
        # the robot profile's parameters as stored in EEPROM before the damage
        stored.update({k: s.fw.param_get(k) for k in s.plant.firmware_params()})
        for slot in (record, f"{record}_copy"):  # both slots: the copy stands in for a damaged main slot
            s.fw.corrupt_record(slot, offset=4, length=1, xor_mask=0x10)
        s.fw.fault_reset("external")

    def read_back(s: SilSession) -> None:
        reloaded.update({k: s.fw.param_get(k) for k in stored})

    tr = drive_with_link_faults(T_INJECT_S + 3.0, seed=7, events=[(T_INJECT_S, inject), (T_INJECT_S + 2.5, read_back)])
    t_inj = tr.t0_us + int(T_INJECT_S * 1e6)
    txt = tr.texts_after(t_inj)
    after = tr.statuses_after(t_inj)
    words = {"calib": ("calib",), "params": ("param",)}[record]
    told = [t for t in txt if any(w in t.lower() for w in words)]
    if record == "calib":
        flagged = any(st[3] & FS_CALIB_DEFAULTED for st in after)
        what = f"CALIB_DEFAULTED health flag {'set' if flagged else 'NOT set'}"
    else:
        # a damaged parameter record is not used: the stored profile gives way to the firmware defaults
        changed = {k: (stored[k], reloaded[k]) for k in stored if k in reloaded and reloaded[k] != stored[k]}
        flagged = bool(changed)
        what = ("stored values replaced by defaults: " + ", ".join(f"{k} {a} -> {b}" for k, (a, b) in list(changed.items())[:2])
                if changed else "the stored parameters were still in use after the reboot")
    ok = bool(told) and flagged
    msg = (f"STATUSTEXT \"{told[0] if told else (txt[0] if txt else 'NONE')}\"; {what}"
           f"; {len(after)} status frames after the reboot")
    return FaultOutcome(msg, ok)


def _isr_burst_case() -> FaultOutcome:
    """40 kHz of encoder edges for 1 s, each edge costing 8 us of CPU (32 % load)."""
    gaps: list[int] = []
    resets: list[int] = []

    def start(s: SilSession) -> None:
        s.fw.kick_gap_max_us()  # reset the maximum
        resets.append(s.fw.reset_count)
        s.fw.set_isr_cost_us(8)
        s.fw.isr_burst(0, 40_000, 25)

    def end(s: SilSession) -> None:
        gaps.append(s.fw.kick_gap_max_us())
        resets.append(s.fw.reset_count)
        s.fw.set_isr_cost_us(0)

    drive_with_link_faults(T_INJECT_S + 2.5, seed=8, events=[(T_INJECT_S, start), (T_INJECT_S + 1.05, end)])
    gap_ms = gaps[0] / 1000.0 if gaps else math.inf
    no_reset = len(resets) == 2 and resets[0] == resets[1]
    ok = gap_ms <= TICK_MS * 1.5 and no_reset
    return FaultOutcome(f"longest gap between control ticks during the burst {gap_ms:.1f} ms (nominal 20); "
                        f"{'no reset' if no_reset else 'WATCHDOG RESET'}", ok, {"tick_gap_ms": gap_ms})


def _inject(kind: str, idx: int, mode: str) -> SessionEvent:
    return lambda s: getattr(s.fw, f"fault_{kind}")(idx, mode)


FIRMWARE_CASES = (
    FaultCase("left encoder stuck while driving", "sensor",
              "ENCODER_FAULT detected and the robot stopped within 1 s; STATUSTEXT; stays stopped",
              _sensor_case(_inject("encoder", 0, "stuck"), FS_ENCODER_FAULT, 1000.0)),
    FaultCase("left encoder disconnected (lines float high)", "sensor",
              "ENCODER_FAULT detected and the robot stopped within 1 s; STATUSTEXT; stays stopped",
              _sensor_case(_inject("encoder", 0, "disconnected"), FS_ENCODER_FAULT, 1000.0)),
    FaultCase("right encoder illegal-transition storm", "sensor",
              "ENCODER_FAULT detected and the robot stopped within 1 s; STATUSTEXT; stays stopped",
              _sensor_case(_inject("encoder", 1, "noise"), FS_ENCODER_FAULT, 1000.0)),
    FaultCase("front sonar dead (echo never rises)", "sensor",
              "SONAR_FAULT (not 'free space') and the robot stopped within 1 s; STATUSTEXT; stays stopped",
              _sensor_case(_inject("sonar", 0, "timeout"), FS_SONAR_FAULT, 1000.0)),
    FaultCase("front sonar always reads ~0 mm", "sensor",
              "SONAR_FAULT and the robot stopped within 1 s; STATUSTEXT; stays stopped",
              _sensor_case(_inject("sonar", 0, "zero"), FS_SONAR_FAULT, 1000.0)),
    FaultCase("watchdog reset at 0.4 m/s", "controller",
              "boots with outputs neutral, reports WATCHDOG_BOOT, ignores setpoints until the host arms it",
              lambda: _reset_case("watchdog")),
    FaultCase("brown-out reset at 0.4 m/s", "controller",
              "boots with outputs neutral, reports it, ignores setpoints until the host arms it",
              lambda: _reset_case("brown_out")),
    FaultCase("calibration tables corrupted in EEPROM (one bit in both slots)", "controller",
              "CRC fails at boot: default tables, CALIB_DEFAULTED health flag, STATUSTEXT", lambda: _eeprom_case("calib")),
    FaultCase("parameter record corrupted in EEPROM (one bit in both slots)", "controller",
              "CRC fails at boot: default parameters, STATUSTEXT", lambda: _eeprom_case("params")),
    FaultCase("encoder interrupt storm (40 kHz for 1 s, 8 us per ISR)", "controller",
              "control tick keeps running (gap <= 30 ms), no watchdog reset", _isr_burst_case),
)
