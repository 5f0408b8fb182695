"""Fuzz regressions: every saved input of firmware/fuzz/regressions replayed through the whole
native firmware (the fuzz target without libFuzzer, gcc + ASan + UBSan), so `make test` keeps
the bugs the fuzzer found fixed on machines that never run clang or the fuzzer.

regressions/raw/ inputs go to the link UART as they are; regressions/crc/ inputs first get their
frame CRCs rewritten (the fuzzer's deep mode, where they were found). The signed mode (a key set,
every MAVLink 2 frame signed by the harness) is checked on the same inputs.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pymavlink.generator.mavcrc import x25crc

from agnav_host.protocol import new_codec

REPO = Path(__file__).resolve().parents[2]
FUZZ_DIR = REPO / "firmware" / "fuzz"
REGRESSIONS = FUZZ_DIR / "regressions"
LINE = re.compile(r"^replay: (\S+) \((\d+) bytes\) rx_frames=(\d+) rx_errors=(\d+) rx_unknown=(\d+)"
                  r" rx_unsigned=(\d+) rx_bad_signature=(\d+) rx_replay=(\d+)$", re.M)


def _fuzz_module():
    spec = importlib.util.spec_from_file_location("agnav_fuzz_driver", FUZZ_DIR / "fuzz.py")
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    sys.modules["agnav_fuzz_driver"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def replay() -> Path:
    return _fuzz_module().build_replay()


def _run(replay: Path, *args: str | Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=0:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
    return subprocess.run([str(replay), *map(str, args)], capture_output=True, text=True, timeout=120, env=env)


def _counters(out: str) -> dict[str, tuple[int, int, int]]:
    return {Path(m[0]).name: (int(m[2]), int(m[3]), int(m[4])) for m in LINE.findall(out)}


def _signing_counters(out: str) -> dict[str, tuple[int, int, int, int]]:
    """name -> (frames accepted, unsigned refused, bad signature, replayed)."""
    return {Path(m[0]).name: (int(m[2]), int(m[5]), int(m[6]), int(m[7])) for m in LINE.findall(out)}


@pytest.mark.parametrize("mode,flags", [("raw", []), ("crc", ["--fix-crc"]), ("raw", ["--sign"]), ("crc", ["--sign"])])
def test_every_regression_input_replays_without_a_sanitizer_report(replay: Path, mode: str, flags: list[str]) -> None:
    folder = REGRESSIONS / mode
    files = sorted(p.name for p in folder.iterdir() if p.is_file())
    assert files, f"no regression inputs in {folder}"
    r = _run(replay, *flags, folder)
    report = (r.stdout + r.stderr)[-3000:]
    assert r.returncode == 0, f"replay of {folder} failed (exit {r.returncode}):\n{report}"
    assert "runtime error" not in r.stderr and "Sanitizer" not in r.stderr, report
    assert sorted(_counters(r.stdout)) == files, f"not every input ran to its end:\n{report}"


def test_raw_regressions_are_frames_the_firmware_accepts(replay: Path) -> None:
    # The hand-made raw inputs are valid frames: each must reach the handlers (counted in rx_frames),
    # otherwise the input no longer tests what its name says.
    r = _run(replay, REGRESSIONS / "raw")
    for name, (frames, errors, unknown) in _counters(r.stdout).items():
        assert frames >= 1 and errors == 0 and unknown == 0, f"{name}: {frames} frames, {errors} errors, {unknown} unknown"


def test_fix_crc_mode_repairs_a_frame_that_raw_mode_drops(replay: Path, tmp_path: Path) -> None:
    mav = new_codec(255, 190)
    frame = bytearray(mav.param_request_list_encode(1, 1).pack(mav))
    frame[-1] ^= 0x5A  # break the CRC
    path = tmp_path / "bad_crc"
    path.write_bytes(bytes(frame))
    raw = _counters(_run(replay, path).stdout)["bad_crc"]
    fixed = _counters(_run(replay, "--fix-crc", path).stdout)["bad_crc"]
    assert raw == (0, 1, 0), f"raw mode: a bad CRC must be dropped and counted, got {raw}"
    assert fixed == (1, 0, 0), f"fix-crc mode: the frame must reach the handlers, got {fixed}"


def test_replay_fails_on_a_missing_input(replay: Path, tmp_path: Path) -> None:
    r = _run(replay, tmp_path / "does_not_exist")
    assert r.returncode != 0


def test_sign_mode_signs_every_mavlink2_frame_and_the_firmware_checks_them(replay: Path, tmp_path: Path) -> None:
    # With a key set, a MAVLink 2 frame the harness signed reaches the handlers; a MAVLink 1 frame (it
    # cannot be signed) is refused as unsigned; in raw mode (no key) both are accepted.
    mav = new_codec(255, 190)
    v2 = tmp_path / "v2_param_request_list"
    v2.write_bytes(bytes(mav.param_request_list_encode(1, 1).pack(mav)))
    v1 = tmp_path / "v1_heartbeat"
    header = bytes([0xFE, 9, 0, 255, 190, 0])  # MAVLink 1: STX, len, seq, sys, comp, msgid 0 (HEARTBEAT)
    payload = bytes([0, 0, 0, 0, 6, 8, 0, 0, 3])  # custom_mode, type GCS, autopilot INVALID, base_mode, status
    crc = x25crc(header[1:] + payload)
    crc.accumulate(bytes([50]))  # HEARTBEAT's crc_extra
    v1.write_bytes(header + payload + crc.crc.to_bytes(2, "little"))
    signed = _signing_counters(_run(replay, "--sign", v2, v1).stdout)
    assert signed["v2_param_request_list"] == (1, 0, 0, 0), f"signed v2 frame: {signed['v2_param_request_list']}"
    assert signed["v1_heartbeat"] == (0, 1, 0, 0), f"v1 frame with signing on: {signed['v1_heartbeat']}"
    assert _signing_counters(_run(replay, v1).stdout)["v1_heartbeat"] == (1, 0, 0, 0), "raw mode (no key) takes v1"
    plain = _signing_counters(_run(replay, v2).stdout)["v2_param_request_list"]
    assert plain == (1, 0, 0, 0), f"raw mode (no key): {plain}"
