"""The AVR link UART as both ends see it, under simavr (hil/simavr/avr_board_model.h): the host side
runs at its nominal rate, the firmware at the rate its UBRR0/U2X0 give, and every byte is re-read
with the receiving side's bit sampling (ATmega2560 datasheet 2549Q, 22.8). Also the EEPROM
programming time of the same board model (8.3.1, Table 8-1) and the control-period watch.

The bit-sampling model itself is checked against the datasheet's receiver limit for a transmitter
that is too fast (22.8.3: Rfast = (D + 2) S / ((D + 1) S + SM), Tables 22-2 / 22-3 for D = 8).
"""

from __future__ import annotations

import ctypes as C
import re
import subprocess
from pathlib import Path

import pytest

from _sil_logic import decode

from agnav_host.sil import Firmware, HostEndpoint
from agnav_host.sil.avr_build import build_avr_library

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "build" / "bin" / "avr_harness"
F_CPU = 16_000_000
CMD_SET_BEHAVIOURS = 45901
EEPROM_WRITE_US = 3296  # 26,368 cycles of the 8 MHz calibrated RC oscillator (Table 8-1: 3.3 ms typ)


def avr_lib() -> C.CDLL:
    lib = C.CDLL(str(build_avr_library()))
    lib.avr_model_uart_resample.restype = C.c_int
    lib.avr_model_uart_resample.argtypes = [C.c_uint8, C.c_double, C.c_double, C.c_uint]
    return lib


def link_stats(fw: Firmware) -> dict[str, int]:
    out = (C.c_uint32 * 6)()
    fw._lib.sil_avr_uart_link_stats(out)
    keys = ("to_host", "to_host_garbled", "to_host_framing", "to_avr", "to_avr_garbled", "to_avr_framing")
    return dict(zip(keys, (int(v) for v in out)))


def host_exchange(fw: Firmware, us: int) -> tuple[HostEndpoint, list]:
    """A 10 Hz host (heartbeat each time, a SET_BEHAVIOURS command once) for `us`; what it decoded."""
    h = HostEndpoint()
    h.set_behaviours(follow_wall=False)
    msgs = []
    end = fw.time_us + us
    while fw.time_us < end:
        h.heartbeat()
        fw.uart_write(h.take_tx())
        fw.step_to(min(end, fw.time_us + 100_000))
        fw.take_triggers()
        data = fw.uart_read()
        h.feed(fw.time_us, data)
        msgs += decode(data)
    return h, msgs


# ---- the bit-sampling model ------------------------------------------------------------------------
@pytest.mark.parametrize("samples, rfast_pct", [(16, 104.58), (8, 103.90)])
def test_bit_sampling_limit_of_a_fast_transmitter_is_the_datasheet_rfast(samples, rfast_pct):
    """Every byte intact at 0.05 % inside Rfast, and framing errors 0.05 % beyond it (8N1, D = 8)."""
    lib = avr_lib()
    sm = samples // 2 + 1
    rfast = 10 * samples / (9 * samples + sm)
    assert round(100 * rfast, 2) == rfast_pct
    rx_bit = 1000.0
    inside = [lib.avr_model_uart_resample(b, rx_bit / (rfast * 0.9995), rx_bit, samples) for b in range(256)]
    beyond = [lib.avr_model_uart_resample(b, rx_bit / (rfast * 1.0005), rx_bit, samples) for b in range(256)]
    assert inside == list(range(256)), f"S={samples}: bytes garbled inside Rfast"
    wrong = [b for b, got in enumerate(beyond) if got != b]
    assert len(wrong) == 256 and all(got & 0x100 for got in beyond if got >= 0), \
        f"S={samples}: only {len(wrong)} of 256 bytes garbled beyond Rfast"


@pytest.mark.parametrize("samples", [16, 8])
def test_bit_sampling_of_a_slow_transmitter_fails_when_the_stop_bit_vote_leaves_the_stop_bit(samples):
    """Transmitter slower: the stop bit's middle vote sample (SM of bit 9) must still lie in it;
    intact 0.05 % above 9 S / (9 S + SM - 1), garbled below."""
    lib = avr_lib()
    sm = samples // 2 + 1
    rslow = 9 * samples / (9 * samples + sm - 1)
    rx_bit = 1000.0
    above = [lib.avr_model_uart_resample(b, rx_bit / (rslow * 1.0005), rx_bit, samples) for b in range(256)]
    below = [lib.avr_model_uart_resample(b, rx_bit / (rslow * 0.9995), rx_bit, samples) for b in range(256)]
    assert above == list(range(256))
    assert sum(got != b for b, got in enumerate(below)) >= 128, below


# ---- the link of the real firmware --------------------------------------------------------------------
@pytest.mark.parametrize("host_baud", [57600, 58824])
def test_avr_link_at_57600_baud_is_intact_both_ways(host_baud):
    """The firmware's 57600 setting (UBRR0 = 34, U2X0: 57143 baud, -0.8 %) against a host at
    exactly 57600 (a crystal-timed adapter or radio) and against the Mega's own USB bridge, whose
    stock ATmega16U2 firmware runs 57600 at normal speed, UBRR1 = 16: 58824 baud (+2.1 %, so 2.9 %
    between the two ends): no byte garbled either way, the command is acknowledged, telemetry
    decodes."""
    with Firmware(backend="avr") as fw:
        assert fw._lib.sil_avr_host_baud() == 57600
        fw._lib.sil_avr_set_host_baud(host_baud)
        h, msgs = host_exchange(fw, 1_500_000)
        st = link_stats(fw)
        assert st["to_host"] > 1000 and st["to_avr"] > 100, st
        assert st["to_host_garbled"] == 0 and st["to_avr_garbled"] == 0, st
        assert [a.result for a in h.acks if a.command == CMD_SET_BEHAVIOURS] == [0], h.acks
        assert sum(m.get_type() == "HEARTBEAT" for m in msgs) >= 1, [m.get_type() for m in msgs]
        print(f"57600 link, host at {host_baud}: {st}")


@pytest.mark.parametrize("ubrr, u2x, host_baud", [(31, 1, 57600), (36, 1, 57600), (34, 1, 115200)])
def test_avr_link_with_a_wrong_divisor_garbles_bytes(ubrr, u2x, host_baud):
    """A divisor off from the host's rate by more than a receiver tolerates (UBRR0 = 31: 62500 baud,
    +8.5 %; 36: 54054 baud, -6.2 %; the 57600 setting against a 115200 host): bytes arrive
    garbled both ways, nothing decodes, the command goes unanswered. The same divisor with the
    host following the firmware's rate (simavr's own UART) shows nothing wrong."""
    with Firmware(backend="avr") as fw:
        fw._lib.sil_avr_set_host_baud(host_baud)
        fw._lib.sil_avr_set_uart_divisor(ubrr, u2x)
        h, msgs = host_exchange(fw, 1_500_000)
        st = link_stats(fw)
        actual = F_CPU / ((8 if u2x else 16) * (ubrr + 1))
        assert st["to_host_garbled"] >= 0.5 * st["to_host"] and st["to_avr_garbled"] >= 0.5 * st["to_avr"], \
            f"UBRR0 {ubrr} U2X0 {u2x} ({actual:.0f} baud) vs host {host_baud}: {st}"
        assert st["to_host_framing"] > 0, st
        assert not [a for a in h.acks if a.command == CMD_SET_BEHAVIOURS], h.acks
        assert not [m for m in msgs if m.get_type() == "HEARTBEAT"], "heartbeat decoded through a garbled link"
        print(f"UBRR0 {ubrr} U2X0 {u2x} ({actual:.0f} baud) vs host {host_baud}: {st}")

    with Firmware(backend="avr") as fw:
        fw._lib.sil_avr_set_host_baud(0)
        fw._lib.sil_avr_set_uart_divisor(ubrr, u2x)
        h, msgs = host_exchange(fw, 1_500_000)
        assert link_stats(fw)["to_host_garbled"] == 0
        assert [a.result for a in h.acks if a.command == CMD_SET_BEHAVIOURS] == [0], h.acks


def test_harness_host_baud_garbles_the_output_of_a_wrong_rate():
    """avr_harness --host-baud: the firmware's 57600 output read by a 57600 host is intact (MAVLink
    decodes), read by a 62500 host (+8.5 %) it is garbled and no known message decodes (what does
    parse is BAD_DATA, or an unknown id, whose CRC pymavlink cannot check)."""
    elf = REPO / "build" / "sil" / "agnav_megaatmega2560.elf"
    Firmware(backend="avr").close()  # builds the ELF copy and the library when stale
    subprocess.run(["make", "-s", "build/bin/avr_harness"], cwd=REPO, check=True)
    results = {}
    for baud in (57600, 62500):
        out = subprocess.run([str(HARNESS), "--seconds", "1.2", "--host-baud", str(baud), str(elf)],
                             capture_output=True, timeout=120)
        assert out.returncode == 4, out.stderr.decode()
        m = re.search(rb"uart_link host_baud=(\d+) to_host=(\d+) garbled=(\d+) framing=(\d+)", out.stderr)
        assert m, out.stderr.decode()
        results[baud] = (int(m.group(2)), int(m.group(3)), sum(not f.get_type().startswith(("BAD_DATA", "UNKNOWN")) for f in decode(out.stdout)))
    sent, garbled, frames = results[57600]
    assert sent > 300 and garbled == 0 and frames >= 5, results
    sent, garbled, frames = results[62500]
    assert garbled >= 0.5 * sent and frames == 0, results


# ---- EEPROM programming time ---------------------------------------------------------------------------
EE_PROGRAM = r"""
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
static void put(uint8_t c) { while (!(UCSR0A & (1 << UDRE0))) {} UDR0 = c; }
int main(void)
{
    UBRR0 = 16; UCSR0A = 1 << U2X0; UCSR0C = 6; UCSR0B = 1 << TXEN0;
    put('A');
    for (uint8_t i = 0; i < N_BYTES; i++) {
        eeprom_write_byte((uint8_t *)(uintptr_t)(0x100 + i), (uint8_t)(0x30 + i)); /* waits for EEPE first */
    }
    eeprom_busy_wait();
    put('B');
    for (uint8_t i = 0; i < N_BYTES; i++) {
        put(eeprom_read_byte((const uint8_t *)(uintptr_t)(0x100 + i)));
    }
    cli();
    sleep_enable();
    sleep_cpu();
    return 0;
}
"""


@pytest.mark.parametrize("write_us", [EEPROM_WRITE_US, 0])
def test_eeprom_write_holds_eepe_for_the_programming_time(tmp_path, write_us):
    """20 bytes written with avr-libc's eeprom_write_byte (it busy-waits on EEPE) take 20 x 3.3 ms
    with the board model, and the bytes read back; --eeprom-write-us 0 is simavr 1.6's own
    EEPROM, which finishes every write at once (under 1 ms for all 20)."""
    n = 20
    src = tmp_path / "ee.c"
    src.write_text(EE_PROGRAM)
    elf = tmp_path / "ee.elf"
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", "-DF_CPU=16000000UL", f"-DN_BYTES={n}", str(src), "-o",
                    str(elf)], check=True)
    subprocess.run(["make", "-s", "build/bin/avr_harness"], cwd=REPO, check=True)
    out = subprocess.run([str(HARNESS), "--timestamps", "--seconds", "2", "--eeprom-write-us", str(write_us), str(elf)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    rows = [(int(t), int(b, 16)) for t, b in (line.split() for line in out.stdout.splitlines())]
    assert [b for _, b in rows] == [ord("A"), ord("B")] + [0x30 + i for i in range(n)], rows
    took_us = rows[1][0] - rows[0][0]
    if write_us:
        assert n * write_us <= took_us <= n * write_us + 1_000, f"{n} EEPROM bytes took {took_us} us"
        assert f"eeprom_writes={n} " in out.stderr, out.stderr
    else:
        assert took_us < 1_000, f"simavr's own EEPROM took {took_us} us for {n} bytes"
    print(f"write_us={write_us}: {n} bytes in {took_us} us")


def test_avr_control_gap_reads_the_control_period_and_a_save_programs_every_changed_byte():
    """sil_avr_control_gap_max_us: about 20 ms (the 50 Hz control task) in normal running. A
    parameter save over the link (PARAM_SET + PREFLIGHT_STORAGE) programs at least every EEPROM
    byte that changed, each holding EEPE for 3.3 ms; the worst control period across the save is
    printed (what a storage change is measured by)."""
    with Firmware(backend="avr") as fw:
        host_exchange(fw, 300_000)
        fw._lib.sil_avr_control_gap_max_us()
        t0, ticks0 = fw.time_us, fw._lib.sil_avr_control_ticks()
        host_exchange(fw, 1_000_000)
        gap = fw._lib.sil_avr_control_gap_max_us()
        rate_hz = (fw._lib.sil_avr_control_ticks() - ticks0) / ((fw.time_us - t0) * 1e-6)
        assert 19_000 <= gap <= 25_000, f"control gap {gap} us in normal running"
        assert 45 <= rate_hz <= 51, f"control ticks at {rate_hz:.1f} Hz"

        before = fw.eeprom()
        writes0 = fw._lib.sil_avr_eeprom_writes()
        h = HostEndpoint()
        h.param_set("LINK_TIMEOUT_MS", 1234)
        h.command_long(245, 1)
        fw.uart_write(h.take_tx())
        t_save = fw.time_us
        _, _ = host_exchange(fw, 1_500_000)
        changed = sum(a != b for a, b in zip(before, fw.eeprom()))
        writes = fw._lib.sil_avr_eeprom_writes() - writes0
        gap = fw._lib.sil_avr_control_gap_max_us()
        assert changed > 0 and writes >= changed, f"{changed} bytes changed, {writes} programmed"
        assert fw.reset_count == 0
        print(f"save at t={t_save} us: {writes} bytes programmed ({writes * EEPROM_WRITE_US} us of EEPE), "
              f"{changed} changed; worst control period {gap} us")
