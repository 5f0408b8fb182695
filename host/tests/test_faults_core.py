"""Pieces of the fault suite that need no firmware: the radio fault model, the table, and the
telemetry log's behaviour on a failing disk."""

from __future__ import annotations

import errno

import numpy as np
import pytest

from agnav_host.faults import FaultCase, FaultOutcome, format_table, run_cases
from agnav_host.link.tlog import TlogWriter, read_tlog
from agnav_host.sil.link import LinkChannel, LinkFaults, LinkParams, random_bursts


def _frame(seq: int) -> bytes:
    # a MAVLink 2 frame shape (0xFD, len, flags, ...) is all the framer needs
    payload = bytes([seq % 256]) * 9
    return bytes([0xFD, len(payload), 0, 0, seq % 256, 1, 1, 0, 0, 0]) + payload + b"\x00\x00"


def test_outage_loses_exactly_the_frames_sent_inside_it():
    ch = LinkChannel(LinkParams(baud=0, latency_s=0.0), np.random.default_rng(0))
    ch.faults = LinkFaults(outages=((1.0, 2.0),))
    sent = [int(t * 1e6) for t in np.arange(0.0, 3.0, 0.1)]
    for i, t in enumerate(sent):
        ch.send(t, _frame(i))
    inside = sum(1 for t in sent if 1.0 <= t * 1e-6 < 2.0)
    assert ch.frames_lost == inside == 10
    assert len(ch.receive(10_000_000)) == (len(sent) - inside) * len(_frame(0))


def test_latency_spike_delays_and_keeps_order():
    ch = LinkChannel(LinkParams(baud=0, latency_s=0.01), np.random.default_rng(0))
    ch.faults = LinkFaults(latency_spikes=((1.0, 1.5, 0.8),))
    order = []
    for i, t in enumerate(np.arange(0.0, 3.0, 0.1)):
        ch.send(int(t * 1e6), _frame(i))
    t = 0
    while (nxt := ch.next_delivery_us()) is not None:
        t = nxt
        data = ch.receive(t)
        order += [data[k + 4] for k in range(0, len(data), len(_frame(0)))]
    assert order == sorted(order), "the radio must stay first-in first-out"
    # the frame sent at 1.0 s arrives 0.8 s late; frames sent after the spike queue behind the last late one
    ch2 = LinkChannel(LinkParams(baud=0, latency_s=0.01), np.random.default_rng(0))
    ch2.faults = LinkFaults(latency_spikes=((1.0, 1.5, 0.8),))
    ch2.send(1_000_000, _frame(1))
    assert ch2.next_delivery_us() == 1_000_000 + 10_000 + 800_000
    ch2.send(1_600_000, _frame(2))  # after the spike, but must not overtake frame 1
    assert ch2.receive(1_809_999) == b""  # plain latency would have delivered it at 1.61 s
    assert ch2.receive(1_810_000) == _frame(1) + _frame(2)


def test_random_bursts_are_deterministic_and_inside_the_window():
    a = random_bursts(5, 100.0, 0.5, 0.3, start_s=2.0)
    assert a == random_bursts(5, 100.0, 0.5, 0.3, start_s=2.0)
    assert a != random_bursts(6, 100.0, 0.5, 0.3, start_s=2.0)
    assert 20 <= len(a) <= 80  # ~50 expected at 0.5 Hz over 100 s
    assert all(2.0 <= s < e <= 102.0 for s, e in a)
    assert all(a[i][1] <= a[i + 1][0] for i in range(len(a) - 1))
    assert random_bursts(5, 100.0, 0.0, 0.3) == ()


@pytest.mark.parametrize("bad", [{"outages": ((2.0, 1.0),)}, {"latency_spikes": ((0.0, 1.0, -0.1),)},
                                 {"outages": ((1.0,),)}])
def test_bad_fault_windows_are_refused(bad):
    with pytest.raises(ValueError):
        LinkFaults(**bad)


def test_suite_reports_a_crashing_case_as_a_failure_and_goes_on():
    def boom() -> FaultOutcome:
        raise ZeroDivisionError("division by zero")

    cases = [FaultCase("crashes", "test", "nothing", boom),
             FaultCase("works", "test", "ok", lambda: FaultOutcome("fine", True))]
    rows = run_cases(cases)
    assert [r.outcome.passed for r in rows] == [False, True]
    assert "ZeroDivisionError" in rows[0].outcome.measured
    table = format_table(rows)
    assert "| test | crashes |" in table and "FAIL" in table and "1 of 2 fault cases pass" in table


class _FullDisk:
    """A file object that accepts ``room`` bytes, then fails as a full disk does."""

    def __init__(self, room: int) -> None:
        self.room = room
        self.data = bytearray()
        self.closed = False

    def write(self, b: bytes) -> int:
        if len(self.data) + len(b) > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.data += b
        return len(b)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True


def test_tlog_writer_survives_a_full_disk(tmp_path):
    w = TlogWriter(tmp_path / "x.tlog")
    w._f.close()
    disk = _FullDisk(room=10 * (8 + len(_frame(0))))
    w._f = disk  # type: ignore[assignment]
    for i in range(25):
        w.write(_frame(i), t_s=1.0 + i)  # must never raise
    assert w.frames == 10 and w.frames_dropped == 15
    assert w.error is not None and "No space left" in w.error
    assert disk.closed
    w.flush()
    w.close()  # both harmless after the failure


def test_tlog_written_before_a_failure_reads_back(tmp_path):
    from agnav_host.protocol import new_codec

    codec = new_codec()
    hb = codec.heartbeat_encode(6, 8, 0, 0, 0).pack(codec)
    p = tmp_path / "y.tlog"
    with TlogWriter(p) as w:
        for i in range(5):
            w.write(hb, t_s=100.0 + i)
    assert [m.get_type() for _, m in read_tlog(p)] == ["HEARTBEAT"] * 5
