"""First light: the real ATmega2560 firmware under simavr sends HEARTBEAT at 1 Hz on UART0.

The simavr harness (hil/simavr/avr_harness.c) stamps every UART byte with simulated time;
pymavlink decodes the stream.
"""
import os
import subprocess
from pathlib import Path

import pytest

from agnav_host.protocol import dialect

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "build" / "bin" / "avr_harness"


def firmware_elf() -> Path:
    """The ELF `pio run -e megaatmega2560` (started in REPO) writes: under $PLATFORMIO_BUILD_DIR when that is set,
    as pio itself reads it (a relative one from REPO), else under .pio/build."""
    set_dir = os.environ.get("PLATFORMIO_BUILD_DIR")
    build_dir = REPO / Path(set_dir).expanduser() if set_dir else REPO / ".pio" / "build"
    return build_dir / "megaatmega2560" / "firmware.elf"


def build_avr_firmware():
    env = dict(os.environ, PLATFORMIO_CORE_DIR=str(REPO / ".pio-core"),
               PLATFORMIO_DISABLE_UPGRADE_CHECK="true")
    subprocess.run([str(REPO / ".venv" / "bin" / "pio"), "run", "-s", "-e", "megaatmega2560"],
                   cwd=REPO, env=env, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["make", "-s", "build/bin/avr_harness"], cwd=REPO, check=True)


def run_timestamped(seconds: float) -> list[tuple[int, int]]:
    out = subprocess.run([str(HARNESS), "--timestamps", "--seconds", str(seconds), str(firmware_elf())],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 4, f"harness ended early (rc {out.returncode}): {out.stderr}"
    pairs = []
    for line in out.stdout.splitlines():
        t_us, byte = line.split()
        pairs.append((int(t_us), int(byte, 16)))
    return pairs


@pytest.fixture(scope="module")
def heartbeats():
    build_avr_firmware()
    mav = dialect().MAVLink(None)
    found = []
    for t_us, byte in run_timestamped(4.5):
        msg = mav.parse_char(bytes([byte]))
        if msg is not None and msg.get_type() == "HEARTBEAT":
            found.append((t_us, msg))
    return found


def test_avr_firmware_sends_heartbeats_on_uart0(heartbeats):
    assert len(heartbeats) >= 3, f"only {len(heartbeats)} heartbeats in 4.5 simulated s"
    d = dialect()
    for _, msg in heartbeats:
        assert msg.type == d.MAV_TYPE_GROUND_ROVER
        assert msg.get_srcSystem() == 1


def test_avr_heartbeats_are_one_second_apart_in_simulated_time(heartbeats):
    # The first heartbeat leaves the UART queue behind the boot STATUSTEXT messages, so the
    # 1 Hz rhythm is measured from the second one on (4.5 s gives 3 gaps).
    times = [t for t, _ in heartbeats][1:]
    assert len(times) >= 4, f"only {len(times)} steady-state heartbeats"
    gaps_s = [(b - a) / 1e6 for a, b in zip(times, times[1:])]
    assert gaps_s, "need at least two heartbeats"
    for gap in gaps_s:
        assert abs(gap - 1.0) <= 0.01, f"heartbeat gap {gap:.4f} s outside 1.0 s +- 1 %"
