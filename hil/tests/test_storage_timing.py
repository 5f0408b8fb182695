"""A save never stalls the control loop: the real AVR ELF under simavr (3.3 ms of EEPE per programmed byte)
keeps its 20 ms control period while it writes each of its records, and answers the save when both slots
are written (agnav_host.sil.storage_timing, bench/bench_storage.py)."""

from __future__ import annotations

import pytest

from agnav_host.protocol import dialect
from agnav_host.sil.storage_timing import RECORDS, save_timing

D = dialect()


@pytest.mark.parametrize("record", RECORDS)
def test_avr_control_period_holds_during_a_save(record):
    t = save_timing(record, "avr")
    print(t)
    assert t.answer_s is not None, t
    assert 19_000 <= t.normal_control_period_us <= 21_000, t
    assert t.worst_control_period_us <= 21_000, t
    assert t.bytes_programmed >= 60, t  # both slots of a record on an erased EEPROM
    if record == "params":
        assert t.answers == (D.MAV_RESULT_IN_PROGRESS, D.MAV_RESULT_ACCEPTED), t
    elif record == "calib":
        assert t.answers == (D.AGNAV_CALIB_IN_PROGRESS, D.AGNAV_CALIB_ACCEPTED), t
    # 3.3 ms a byte, one byte per 2 ms link task: the save takes about 4 ms a byte, not more
    assert t.answer_s <= t.bytes_programmed * 0.0045 + 0.2, t


def test_unknown_record_is_refused():
    with pytest.raises(ValueError, match="unknown record"):
        save_timing("nope")
