"""AVR SIL benchmark: speed of the real ATmega2560 ELF under libsimavr (build/sil/libagnav_avr_sil.so)
against real time, alone and in lock step, compared with the native SIL.

Run: .venv/bin/python bench/bench_avr_sil.py [--busy-elf PATH] [--seconds S] [--elf PATH] [--lib-dir DIR]
     (prints a markdown table; numbers depend on the machine and its load)
     --elf: the AVR ELF to measure (default: `pio run -e megaatmega2560`, copied to build/sil/);
     --lib-dir: build libagnav_sil.so and libagnav_avr_sil.so in DIR instead of build/sil/
     (with --elf, nothing is written to build/sil/).

1. firmware alone: S simulated seconds, no host, every sonar trigger answered with a 1.5 m echo
   (so the ring and its interrupts run), stop-on-trigger as in lock step;
2. lock step: hil/tests/scenarios/open_field.toml, host pure pursuit to the waypoint at 15 Hz,
   world step 10 ms (robot model, encoder edges, 12-sonar echoes, radio link model, host endpoint
   decoding all telemetry), S simulated seconds;
both for the native SIL, the AVR SIL on the PlatformIO ELF (idle sleep in the main loop) and,
with --busy-elf, an ELF whose main loop spins (e.g. built from commit c595cb2, before the idle
sleep); and the busy ELF once more with simavr's INTn low-level polling left on
(AGNAV_AVR_SIL_LEVEL_POLL=1: what the AVR build cost before avr_sil.c turned it off).
"wall" is perf_counter time, "CPU" is process time (the container is shared: CPU is the steadier
figure). "x real time" = simulated s / wall s.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _use_libs(libs: dict[str, str] | None) -> None:
    """Point the binding's on-demand library builds at the given files ({"native": path, "avr": path})."""
    if not libs:
        return
    from agnav_host.sil import avr_build, binding

    binding.build_library = lambda *a, **k: Path(libs["native"])
    avr_build.build_avr_library = lambda *a, **k: Path(libs["avr"])


def fw_alone(backend: str, seconds: float, elf: str | None, libs: dict[str, str] | None = None) -> dict[str, float]:
    _use_libs(libs)
    from agnav_host.sil import Firmware

    width = round(2 * 1.5 / 343.0 * 1e6)
    with Firmware(backend=backend, elf=elf) as fw:
        end = fw.time_us + int(seconds * 1e6)
        w0, c0 = time.perf_counter(), time.process_time()
        i0 = fw._lib.sil_avr_instructions() if backend == "avr" else 0
        while fw.time_us < end:
            fw.step_to(end)
            for idx, t in fw.take_triggers():
                fw.queue_echo(idx, t + 450, 1)
                fw.queue_echo(idx, t + 450 + width, 0)
            fw.uart_read()
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        instr = (fw._lib.sil_avr_instructions() - i0) if backend == "avr" else 0
        return {"sim": seconds, "wall": wall, "cpu": cpu, "instr": instr, "resets": fw.resets}


def lock_step(backend: str, seconds: float, elf: str | None, libs: dict[str, str] | None = None) -> dict[str, float]:
    _use_libs(libs)
    from agnav_host.sil import SilConfig, SilSession
    from agnav_host.sim import load_scenario

    sys.path.insert(0, str(REPO / "hil" / "tests"))
    from _sil_logic import PurePursuit  # the scenario tests' host

    sc = load_scenario(str(REPO / "hil/tests/scenarios/open_field.toml"))
    s = SilSession(sc, 0, SilConfig(firmware=backend, firmware_elf=elf), PurePursuit())
    try:
        s.provision()
        t0 = s.t_s
        w0, c0 = time.perf_counter(), time.process_time()
        s.run_for(seconds)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        g = sc.goals[0]
        return {"sim": s.t_s - t0, "wall": wall, "cpu": cpu, "err": math.hypot(g.x_m - s.pose.x_m, g.y_m - s.pose.y_m),
                "resets": s.fw.resets}
    finally:
        s.close()


def run_child(kind: str, backend: str, seconds: float, elf: str | None, env: dict[str, str],
              libs: dict[str, str] | None = None) -> dict[str, float]:
    """Each measurement in its own process (fresh library copies, env knobs apply at load)."""
    code = (f"import sys, json; sys.path.insert(0, {str(REPO / 'bench')!r}); import bench_avr_sil as b; "
            f"print(json.dumps(b.{kind}({backend!r}, {seconds!r}, {elf!r}, {libs!r})))")
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, env={**os.environ, **env})
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    import json

    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--busy-elf", default=None, help="an AVR ELF without idle sleep, for comparison")
    ap.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per measurement (default 20)")
    ap.add_argument("--elf", default=None,
                    help="the AVR ELF to measure (default: the PlatformIO build, rebuilt when stale)")
    ap.add_argument("--lib-dir", default=None, help="build the two SIL libraries here instead of build/sil/")
    ns = ap.parse_args()
    from agnav_host.sil import build_avr_elf, build_avr_library, build_library

    libs = None
    if ns.lib_dir:
        d = Path(ns.lib_dir)
        libs = {"native": str(build_library(d / "libagnav_sil.so")),
                "avr": str(build_avr_library(d / "libagnav_avr_sil.so"))}
    else:
        build_library()
        build_avr_library()
    elf = ns.elf or str(build_avr_elf())
    rows = [("native SIL", "native", None, {}), ("AVR SIL, idle-sleep ELF (HEAD)", "avr", elf, {})]
    if ns.busy_elf:
        rows += [("AVR SIL, busy-loop ELF", "avr", ns.busy_elf, {}),
                 ("AVR SIL, busy-loop ELF, simavr INTn level polling on", "avr", ns.busy_elf,
                  {"AGNAV_AVR_SIL_LEVEL_POLL": "1"})]
    print(f"# AVR SIL benchmark ({ns.seconds:g} simulated s per row)\n")
    print("| Firmware | What | Simulated | Wall | CPU | x real time (wall) | x real time (CPU) | notes |")
    print("|---|---|---|---|---|---|---|---|")
    for label, backend, e, env in rows:
        for kind, what in (("fw_alone", "firmware alone, sonar echoes answered"),
                           ("lock_step", "lock step, open_field pure pursuit, 10 ms world step")):
            if kind == "lock_step" and env:
                continue
            r = run_child(kind, backend, ns.seconds, e, env, libs)
            note = []
            if r.get("instr"):
                note.append(f"{r['instr'] / r['cpu'] / 1e6:.1f} M AVR instr / CPU s, "
                            f"{r['instr'] / r['sim'] / 1e6:.1f} M instr / simulated s")
            if "err" in r:
                note.append(f"ended {r['err']:.2f} m from the goal")
            if r.get("resets"):
                note.append(f"{r['resets']} watchdog resets")
            print(f"| {label} | {what} | {r['sim']:.1f} s | {r['wall']:.2f} s | {r['cpu']:.2f} s | "
                  f"{r['sim'] / r['wall']:.1f}x | {r['sim'] / r['cpu']:.1f}x | {'; '.join(note)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
