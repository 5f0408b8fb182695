"""Safety promises on the REAL ATmega2560 firmware under simavr (hil/simavr/avr_sil.c): with a
signing key the control tick keeps its period (SHA-256 costs real cycles here), unsigned frames
are refused, a watchdog reset read from MCUSR boots stopped, and an encoder interrupt storm of
10 to 50 kHz neither starves the control task nor goes unreported.

$AGNAV_AVR_ELF picks the ELF (default: the PlatformIO build, rebuilt when stale)."""

from __future__ import annotations

import os

import pytest

from _sil_logic import decode

from agnav_host.link.keys import setup_signing_message
from agnav_host.protocol import dialect
from agnav_host.sil import Firmware

D = dialect()
KEY = bytes(range(1, 33))
NOW_S = 1.8e9


def avr() -> Firmware:
    fw = Firmware(backend="avr", elf=os.environ.get("AGNAV_AVR_ELF") or None)
    fw.set_stop_on_trigger(False)
    return fw


def codec(key: bytes | None):
    mav = D.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key, mav.signing.sign_outgoing, mav.signing.link_id = key, True, 1
        mav.signing.timestamp = int((NOW_S - 1420070400) * 100_000)
    return mav


def host_run(fw: Firmware, us: int, mav, echo: bool = False) -> list:
    """Heartbeat + zero setpoint every 50 ms (a 20 Hz host), optional 2 m sonar echoes. The bytes
    are decoded as one stream: a frame split across two 50 ms reads stays whole."""
    out = bytearray()
    end = fw.time_us + us
    seq = 0
    while fw.time_us < end:
        seq += 1
        fw.uart_write(D.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mav))
        fw.uart_write(D.MAVLink_agnav_drive_setpoint_message(1, 1, 0, 0, 0, 0, 0, seq & 0xFFFF).pack(mav))
        fw.step_to(min(end, fw.time_us + 50_000))
        for idx, t in fw.take_triggers():
            if echo:
                fw.queue_echo(idx, t + 200, 1)
                fw.queue_echo(idx, t + 11_862, 0)
        out += fw.uart_read()
    return decode(bytes(out))


@pytest.mark.parametrize("signed", [False, True])
def test_control_tick_period_with_and_without_signing(signed):
    with avr() as fw:
        host_run(fw, 100_000, codec(None))
        if signed:
            fw.uart_write(setup_signing_message(D, KEY, 1, unix_s=NOW_S).pack(codec(None)))
        msgs = host_run(fw, 1_000_000, codec(KEY if signed else None))
        fw.kick_gap_max_us()
        msgs += host_run(fw, 4_000_000, codec(KEY if signed else None))
        gap = fw.kick_gap_max_us()
        texts = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
        assert fw.reset_count == 0, f"watchdog resets: {fw.reset_count}"
        # Signed: each frame in or out costs ~5.7 ms of SHA-256, so a telemetry task with two or
        # three frames can push one control tick back by ~12 ms; far inside the 250 ms watchdog.
        assert gap <= (40_000 if signed else 25_000), f"control tick gap {gap} us (period 20 ms), signed={signed}"
        if signed:
            assert "signing: key set" in texts
        print(f"signed={signed}: worst control tick gap {gap} us over 4 s")


def test_signed_avr_refuses_unsigned_commands():
    with avr() as fw:
        host_run(fw, 100_000, codec(None))
        fw.uart_write(setup_signing_message(D, KEY, 1, unix_s=NOW_S).pack(codec(None)))
        host_run(fw, 300_000, codec(KEY))
        fw.uart_write(D.MAVLink_command_long_message(1, 1, D.MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0)
                      .pack(codec(None)))
        # SYS_STATUS is a 1 Hz message, sent later with signing: 3.3 s hold one whatever the phase
        # (the key's EEPROM save, 40 bytes at 3.3 ms a byte, shifts it by 132 ms)
        msgs = host_run(fw, 3_300_000, codec(KEY))
        assert not [m for m in msgs if m.get_type() == "COMMAND_ACK"], "unsigned command acted on"
        ss = [m for m in msgs if m.get_type() == "SYS_STATUS"][-1]
        assert ss.errors_count2 >= 1, f"unsigned frames counted: {ss.errors_count2}"


def test_watchdog_reset_from_mcusr_boots_stopped():
    with avr() as fw:
        boot = host_run(fw, 300_000, codec(None))
        assert "boot: power-on reset" in [m.text for m in boot if m.get_type() == "STATUSTEXT"]
        fw.fault_reset("watchdog")
        msgs = host_run(fw, 600_000, codec(None))
        assert "boot: WATCHDOG reset, stopped until armed" in [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
        st = [m for m in msgs if m.get_type() == "AGNAV_BEHAVIOUR_STATUS"][-1]
        assert st.failsafe_flags & D.AGNAV_FAILSAFE_WATCHDOG_RESET and st.reason == D.AGNAV_REASON_WATCHDOG_BOOT


@pytest.mark.parametrize("period_us", [100, 50, 20])
def test_encoder_interrupt_storm_keeps_the_control_tick_and_stops(period_us):
    """Legal quadrature edges at 10, 20 and 50 kHz for 1 s (13.55 mm a count: far beyond any real
    wheel). Before the odometry clamp in main.c, 20 kHz made one control tick take up to 121 ms
    and the watchdog reset the board."""
    with Firmware(backend="avr", elf=os.environ.get("AGNAV_AVR_ELF") or None,
                  params={"ENC_MODE": 0, "SONAR_COUNT": 0}) as fw:
        fw.set_stop_on_trigger(False)
        host_run(fw, 200_000, codec(None))
        fw.kick_gap_max_us()
        n = 1_000_000 // period_us
        assert fw.isr_burst(0, n, period_us) == n
        msgs = host_run(fw, 1_100_000, codec(None))
        gap = fw.kick_gap_max_us()
        khz = 1000 / period_us
        assert fw.reset_count == 0, f"{fw.reset_count} watchdog resets during a {khz:.0f} kHz storm"
        assert gap <= 25_000, f"control tick gap {gap} us during a {khz:.0f} kHz edge storm"
        assert "health: encoder 0 illegal edges/storm, stop" in [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
        print(f"{khz:.0f} kHz encoder storm: worst control tick gap {gap} us")
