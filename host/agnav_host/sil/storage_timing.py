"""What a save costs the control loop, measured on the firmware under simulation.

``save_timing(record)`` boots the firmware (by default the real AVR ELF under simavr, where a programmed
EEPROM byte holds EEPE for 3.3 ms as on the chip), lets a 10 Hz host settle the link, then asks for one save
over MAVLink while the host keeps sending heartbeats: the parameters (PARAM_SET + PREFLIGHT_STORAGE), the
calibration tables (AGNAV_CALIB_REQUEST save) or the signing key (SETUP_SIGNING inside the power-on
provisioning window). It returns the worst control period across the save, the bytes programmed and the time
until the firmware's final answer."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..protocol import dialect
from .binding import Firmware
from .host import HostEndpoint

RECORDS = ("params", "calib", "signing_key")
AVR_EEPROM_WRITE_US = 3296  # ATmega2560 datasheet, Table 8-1 (hil/simavr/avr_board_model.h)
_KEY = bytes(range(1, 33))
_NOW_S = 1.8e9  # a fixed wall clock for the key's initial timestamp (repeatable runs)


@dataclass(frozen=True)
class SaveTiming:
    record: str
    backend: str
    worst_control_period_us: int  # longest gap between two control ticks from the request to the final answer
    normal_control_period_us: int  # the same over a second of running before the request
    bytes_programmed: int
    answer_s: float | None  # request to the final answer (None: never answered)
    answers: tuple[int, ...]  # results in order (IN_PROGRESS first for parameters and tables)


def _exchange(fw: Firmware, h: HostEndpoint, us: int, until: Callable[[], bool] | None = None) -> None:
    end = fw.time_us + us
    while fw.time_us < end:
        h.heartbeat()
        fw.uart_write(h.take_tx())
        fw.step_to(min(end, fw.time_us + 20_000))
        fw.take_triggers()
        h.feed(fw.time_us, fw.uart_read())
        if until is not None and until():
            return


def save_timing(record: str, backend: str = "avr", timeout_s: float = 8.0) -> SaveTiming:
    """Measure one save of ``record`` (see RECORDS) on ``backend`` ("avr": simavr; "native": the sim HAL, whose
    EEPROM takes the same 3.3 ms a byte). ValueError for an unknown record."""
    if record not in RECORDS:
        raise ValueError(f"unknown record {record!r}: one of {', '.join(RECORDS)}")
    D = dialect()
    with Firmware(backend=backend) as fw:
        avr = backend == "avr"
        if avr:
            fw._lib.sil_avr_set_eeprom_write_us(AVR_EEPROM_WRITE_US)
        h = HostEndpoint()
        h.set_behaviours(follow_wall=False)
        _exchange(fw, h, 300_000)
        gap = fw._lib.sil_avr_control_gap_max_us if avr else fw._lib.sil_kick_gap_max_us
        writes = fw._lib.sil_avr_eeprom_writes if avr else fw._lib.sil_eeprom_writes
        gap()
        _exchange(fw, h, 1_000_000)
        normal = int(gap())
        w0 = writes()
        t0 = fw.time_us
        h.acks.clear()
        h.calib_acks.clear()
        final: Callable[[], bool]
        if record == "params":
            h.param_set("LINK_TIMEOUT_MS", 1234)
            h.command_long(D.MAV_CMD_PREFLIGHT_STORAGE, 1)

            def answers() -> list[int]:
                return [a.result for a in h.acks if a.command == D.MAV_CMD_PREFLIGHT_STORAGE]
            final = lambda: any(r != D.MAV_RESULT_IN_PROGRESS for r in answers())  # noqa: E731
        elif record == "calib":
            h.calib_request(0, D.AGNAV_CALIB_ACTION_SAVE)

            def answers() -> list[int]:
                return [a.result for a in h.calib_acks]
            final = lambda: any(r != D.AGNAV_CALIB_IN_PROGRESS for r in answers())  # noqa: E731
        else:
            from ..link.keys import setup_signing_message

            mav = D.MAVLink(None, srcSystem=255, srcComponent=190)
            fw.uart_write(setup_signing_message(D, _KEY, 1, unix_s=_NOW_S).pack(mav))

            def answers() -> list[int]:
                return []
            main, copy = fw.eeprom_record("signing")[0], fw.eeprom_record("signing_copy")[0]

            def final() -> bool:  # no answer message: done when both slots hold the key and its CRC
                ee = fw.eeprom()
                return ee[main:main + 36] == ee[copy:copy + 36] and ee[main + 2:main + 34] == _KEY
        fw.uart_write(h.take_tx())
        t_final: int | None = None
        end = fw.time_us + int(timeout_s * 1e6)
        while fw.time_us < end and t_final is None:
            _exchange(fw, h, 20_000)
            if final():
                t_final = fw.time_us
        _exchange(fw, h, 100_000)  # the loop after the answer, inside the measured window
        worst = int(gap())
        return SaveTiming(record, backend, worst, normal, int(writes() - w0),
                          None if t_final is None else (t_final - t0) * 1e-6, tuple(answers()))
