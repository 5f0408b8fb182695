"""MAVLink 2 signing end to end: the native SIL firmware with a key provisioned by the host's
SETUP_SIGNING (agnav_host.link.keys) rejects unsigned, wrongly signed and replayed commands and
counts them where the host can read them (SYS_STATUS errors_count2..4)."""

from __future__ import annotations

import pytest

from _sil_logic import decode

from agnav_host.link.keys import CLEAR_KEY, setup_signing_message
from agnav_host.protocol import dialect
from agnav_host.sil import Firmware, build_library

D = dialect()
KEY = bytes(range(1, 33))
OTHER = bytes([0x5A] * 32)
NOW_S = 1.8e9  # a fixed wall clock (2027) so runs are repeatable


@pytest.fixture(scope="module", autouse=True)
def lib():
    return build_library()


def codec(key: bytes | None, t_s: float = NOW_S):
    mav = D.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = 1
        mav.signing.timestamp = int((t_s - 1420070400) * 100_000)
    return mav


def run(fw: Firmware, us: int) -> list:
    end = fw.time_us + us
    out = []
    while fw.time_us < end:
        fw.step_to(min(end, fw.time_us + 50_000))
        fw.take_triggers()
        out += decode(fw.uart_read())
    return out


def estop(engage: bool, mav) -> bytes:
    return D.MAVLink_command_long_message(1, 1, D.MAV_CMD_AGNAV_ESTOP, 0, 1.0 if engage else 0.0,
                                          0, 0, 0, 0, 0, 0).pack(mav)


def acks(msgs) -> list:
    return [m for m in msgs if m.get_type() == "COMMAND_ACK"]


def provisioned() -> Firmware:
    fw = Firmware()
    run(fw, 200_000)
    fw.uart_write(setup_signing_message(D, KEY, 1, unix_s=NOW_S).pack(codec(None)))
    msgs = run(fw, 500_000)  # also lets the key record reach the EEPROM
    assert "signing: key set" in [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    return fw


def test_signed_firmware_accepts_signed_and_rejects_unsigned_wrong_and_replayed():
    with provisioned() as fw:
        good = codec(KEY, NOW_S + 1)
        engage = estop(True, good)
        fw.uart_write(engage)
        assert [a.result for a in acks(run(fw, 200_000))] == [D.MAV_RESULT_ACCEPTED]
        fw.uart_write(estop(False, good))
        assert [a.result for a in acks(run(fw, 200_000))] == [D.MAV_RESULT_ACCEPTED]

        fw.uart_write(estop(True, codec(None)))            # unsigned
        fw.uart_write(estop(True, codec(OTHER, NOW_S + 2)))  # signed with another key
        fw.uart_write(engage)                             # the recorded engage frame, replayed
        msgs = run(fw, 1_200_000)
        assert acks(msgs) == [], "none of the three reached the command handler (it answers every command)"
        ss = [m for m in msgs if m.get_type() == "SYS_STATUS"][-1]
        assert (ss.errors_count2, ss.errors_count3, ss.errors_count4) == (1, 1, 1), \
            f"unsigned/bad/replay counters {ss.errors_count2}/{ss.errors_count3}/{ss.errors_count4}"


def test_telemetry_of_a_signed_firmware_is_signed_with_the_key():
    with provisioned() as fw:
        checker = codec(KEY)
        checker.signing.allow_unsigned_callback = None
        checker.signing.sign_outgoing = False
        msgs = checker.parse_buffer(b"".join(m.get_msgbuf() for m in run(fw, 1_100_000))) or []
        assert any(m.get_type() == "HEARTBEAT" for m in msgs)
        assert checker.signing.goodsig_count > 0 and checker.signing.badsig_count == 0


def test_key_survives_a_reboot_and_unsigned_change_after_the_window_is_refused():
    with provisioned() as fw:
        fw.fault_reset("watchdog")  # no provisioning window after an unexpected reset
        run(fw, 200_000)
        fw.uart_write(setup_signing_message(D, CLEAR_KEY, 1, unix_s=NOW_S + 5).pack(codec(None)))
        fw.uart_write(estop(True, codec(None)))
        msgs = run(fw, 300_000)
        assert acks(msgs) == [], "signing is still on after the reset"
        fw.uart_write(estop(True, codec(KEY, NOW_S + 10)))
        assert [a.result for a in acks(run(fw, 200_000))] == [D.MAV_RESULT_ACCEPTED]


def test_signed_key_change_and_clear():
    with provisioned() as fw:
        run(fw, 10_500_000)  # the provisioning window is closed now
        fw.uart_write(setup_signing_message(D, OTHER, 1, unix_s=NOW_S + 20).pack(codec(KEY, NOW_S + 20)))
        run(fw, 300_000)
        fw.uart_write(estop(True, codec(OTHER, NOW_S + 21)))
        assert [a.result for a in acks(run(fw, 200_000))] == [D.MAV_RESULT_ACCEPTED]
        fw.uart_write(setup_signing_message(D, CLEAR_KEY, 1, unix_s=NOW_S + 22).pack(codec(OTHER, NOW_S + 22)))
        run(fw, 300_000)
        fw.uart_write(estop(False, codec(None)))
        assert [a.result for a in acks(run(fw, 200_000))] == [D.MAV_RESULT_ACCEPTED], "signing off: unsigned ok"
