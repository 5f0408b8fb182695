"""The ARM (STM32F405) build boots under QEMU netduinoplus2, sends heartbeats on USART1 and
answers a command: the same firmware wiring as the AVR, on the second target."""
import os
import selectors
import subprocess
import time
from pathlib import Path
from typing import Callable

import pytest

from agnav_host.protocol import dialect

REPO = Path(__file__).resolve().parents[2]


def firmware_elf() -> Path:
    """The ELF `pio run -e stm32f405` (started in REPO) writes: under $PLATFORMIO_BUILD_DIR when that is set,
    as pio itself reads it (a relative one from REPO), else under .pio/build."""
    set_dir = os.environ.get("PLATFORMIO_BUILD_DIR")
    build_dir = REPO / Path(set_dir).expanduser() if set_dir else REPO / ".pio" / "build"
    return build_dir / "stm32f405" / "firmware.elf"


@pytest.fixture(scope="module")
def arm_firmware() -> Path:
    env = dict(os.environ, PLATFORMIO_CORE_DIR=str(REPO / ".pio-core"), PLATFORMIO_DISABLE_UPGRADE_CHECK="true")
    subprocess.run([str(REPO / ".venv" / "bin" / "pio"), "run", "-s", "-e", "stm32f405"], cwd=REPO, env=env,
                   check=True, stdout=subprocess.DEVNULL)
    return firmware_elf()


class _Session:
    """The ARM firmware under QEMU on USART1 (stdio): the host's codec, what the robot sent so far."""

    def __init__(self, elf: Path) -> None:
        self.d = dialect()
        self.host = self.d.MAVLink(None, srcSystem=255, srcComponent=190)
        self.parser = self.d.MAVLink(None)
        self.proc = subprocess.Popen(
            ["qemu-system-arm", "-M", "netduinoplus2", "-display", "none", "-monitor", "none", "-serial", "stdio",
             "-kernel", str(elf)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)

    def send(self, data: bytes) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(data)
        self.proc.stdin.flush()

    def run(self, on_message: Callable[[object], None], done: Callable[[], bool], seconds: float = 20.0) -> None:
        """Hand every message the robot sends to on_message until done() or the time is up; then stop QEMU."""
        deadline = time.monotonic() + seconds
        sel = selectors.DefaultSelector()
        assert self.proc.stdout is not None
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        try:
            while time.monotonic() < deadline and not done():
                if not sel.select(timeout=0.2):
                    continue
                chunk = os.read(self.proc.stdout.fileno(), 4096)
                if not chunk:
                    break
                for msg in self.parser.parse_buffer(chunk) or []:
                    on_message(msg)
        finally:
            self.proc.kill()
            self.proc.wait(timeout=5)


def test_arm_firmware_boots_heartbeats_and_acknowledges_a_command(arm_firmware):
    s = _Session(arm_firmware)
    d = s.d
    cmd = d.MAVLink_command_long_message(1, 1, d.MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0).pack(s.host)
    seen: dict[str, list] = {}

    def on_message(msg) -> None:
        if msg.get_type() == "HEARTBEAT" and not seen.get("HEARTBEAT"):
            s.send(cmd)
        seen.setdefault(msg.get_type(), []).append(msg)

    s.run(on_message, lambda: len(seen.get("HEARTBEAT", [])) >= 2 and bool(seen.get("COMMAND_ACK")))
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
    s = _Session(arm_firmware)
    burst = b"".join(s.d.MAVLink_param_request_read_message(1, 1, b"", k).pack(s.host) for k in range(30))
    indices: list[int] = []
    sent_at: list[float] = []

    def on_message(msg) -> None:
        if msg.get_type() == "HEARTBEAT" and not sent_at:
            s.send(burst)
            sent_at.append(time.monotonic())
        elif msg.get_type() == "PARAM_VALUE":
            indices.append(msg.param_index)

    # after the 30th answer keep listening 1 s more: a repeated request would answer again
    s.run(on_message, lambda: len(indices) >= 30 and time.monotonic() > sent_at[0] + 1.0)
    assert sent_at, "no heartbeat: the firmware did not boot"
    assert indices == list(range(30)), f"{len(indices)} PARAM_VALUEs, indices begin {indices[:40]}"
    assert s.parser.total_receive_errors == 0, f"{s.parser.total_receive_errors} bad frames from the robot"


def test_arm_firmware_stores_a_parameter_and_keeps_running(arm_firmware):
    """PARAM_SET on the STM32 build goes through the flash EEPROM (lib/flash_eeprom): QEMU does not model
    the flash controller, so the store falls back to RAM - the value is echoed and read back, and the
    firmware keeps sending heartbeats afterwards (no fault from the flash path)."""
    s = _Session(arm_firmware)
    d = s.d
    msgs = (d.MAVLink_param_set_message(1, 1, b"LINK_TIMEOUT_MS", 750.0, d.MAV_PARAM_TYPE_UINT16).pack(s.host)
            + d.MAVLink_param_request_read_message(1, 1, b"LINK_TIMEOUT_MS", -1).pack(s.host))
    values: list[float] = []
    beats_after: list[int] = []
    sent: list[bool] = []

    def on_message(msg) -> None:
        t = msg.get_type()
        if t == "HEARTBEAT" and not sent:
            s.send(msgs)
            sent.append(True)
        elif t == "HEARTBEAT" and len(values) >= 2:
            beats_after.append(1)
        elif t == "PARAM_VALUE" and msg.param_id == "LINK_TIMEOUT_MS":
            values.append(msg.param_value)

    s.run(on_message, lambda: len(values) >= 2 and len(beats_after) >= 2)
    assert values[:2] == [750.0, 750.0], f"LINK_TIMEOUT_MS echoed / read back as {values}"
    assert len(beats_after) >= 2, "no heartbeat after the parameter was stored"
