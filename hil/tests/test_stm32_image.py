"""The STM32F405 image and its upload (docs/stm32.md): what gets written to the board's flash.

Flash sectors 1-2 (0x08004000-0x0800BFFF) hold the emulated EEPROM (calibration, parameters, the
signing key): nothing the build makes or the upload writes may cover them. The upload is checked
dry, with AGNAV_OPENOCD pointed at a script that records its arguments instead of flashing; the boot
report is checked under QEMU, whose unmodelled RCC makes the firmware take the HSI fallback.
"""
import json
import os
import selectors
import subprocess
import sys
import time
from pathlib import Path

import pytest
from elftools.elf.constants import SH_FLAGS
from elftools.elf.elffile import ELFFile

from agnav_host.protocol import dialect

REPO = Path(__file__).resolve().parents[2]
PIO = REPO / ".venv" / "bin" / "pio"
EEPROM_START, EEPROM_END = 0x08004000, 0x0800C000  # sectors 1 and 2 (RM0090 3.3, Table 5)
VECTORS_START, CODE_START = 0x08000000, 0x0800C000


def _pio(build_dir: Path, *args: str, extra_env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ, PLATFORMIO_CORE_DIR=str(REPO / ".pio-core"), PLATFORMIO_BUILD_DIR=str(build_dir),
               PLATFORMIO_DISABLE_UPGRADE_CHECK="true", **(extra_env or {}))
    return subprocess.run([str(PIO), "run", "-e", "stm32f405", *args], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def build_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("pio-build")
    r = _pio(d)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return d


def _out(build_dir: Path) -> Path:
    return build_dir / "stm32f405"


def _overlaps_eeprom(start: int, size: int) -> bool:
    return size > 0 and start < EEPROM_END and start + size > EEPROM_START


def test_elf_loadable_segments_stay_out_of_the_eeprom_sectors(build_dir):
    with open(_out(build_dir) / "firmware.elf", "rb") as f:
        elf = ELFFile(f)
        loads = [(s["p_paddr"], s["p_filesz"]) for s in elf.iter_segments() if s["p_type"] == "PT_LOAD"]
        assert any(size for _, size in loads), "no loadable segment"
        bad = [f"0x{a:08x}+0x{n:x}" for a, n in loads if _overlaps_eeprom(a, n)]
        assert not bad, f"segments written into the EEPROM sectors: {bad}"
        # sections by load address too (a segment's file image is what OpenOCD writes)
        for sec in elf.iter_sections():
            if sec["sh_flags"] & SH_FLAGS.SHF_ALLOC and sec["sh_type"] != "SHT_NOBITS" and sec["sh_size"]:
                lma = next((s["p_paddr"] + sec["sh_addr"] - s["p_vaddr"] for s in elf.iter_segments()
                            if s["p_type"] == "PT_LOAD" and s.section_in_segment(sec)), sec["sh_addr"])
                assert not _overlaps_eeprom(lma, sec["sh_size"]), f"{sec.name} loads at 0x{lma:08x}"


def _region(elf_path: Path, start: int, end: int) -> bytes:
    """The bytes the ELF loads into [start, end), gaps as 0xFF (erased flash)."""
    with open(elf_path, "rb") as f:
        elf = ELFFile(f)
        top = max(s["p_paddr"] + s["p_filesz"] for s in elf.iter_segments()
                  if s["p_type"] == "PT_LOAD" and s["p_filesz"] and start <= s["p_paddr"] < end)
        img = bytearray(b"\xff" * (top - start))
        for s in elf.iter_segments():
            if s["p_type"] == "PT_LOAD" and s["p_filesz"] and start <= s["p_paddr"] < end:
                img[s["p_paddr"] - start:s["p_paddr"] - start + s["p_filesz"]] = s.data()
        return bytes(img)


def test_raw_images_hold_the_vectors_and_the_code_but_no_eeprom_span(build_dir):
    out = _out(build_dir)
    bins = sorted(p.name for p in out.glob("*.bin"))
    assert bins == ["firmware.code.bin", "firmware.vectors.bin"], f"raw images built: {bins}"
    vectors = (out / "firmware.vectors.bin").read_bytes()
    code = (out / "firmware.code.bin").read_bytes()
    assert len(vectors) <= EEPROM_START - VECTORS_START, "the vectors image reaches sector 1"
    assert vectors == _region(out / "firmware.elf", VECTORS_START, EEPROM_START)
    assert code == _region(out / "firmware.elf", CODE_START, 0x08100000)


FAKE_OPENOCD = """#!{python}
import json, sys
with open({log!r}, "a") as f:
    f.write(json.dumps(sys.argv[1:]) + "\\n")
"""


def test_upload_programs_the_elf_with_openocd_and_no_raw_image(build_dir, tmp_path):
    log = tmp_path / "openocd-args.jsonl"
    fake = tmp_path / "openocd"
    fake.write_text(FAKE_OPENOCD.format(python=sys.executable, log=str(log)))
    fake.chmod(0o755)
    r = _pio(build_dir, "-t", "upload", "-v", extra_env={"AGNAV_OPENOCD": str(fake)})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    calls = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(calls) == 1, f"openocd ran {len(calls)} times"
    args = calls[0]
    assert args[:4] == ["-f", "interface/stlink.cfg", "-f", "target/stm32f4x.cfg"], args
    assert args[4] == "-c", args
    words = args[5].split()
    assert words[0] == "program" and words[-3:] == ["verify", "reset", "exit"], args[5]
    image = " ".join(words[1:-3]).strip("{}")
    assert Path(image) == _out(build_dir) / "firmware.elf", f"uploads {image}"
    assert not any(a.endswith(".bin") or a.endswith(".hex") for a in args), "a raw image in the upload"
    assert "erase" not in args[5] and "mass_erase" not in args[5]


def test_upload_without_openocd_fails_with_the_install_command(build_dir, tmp_path):
    r = _pio(build_dir, "-t", "upload", extra_env={"AGNAV_OPENOCD": str(tmp_path / "no-such-openocd")})
    assert r.returncode != 0
    assert "apt-get install openocd" in r.stdout + r.stderr


def test_arm_firmware_reports_the_clock_fallback_at_boot(build_dir):
    """QEMU's RCC reads 0: HSERDY never comes, the firmware runs from HSI + PLL and says so once."""
    d = dialect()
    parser = d.MAVLink(None)
    proc = subprocess.Popen(
        ["qemu-system-arm", "-M", "netduinoplus2", "-display", "none", "-monitor", "none", "-serial", "stdio",
         "-kernel", str(_out(build_dir) / "firmware.elf")],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    texts: list[tuple[int, str]] = []
    heartbeats = 0
    sel = selectors.DefaultSelector()
    assert proc.stdout is not None
    sel.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + 20.0
    try:
        while time.monotonic() < deadline and heartbeats < 3:
            if not sel.select(timeout=0.2):
                continue
            chunk = os.read(proc.stdout.fileno(), 4096)
            if not chunk:
                break
            for msg in parser.parse_buffer(chunk) or []:
                if msg.get_type() == "STATUSTEXT":
                    texts.append((msg.severity, msg.text))
                elif msg.get_type() == "HEARTBEAT":
                    heartbeats += 1
    finally:
        proc.kill()
        proc.wait(timeout=5)
    assert heartbeats >= 1, "the firmware did not boot"
    fallback = [t for t in texts if t[1] == "boot: no crystal, clock from HSI (+-1 %)"]
    assert fallback == [(d.MAV_SEVERITY_WARNING, "boot: no crystal, clock from HSI (+-1 %)")], texts
