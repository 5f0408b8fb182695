"""The ARM (STM32F405) build boots under QEMU netduinoplus2, sends heartbeats on USART1 and
answers a command: the same firmware wiring as the AVR, on the second target."""
import os
import selectors
import subprocess
import time
from pathlib import Path

import pytest

from agnav_host.protocol import dialect

REPO = Path(__file__).resolve().parents[2]
ELF = REPO / ".pio" / "build" / "stm32f405" / "firmware.elf"


@pytest.fixture(scope="module")
def arm_firmware() -> Path:
    env = dict(os.environ, PLATFORMIO_CORE_DIR=str(REPO / ".pio-core"), PLATFORMIO_DISABLE_UPGRADE_CHECK="true")
    subprocess.run([str(REPO / ".venv" / "bin" / "pio"), "run", "-s", "-e", "stm32f405"], cwd=REPO, env=env,
                   check=True, stdout=subprocess.DEVNULL)
    return ELF


def _boot(elf: Path) -> subprocess.Popen:
    return subprocess.Popen(
        ["qemu-system-arm", "-M", "netduinoplus2", "-display", "none", "-monitor", "none", "-serial", "stdio",
         "-kernel", str(elf)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)


def test_arm_firmware_boots_heartbeats_and_acknowledges_a_command(arm_firmware):
    d = dialect()
    host = d.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = d.MAVLink(None)
    cmd = d.MAVLink_command_long_message(1, 1, d.MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0).pack(host)
    proc = _boot(arm_firmware)
    seen: dict[str, list] = {}
    sent = False
    deadline = time.monotonic() + 20.0
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        while time.monotonic() < deadline:
            if not sel.select(timeout=0.2):
                continue
            chunk = os.read(proc.stdout.fileno(), 4096)
            if not chunk:
                break
            for msg in parser.parse_buffer(chunk) or []:
                seen.setdefault(msg.get_type(), []).append(msg)
            if not sent and seen.get("HEARTBEAT"):
                proc.stdin.write(cmd)
                proc.stdin.flush()
                sent = True
            if len(seen.get("HEARTBEAT", [])) >= 2 and seen.get("COMMAND_ACK"):
                break
    finally:
        proc.kill()
        proc.wait(timeout=5)
    assert len(seen.get("HEARTBEAT", [])) >= 2, f"heartbeats seen: {len(seen.get('HEARTBEAT', []))}"
    hb = seen["HEARTBEAT"][0]
    assert hb.type == d.MAV_TYPE_GROUND_ROVER
    acks = seen.get("COMMAND_ACK", [])
    assert acks, f"no COMMAND_ACK; messages seen: {sorted(seen)}"
    assert acks[0].command == d.MAV_CMD_AGNAV_ESTOP and acks[0].result == d.MAV_RESULT_ACCEPTED
    status = seen.get("AGNAV_BEHAVIOUR_STATUS", [])
    assert status and status[-1].failsafe_flags & d.AGNAV_FAILSAFE_ESTOP, "e-stop not reflected in the status"


def test_arm_firmware_answers_every_request_of_a_burst_once_and_in_order(arm_firmware):
    """30 PARAM_REQUEST_READs (indices 0..29) in one write, about 0.6 kB: the 256-byte receive ring wraps
    twice while the link drains it, and the answers queue behind the telemetry in the transmit ring.
    Exactly one PARAM_VALUE per index, in order (a ring that loses, repeats or reorders bytes shows here),
    and no bad frame from the robot."""
    d = dialect()
    host = d.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = d.MAVLink(None)
    burst = b"".join(d.MAVLink_param_request_read_message(1, 1, b"", k).pack(host) for k in range(30))
    proc = _boot(arm_firmware)
    indices: list[int] = []
    sent_at = None
    deadline = time.monotonic() + 20.0
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        # after the 30th answer keep listening 1 s more: a repeated request would answer again
        while time.monotonic() < deadline and not (len(indices) >= 30 and time.monotonic() > sent_at + 1.0):
            if not sel.select(timeout=0.2):
                continue
            chunk = os.read(proc.stdout.fileno(), 4096)
            if not chunk:
                break
            for msg in parser.parse_buffer(chunk) or []:
                if msg.get_type() == "HEARTBEAT" and sent_at is None:
                    proc.stdin.write(burst)
                    proc.stdin.flush()
                    sent_at = time.monotonic()
                elif msg.get_type() == "PARAM_VALUE":
                    indices.append(msg.param_index)
    finally:
        proc.kill()
        proc.wait(timeout=5)
    assert sent_at is not None, "no heartbeat: the firmware did not boot"
    assert indices == list(range(30)), f"{len(indices)} PARAM_VALUEs, indices begin {indices[:40]}"
    assert parser.total_receive_errors == 0, f"{parser.total_receive_errors} bad frames from the robot"


def test_arm_firmware_stores_a_parameter_and_keeps_running(arm_firmware):
    """PARAM_SET on the STM32 build goes through the flash EEPROM (lib/flash_eeprom): QEMU does not model
    the flash controller, so the store falls back to RAM - the value is echoed and read back, and the
    firmware keeps sending heartbeats afterwards (no fault from the flash path)."""
    d = dialect()
    host = d.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = d.MAVLink(None)
    set_msg = d.MAVLink_param_set_message(1, 1, b"LINK_TIMEOUT_MS", 750.0, d.MAV_PARAM_TYPE_UINT16).pack(host)
    read_msg = d.MAVLink_param_request_read_message(1, 1, b"LINK_TIMEOUT_MS", -1).pack(host)
    proc = _boot(arm_firmware)
    values: list[float] = []
    beats_after = 0
    sent = False
    deadline = time.monotonic() + 20.0
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        while time.monotonic() < deadline and not (len(values) >= 2 and beats_after >= 2):
            if not sel.select(timeout=0.2):
                continue
            chunk = os.read(proc.stdout.fileno(), 4096)
            if not chunk:
                break
            for msg in parser.parse_buffer(chunk) or []:
                t = msg.get_type()
                if t == "HEARTBEAT" and not sent:
                    proc.stdin.write(set_msg + read_msg)
                    proc.stdin.flush()
                    sent = True
                elif t == "HEARTBEAT" and len(values) >= 2:
                    beats_after += 1
                elif t == "PARAM_VALUE" and msg.param_id == "LINK_TIMEOUT_MS":
                    values.append(msg.param_value)
    finally:
        proc.kill()
        proc.wait(timeout=5)
    assert values[:2] == [750.0, 750.0], f"LINK_TIMEOUT_MS echoed / read back as {values}"
    assert beats_after >= 2, "no heartbeat after the parameter was stored"
