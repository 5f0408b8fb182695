#!/usr/bin/env python3
"""Firmware benchmarks on the real ATmega2560 build under simavr (16 MHz).

    .venv/bin/python bench/bench_firmware.py [--seconds 4] [--markdown bench/results/firmware.md]

Builds the `megaatmega2560_bench` profile (differential drive, 4 quadrature encoders, all
behaviour layers on, 12 sonars) and runs it in build/bin/avr_harness with every sonar echoing
a wall at 0.8 m, 4 encoders stepping at 2 kHz each (1 and 3 backward, mirrored right wheels) and a live host (HEARTBEAT + drive setpoint
at 10 Hz). Prints:
  - flash and static RAM per module and in total (linker map, tools/fw_size.py);
  - worst run time of each scheduler task as the firmware itself measured it (NAMED_VALUE_INT
    "T_<task>", us, 4 us resolution) and the control tick in cycles;
  - flash of the default `megaatmega2560` build (the flash target's), and the control task's worst
    period (gap between ticks) with a 20 Hz host: no key, key + SIGN_TELEM 1, key + SIGN_TELEM 0, and both again with a COMMAND_LONG
    every 0.5 s (signed answers; acks and receive errors show that no frame was lost);
  - per-function cycles from the non-LTO `megaatmega2560_profile` build (where the time goes);
  - encoder ISR cycles (PCINT2 vector entry to return), staggered edges and all 4 at once;
  - cycles of the other interrupts (sonar echo, UART0 RX / TX, Timer5 overflow) in the main run;
  - the highest single-encoder edge rate with zero lost counts (sweep);
  - sonar ring update rate; simavr speed (simulated / wall-clock time).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "host"))

from agnav_host.protocol import dialect  # noqa: E402

HARNESS = REPO / "build" / "bin" / "avr_harness"
F_CPU = 16_000_000
TARGETS = {"flash_B": 48 * 1024, "ram_B": 3 * 1024, "tick_us": 1000, "isr_cycles": 60,
           "edge_rate_hz": 40_000, "ring_hz": 10.0, "period_ms": 21.0}


# PLATFORMIO_BUILD_DIR is honoured (several engineers build in one checkout); the non-LTO build
# for the per-module size split goes next to it.
BUILD_DIR = Path(os.environ.get("PLATFORMIO_BUILD_DIR", str(REPO / ".pio" / "build")))


def pio_env(**extra: str) -> dict:
    return {**os.environ, "PLATFORMIO_CORE_DIR": str(REPO / ".pio-core"),
            "PLATFORMIO_DISABLE_UPGRADE_CHECK": "true", "PLATFORMIO_BUILD_DIR": str(BUILD_DIR), **extra}


def build(env: str) -> Path:
    subprocess.run([str(REPO / ".venv" / "bin" / "pio"), "run", "-s", "-e", env], cwd=REPO, env=pio_env(),
                   check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["make", "-s", "build/bin/avr_harness"], cwd=REPO, check=True)
    return BUILD_DIR / env / "firmware.elf"


def size_table(env: str) -> str:
    """Flash/RAM per module and in total, exactly as tools/fw_size.py prints it (same build dirs)."""
    sys.path.insert(0, str(REPO / "tools"))
    import fw_size  # noqa: E402

    fw_size.build(env)
    return fw_size.table(env) or "(no size table)"


def host_frames_hex() -> str:
    d = dialect()
    m = d.MAVLink(None, srcSystem=255, srcComponent=190)
    b = d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3).pack(m)
    b += d.MAVLink_agnav_drive_setpoint_message(1, 1, 500, 600, 0, 0, 0, 1).pack(m)
    return b.hex()


def run(elf: Path, seconds: float, extra: list[str]) -> tuple[list, str, float]:
    t0 = time.perf_counter()
    out = subprocess.run([str(HARNESS), "--seconds", str(seconds), *extra, str(elf)], capture_output=True, timeout=600)
    wall = time.perf_counter() - t0
    mav = dialect().MAVLink(None)
    msgs = mav.parse_buffer(out.stdout) or []
    return msgs, out.stderr.decode(), wall


def symbol_addrs(elf: Path, names: list[str]) -> list[str]:
    nm = subprocess.run(["avr-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    args = []
    for name in names:
        m = re.search(rf"^([0-9a-f]+) [Tt] {re.escape(name)}$", nm, re.M)
        if m:
            args += ["--profile", f"{name}:0x{m.group(1)}"]
    return args


def control_period_us(elf: Path, key: bytes | None, sign_telem: int, seconds: float = 4.0,
                      commands: bool = False) -> tuple[int, int, str]:
    """Worst gap between two control ticks (watchdog kicks, us) and watchdog resets, with a 20 Hz
    host (HEARTBEAT + setpoint), signing key pushed when key is given, parameter SIGN_TELEM set.
    The same rig as hil/tests/test_avr_safety.py (hil/simavr/avr_sil.c). With commands, the host
    also sends a COMMAND_LONG (arm) every 0.5 s, which the robot answers with a COMMAND_ACK (signed
    when SIGN_TELEM is 1). Third value: "acks/commands, SYS_STATUS receive errors" (frames lost
    in the UART queue would show as missing acks or CRC / signature errors)."""
    from agnav_host.link.keys import setup_signing_message
    from agnav_host.sil import Firmware

    d = dialect()

    def codec(k: bytes | None):
        mav = d.MAVLink(None, srcSystem=255, srcComponent=190)
        if k is not None:
            mav.signing.secret_key, mav.signing.sign_outgoing, mav.signing.link_id = k, True, 1
            mav.signing.timestamp = int((1.8e9 - 1420070400) * 100_000)
        return mav

    rx = d.MAVLink(None)
    rx.robust_parsing = True
    tally = {"sent": 0, "acks": 0, "errors": 0}

    def host(fw, us: int, mav) -> None:
        end, seq = fw.time_us + us, 0
        while fw.time_us < end:
            seq += 1
            fw.uart_write(d.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mav))
            fw.uart_write(d.MAVLink_agnav_drive_setpoint_message(1, 1, 0, 0, 0, 0, 0, seq & 0xFFFF).pack(mav))
            if commands and seq % 10 == 0:
                fw.uart_write(d.MAVLink_command_long_message(1, 1, d.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                                             1, 0, 0, 0, 0, 0, 0).pack(mav))
                tally["sent"] += 1
            fw.step_to(min(end, fw.time_us + 50_000))
            fw.take_triggers()
            for m in rx.parse_buffer(fw.uart_read()) or []:
                if m.get_type() == "COMMAND_ACK":
                    tally["acks"] += 1
                elif m.get_type() == "SYS_STATUS":
                    tally["errors"] = (m.errors_comm + m.errors_count2 + m.errors_count3 + m.errors_count4)

    with Firmware(backend="avr", elf=elf) as fw:
        fw.set_stop_on_trigger(False)
        host(fw, 100_000, codec(None))
        fw.param_set("SIGN_TELEM", sign_telem)
        if key is not None:
            fw.uart_write(setup_signing_message(d, key, 1, unix_s=1.8e9).pack(codec(None)))
        mav = codec(key)  # one signing stream throughout (a second codec would replay its timestamps)
        host(fw, 1_000_000, mav)
        fw.kick_gap_max_us()
        host(fw, int(seconds * 1e6), mav)
        gap = fw.kick_gap_max_us()
        # an answer still on its way when the window closes is not a lost frame: 200 ms more, nothing sent
        fw.step_to(fw.time_us + 200_000)
        for m in rx.parse_buffer(fw.uart_read()) or []:
            if m.get_type() == "COMMAND_ACK":
                tally["acks"] += 1
        return gap, fw.reset_count, f"{tally['acks']}/{tally['sent']}, {tally['errors']}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds of the main run")
    ap.add_argument("--markdown", type=Path, help="also write the results as a markdown table here")
    args = ap.parse_args(argv)
    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    elf = build("megaatmega2560_bench")
    size = size_table("megaatmega2560_bench")
    say("## Flash and static RAM (ATmega2560, benchmark profile, LTO)")
    say("```")
    say(size.rstrip())
    say("```")

    # --enc-mirror: the right wheels turn their encoders backward (both decode paths of the ISR)
    stim = ["--enc-count", "4", "--enc-hz", "2000", "--enc-mirror", "--sonar-mm", "800",
            "--uart-inject-hex", host_frames_hex(), "--uart-inject-hz", "10", "--isr-stats"]
    # Interrupt vectors of the LTO build (cycles from the vector body to reti, so add the table's
    # 3-cycle jmp and the 5-cycle interrupt response for the whole cost): the echo body serves
    # PCINT0 (__vector_9) and INT0..3, which share its address.
    vectors = {"__vector_9": "sonar echo (PCINT0, INT0..3)", "__vector_25": "UART0 RX",
               "__vector_26": "UART0 UDRE (TX)", "__vector_50": "Timer5 overflow"}
    msgs, err, wall = run(elf, args.seconds, stim + symbol_addrs(elf, list(vectors)))
    worst = {}
    rings = []
    for m in msgs:
        if m.get_type() == "NAMED_VALUE_INT" and m.name.startswith("T_"):
            worst[m.name[2:]] = max(worst.get(m.name[2:], 0), m.value)
        elif m.get_type() == "AGNAV_SONAR_RING":
            rings.append((m.time_boot_ms, m.seq))
    say("")
    say(f"## Scheduler tasks, worst run time measured by the firmware ({args.seconds:.0f} simulated s, 4 encoders at 2 kHz, 12 sonars, live host)")
    say("| task | worst us | worst cycles |")
    say("|---|---:|---:|")
    for name, us in worst.items():
        say(f"| {name} | {us} | {us * F_CPU // 1_000_000} |")
    tick = worst.get("control", 0)
    say(f"control tick worst {tick} us = {tick * 16} cycles (target <= {TARGETS['tick_us']} us): "
        f"{'OK' if tick <= TARGETS['tick_us'] else 'OVER'}")
    m = re.search(r"encoder_isr_cycles n=(\d+) min=(\d+) mean=([\d.]+) max=(\d+)", err)
    if m:
        say(f"encoder ISR cycles: min {m.group(2)}, mean {m.group(3)}, max {m.group(4)} over {m.group(1)} interrupts "
            f"(target <= {TARGETS['isr_cycles']}): {'OK' if int(m.group(4)) <= TARGETS['isr_cycles'] else 'OVER'}")
    # The shared PORTK vector's other worst case: every encoder's lines change before it runs
    # (one interrupt decodes all four; not the figure the target is for, reported beside it).
    _, aerr, _ = run(elf, 1.0, ["--enc-count", "4", "--enc-hz", "2000", "--enc-mirror", "--enc-aligned",
                                 "--isr-stats"])
    am = re.search(r"encoder_isr_cycles n=(\d+) min=(\d+) mean=([\d.]+) max=(\d+)", aerr)
    if am:
        say(f"encoder ISR cycles with all 4 encoders' edges in one interrupt (--enc-aligned): max {am.group(4)} "
            f"= {int(am.group(4)) / 4:.1f} per edge over {am.group(1)} interrupts")
    say("")
    say("| interrupt (LTO build, same run) | count | mean cycles | max cycles |")
    say("|---|---:|---:|---:|")
    for pm in re.finditer(r"profile (\S+) n=(\d+) min=(\d+) mean=([\d.]+) max=(\d+)", err):
        if pm.group(1) in vectors:
            say(f"| {vectors[pm.group(1)]} | {pm.group(2)} | {float(pm.group(4)):.0f} | {pm.group(5)} |")
    say("")
    if len(rings) >= 2:
        (t0, s0), (t1, s1) = rings[1], rings[-1]
        hz = (s1 - s0) / ((t1 - t0) / 1000.0)
        say(f"sonar ring: {hz:.2f} full 12-sensor rings per second (target >= {TARGETS['ring_hz']}): "
            f"{'OK' if hz >= TARGETS['ring_hz'] else 'UNDER'}")
    say(f"simavr speed: {args.seconds / wall:.2f}x real time ({args.seconds:.1f} simulated s in {wall:.2f} s wall)")

    default_elf = build("megaatmega2560")
    sys.path.insert(0, str(REPO / "tools"))
    import fw_size  # noqa: E402

    d_flash, d_ram = fw_size.totals(default_elf)
    say("")
    say(f"Default `megaatmega2560` build (the one the flash target is for): flash {d_flash} B of "
        f"{TARGETS['flash_B']} B ({'OK' if d_flash <= TARGETS['flash_B'] else 'OVER'}), static RAM {d_ram} B")
    say("")
    say("## Control task period (worst gap between ticks, default build, 20 Hz host, 4 simulated s)")
    say("| signing | SIGN_TELEM | host also sends | worst period ms | watchdog resets | acks/commands, rx errors |")
    say("|---|---:|---|---:|---:|---|")
    key = bytes(range(1, 33))
    for label, k, st, cmd in (("no key", None, 1, False), ("key set", key, 1, False), ("key set", key, 0, False),
                              ("key set", key, 1, True), ("key set", key, 0, True)):
        gap, resets, lost = control_period_us(default_elf, k, st, commands=cmd)
        say(f"| {label} | {st} | {'COMMAND_LONG every 0.5 s' if cmd else '-'} | {gap / 1000:.1f} | {resets} | {lost} |")
    say(f"target: worst period <= {TARGETS['period_ms']} ms with a key")

    prof_elf = build("megaatmega2560_profile")
    names = ["control_task", "encoder_update", "encoder_snapshot", "health_encoders", "odom_update_diff",
             "behaviour_step", "drive_apply",
             "telemetry_task_50hz", "telemetry_task", "task_link", "sonar_ring_step", "link_send"]
    _, perr, _ = run(prof_elf, min(args.seconds, 3.0), stim + symbol_addrs(prof_elf, names))
    say("")
    say("## Where the time goes (non-LTO build, cycles per call)")
    say("| function | calls | mean | max |")
    say("|---|---:|---:|---:|")
    for pm in re.finditer(r"profile (\S+) n=(\d+) min=(\d+) mean=([\d.]+) max=(\d+)", perr):
        say(f"| {pm.group(1)} | {pm.group(2)} | {float(pm.group(4)):.0f} | {pm.group(5)} |")

    say("")
    say("## Highest single-encoder edge rate with zero lost counts (2 simulated s each)")
    say("| edges/s | counted | expected | errors | lost |")
    say("|---:|---:|---:|---:|---|")
    best = 0
    for rate in (10_000, 20_000, 30_000, 40_000, 50_000, 60_000):
        msgs, _, _ = run(elf, 2.0, ["--enc-count", "1", "--enc-hz", str(rate), "--sonar-mm", "800",
                                    "--uart-inject-hex", host_frames_hex(), "--uart-inject-hz", "10"])
        enc = [x for x in msgs if x.get_type() == "AGNAV_ENCODER_STATUS"]
        if not enc:
            say(f"| {rate} | - | - | - | no telemetry |")
            continue
        last = enc[-1]
        # edges start 0.5 s after boot; the snapshot was taken at last.time_boot_ms
        expected = int((last.time_boot_ms / 1000.0 - 0.5) * rate)
        counted = last.count[0]
        lost = last.errors[0] > 0 or abs(counted - expected) > rate * 0.02 + 2
        say(f"| {rate} | {counted} | ~{expected} | {last.errors[0]} | {'yes' if lost else 'no'} |")
        if not lost:
            best = rate
    say(f"highest rate without lost counts: {best} edges/s (target >= {TARGETS['edge_rate_hz']}): "
        f"{'OK' if best >= TARGETS['edge_rate_hz'] else 'UNDER'}")
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("Command: `.venv/bin/python bench/bench_firmware.py --markdown bench/results/firmware.md`\n\n"
                                 + "\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
