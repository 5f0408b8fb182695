# AgNav: two commands do everything on a fresh Debian machine.
#   make demo   install what is missing, then run the default mission
#   make test   install what is missing, then every test suite, ending "N passed, N failed"
#   make setup  only the installing (both of the above call it; idempotent)
SHELL := /bin/bash
.DEFAULT_GOAL := help

VENV        := .venv
PY          := $(VENV)/bin/python
PIO         := $(VENV)/bin/pio
export PLATFORMIO_CORE_DIR := $(CURDIR)/.pio-core
export PLATFORMIO_DISABLE_UPGRADE_CHECK := true
export PLATFORMIO_NO_ANSI := true
export PLATFORMIO_SETTING_ENABLE_TELEMETRY := No
export PLATFORMIO_SETTING_CHECK_PLATFORMIO_INTERVAL := 3650

APT_PACKAGES := gcc-avr avr-libc avrdude simavr libsimavr-dev libelf-dev \
                gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm \
                binutils-avr pkg-config clang libclang-rt-dev

.PHONY: help setup apt venv tools demo test test-host test-firmware test-sil sil size bench bench-sil faults attacks fuzz clean

help:
	@echo "make demo   - install what is missing, run the default mission (output in out/demo)"
	@echo "make test   - install what is missing, run every test suite"
	@echo "make setup  - only install (Debian packages, .venv, PlatformIO offline pieces)"
	@echo "make size   - AVR flash/RAM use of the firmware (avr-size)"
	@echo "make bench  - benchmarks (figures go to BENCHMARKS.md by hand)"
	@echo "make fuzz SECONDS=N - libFuzzer on the firmware's MAVLink link for N s (needs clang)"
	@echo "make faults - fault-injection suite: fault, expected reaction, measured reaction, pass/fail"
	@echo "make attacks - attacks from a MAVLink client on the served SIL: attack, tries, refused, moved, crashed"

setup: apt venv tools

# Debian packages: installed only when one is missing (a second run installs nothing).
apt:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "setup: installing Debian packages:" $$missing; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q --no-install-recommends $$missing; \
	fi

venv: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml requirements-lock.txt
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r requirements-lock.txt
	$(PY) -m pip install -q --disable-pip-version-check --no-deps -e .
	@touch $@

tools: build/bin/avr_harness

build/bin/avr_harness: hil/simavr/avr_harness.c hil/simavr/avr_board_model.c hil/simavr/avr_board_model.h
	@mkdir -p build/bin
	cc -O2 -Wall -Wextra -o $@ hil/simavr/avr_harness.c hil/simavr/avr_board_model.c -lsimavr -lelf

# The default mission: the real firmware (native SIL) in lock-step with the world simulator,
# driven by the default host planner over the modelled 57600-baud radio link.
demo: setup sil
	$(VENV)/bin/agnav sim --firmware sil --out out/demo

# Native software-in-the-loop library (the firmware built against the simulated HAL).
sil: build/sil/libagnav_sil.so
build/sil/libagnav_sil.so: firmware/src/main.c $(wildcard firmware/lib/*/*.[ch] firmware/lib/hal/sim/*) hil/sil/sil_api.c $(wildcard hil/sil/*.h) protocol/agnav.xml | venv
	$(PY) -m agnav_host.sil.build

test: setup sil
	@bash tools/run_all_tests.sh

test-host: setup
	$(VENV)/bin/pytest -q

test-firmware: setup
	$(PIO) test -e native

test-sil: setup sil
	$(VENV)/bin/pytest -q hil/tests/test_sil_api.py hil/tests/test_sil_scenarios.py

bench-sil: setup sil
	$(PY) bench/bench_sil.py

# Every fault scenario (radio, sensors, controller, bad commands, signing, host I/O) with its
# measured reaction; the markdown table goes to bench/results/faults.md (RELIABILITY.md cites it).
faults: setup sil
	$(VENV)/bin/agnav faults --markdown bench/results/faults.md

# Attacks from outside: a MAVLink client of its own (not the project's link classes) against
# `agnav sil fault_yard --tcp` in a subprocess, motion judged on the simulator's true pose; the markdown
# table (attack, tries, refused, moved, crashed, target, met) goes to bench/results/attacks.md.
attacks: setup sil
	$(PY) -m agnav_host.faults.attacks --markdown bench/results/attacks.md

# libFuzzer + ASan + UBSan on the firmware's MAVLink parser and handlers (firmware/fuzz/): builds
# with clang into build/fuzz, runs SECONDS (default 60; MODE=all|both|crc|raw|signed, WORKERS=1) and prints
# executions, exec/s and findings; exits non-zero when anything was found (build/fuzz/artifacts).
fuzz: setup
	nice -n 10 $(PY) firmware/fuzz/fuzz.py run --seconds $(or $(SECONDS),60) --mode $(or $(MODE),all) --workers $(or $(WORKERS),1)

size: setup
	$(PIO) run -s -e megaatmega2560
	avr-size -A -d .pio/build/megaatmega2560/firmware.elf
	avr-size .pio/build/megaatmega2560/firmware.elf

clean:
	rm -rf .pio build out
