"""Worst control period while the firmware saves each of its EEPROM records.

Run: .venv/bin/python bench/bench_storage.py [--backend avr|native|both]
     (prints a markdown table; simulated time, so the figures do not depend on the machine)

For each record (parameters, calibration tables, signing key) the firmware boots, a 10 Hz host settles the
link for 1.3 s, then asks for the save over MAVLink and keeps sending heartbeats until the final answer
(agnav_host.sil.storage_timing). "avr" is the real ATmega2560 ELF under simavr, where each programmed EEPROM
byte holds EEPE for 3.3 ms as on the chip; "native" is the firmware on the sim HAL with the same byte time.
Target: worst control period <= 21 ms (the 50 Hz budget) during every save.
"""

from __future__ import annotations

import argparse
import sys

from agnav_host.sil.storage_timing import RECORDS, save_timing

TARGET_US = 21_000


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", choices=("avr", "native", "both"), default="avr")
    ns = ap.parse_args(argv)
    backends = ("avr", "native") if ns.backend == "both" else (ns.backend,)
    print("| backend | record | bytes programmed | final answer after (s) | control period before (ms) "
          "| worst control period during the save (ms) | <= 21 ms |")
    print("|---|---|---|---|---|---|---|")
    ok = True
    for be in backends:
        for rec in RECORDS:
            t = save_timing(rec, be)
            met = t.worst_control_period_us <= TARGET_US and t.answer_s is not None
            ok &= met
            ans = "never" if t.answer_s is None else f"{t.answer_s:.2f}"
            print(f"| {be} | {rec} | {t.bytes_programmed} | {ans} | {t.normal_control_period_us / 1000:.2f} "
                  f"| {t.worst_control_period_us / 1000:.2f} | {'yes' if met else 'no'} |", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
