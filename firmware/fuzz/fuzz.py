#!/usr/bin/env python3
"""Build and run the firmware link fuzzer (libFuzzer), its seed corpus and its replay driver.

    python firmware/fuzz/fuzz.py run [--seconds 60] [--mode all|both|crc|raw|signed] [--workers 1]
    python firmware/fuzz/fuzz.py build        # clang + libFuzzer targets (build/fuzz/fuzz_link_{raw,crc,signed})
    python firmware/fuzz/fuzz.py replay-build # gcc + ASan/UBSan replay driver (build/fuzz/fuzz_replay)
    python firmware/fuzz/fuzz.py corpus       # seed corpus (build/fuzz/corpus)
    python firmware/fuzz/fuzz.py coverage     # gcov line coverage of link.c, main.c... per mode

The target (fuzz_link.c) is the whole firmware built against the simulated HAL, as in the
native SIL; ``run`` ends with a summary in plain words and exits non-zero when libFuzzer found
a crash, a hang (an input running longer than --timeout seconds), a memory blow-up or a
sanitizer report. Artefacts (the inputs that failed) are kept in build/fuzz/artifacts/.
Run it with the project's venv (.venv/bin/python): the corpus needs pymavlink and agnav_host.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO / "host"))

from agnav_host.protocol import _generator, new_codec  # noqa: E402
from agnav_host.sil import build as sil_build  # noqa: E402

OUT = REPO / "build" / "fuzz"
CORPUS = OUT / "corpus"
ARTIFACTS = OUT / "artifacts"
DICT = HERE / "mavlink.dict"
REGRESSIONS = HERE / "regressions"
MODES = {"raw": 0, "crc": 1, "signed": 2}
# run --mode all / both: the share of the time each mode gets
SHARES = {"all": {"crc": 0.6, "raw": 0.2, "signed": 0.2}, "both": {"crc": 0.75, "raw": 0.25}}
REPLAY_FLAGS = {"raw": [], "crc": ["--fix-crc"], "signed": ["--sign"]}

# -std=c11, not the SIL's gnu11: glibc then declares no BSD extras (finite, ...) that a firmware
# static helper could clash with under clang; the firmware itself needs no GNU extension.
COMMON = ["-g", "-O1", "-std=c11", "-DAGNAV_NO_MAIN", "-DAGNAV_TARGET_NATIVE",
          "-Wno-address-of-packed-member", "-fno-omit-frame-pointer"]
FUZZ_SAN = ["-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all"]
# gcc leaves float-cast-overflow out of -fsanitize=undefined (clang has it): name it.
REPLAY_SAN = ["-fsanitize=address,undefined,float-cast-overflow", "-fno-sanitize-recover=all"]


def _includes() -> list[str]:
    mods = sorted(p for p in (REPO / "firmware" / "lib").iterdir() if p.is_dir())
    return [f"-I{d}" for d in mods] + [f"-I{sil_build.MAVLINK_C}", f"-I{sil_build.SIL_DIR}", f"-I{HERE}"]


def _firmware_sources() -> list[str]:
    return [str(s) for s in sil_build.sources()]  # main.c, every lib module, hal/sim, sil_api.c


def _stale(target: Path, extra: list[Path]) -> bool:
    if not target.exists():
        return True
    inputs = [Path(s) for s in _firmware_sources()] + extra
    inputs += list((REPO / "firmware" / "lib").rglob("*.h")) + list(HERE.glob("*.[ch]"))
    inputs.append(REPO / "protocol" / "agnav.xml")
    t = target.stat().st_mtime
    return any(p.exists() and p.stat().st_mtime > t for p in inputs)


def _compile(cmd: list[str], target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + f".tmp{os.getpid()}")
    full = [*cmd, "-o", str(tmp)]
    r = subprocess.run(full, cwd=REPO, capture_output=True, text=True)
    if r.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise SystemExit(f"fuzz: build failed:\n{shlex.join(full)}\n{r.stderr}")
    os.replace(tmp, target)


def generate_headers() -> None:
    _generator().generate("c", REPO / "build" / "mavlink")


# Coverage feedback (and its cost) only where link bytes lead: the parser (MAVLink's helpers in
# mavlink_lib, link), the handlers and what they change (main.c's wiring, the calibration handler, the
# control task, telemetry, the wheels and the storage records among them). The scheduler, sensor front
# ends, simulated HAL and SIL glue run every loop pass and would dominate the run time if instrumented;
# they still get ASan and UBSan.
FEEDBACK_MODULES = {"mavlink_lib", "link", "params", "calib", "crc", "behaviour", "drive", "calib_service", "control",
                    "telemetry", "wheels", "storage_records"}


def _feedback(src: Path) -> bool:
    if src.name == "main.c":
        return True
    return src.parent.name in FEEDBACK_MODULES


def build_fuzzers(force: bool = False) -> dict[str, Path]:
    """clang + libFuzzer + ASan + UBSan, one binary per mode (objects shared in build/fuzz/obj)."""
    generate_headers()
    cc = shlex.split(os.environ.get("FUZZ_CC", "clang"))
    objdir = OUT / "obj"
    objdir.mkdir(parents=True, exist_ok=True)
    out = {}
    for mode, fix in MODES.items():
        target = OUT / f"fuzz_link_{mode}"
        if not (force or _stale(target, [])):
            out[mode] = target
            continue
        objs = []
        units = [(Path(s), []) for s in _firmware_sources()] + [(HERE / "fuzz_link.c", [f"-DFUZZ_FIX_CRC={fix}"])]
        for src, defs in units:
            stem = src.parent.name + "_" + src.stem + (f"_{mode}" if defs else "")
            obj = objdir / f"{stem}.o"
            if defs or force or not obj.exists() or _stale(obj, []):
                san = FUZZ_SAN if _feedback(src) else ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
                _compile([*cc, *COMMON, *san, *defs, *_includes(), "-c", str(src)], obj)
            objs.append(str(obj))
        _compile([*cc, *FUZZ_SAN, *objs], target)
        out[mode] = target
    return out


def build_replay(force: bool = False, coverage: bool = False) -> Path:
    """gcc + ASan + UBSan replay driver (no libFuzzer); --coverage adds gcov instrumentation."""
    generate_headers()
    cc = shlex.split(os.environ.get("CC", "gcc"))
    # gcc writes the .gcno/.gcda files next to the binary: the coverage one gets a folder of its own
    target = OUT / "cov-obj" / "fuzz_replay_cov" if coverage else OUT / "fuzz_replay"
    if force or _stale(target, []):
        extra = ["--coverage", "-O0"] if coverage else [*REPLAY_SAN]
        if coverage:
            target.parent.mkdir(parents=True, exist_ok=True)
            for f in target.parent.glob("*.gc*"):
                f.unlink()
            cmd = [*cc, *COMMON, *extra, *_includes(), *_firmware_sources(),
                   str(HERE / "fuzz_link.c"), str(HERE / "replay_main.c"), "-o", str(target)]
            r = subprocess.run(cmd, cwd=target.parent, capture_output=True, text=True)
            if r.returncode != 0:
                raise SystemExit(f"fuzz: coverage build failed:\n{r.stderr}")
        else:
            _compile([*cc, *COMMON, *extra, *_includes(), *_firmware_sources(),
                      str(HERE / "fuzz_link.c"), str(HERE / "replay_main.c")], target)
    return target


# ---- seed corpus --------------------------------------------------------------------------------
def _handled_frames() -> dict[str, bytes]:
    """One or more frames of every message id the firmware handles, as a ground station sends them."""
    mav = new_codec(255, 190)
    d = sys.modules["agnav_mavlink_dialect"]
    msgs = {
        "heartbeat": mav.heartbeat_encode(6, 8, 0, 0, 4),
        "drive_setpoint": mav.agnav_drive_setpoint_encode(1, 1, 1200, 500, 0, 0, 0, 3),
        "drive_setpoint_raw": mav.agnav_drive_setpoint_encode(1, 1, 0, -100, 1400, 1600, 1, 4),
        "rc_override": mav.rc_channels_override_encode(1, 1, 1800, 0, 1300, 0, 0, 0, 0, 0),
        "rc_release": mav.rc_channels_override_encode(1, 1, 0, 0, 65535, 0, 0, 0, 0, 0),
        "manual_control": mav.manual_control_encode(1, 600, 0, 500, -300, 0),
        "goal": mav.set_position_target_local_ned_encode(0, 1, 1, 1, 0x0FF8, 2.5, -1.0, 0, 0, 0, 0, 0, 0, 0, 0, 0),
        "cmd_estop": mav.command_long_encode(1, 1, d.MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0),
        "cmd_estop_release": mav.command_long_encode(1, 1, d.MAV_CMD_AGNAV_ESTOP, 0, 0, 0, 0, 0, 0, 0, 0),
        "cmd_arm": mav.command_long_encode(1, 1, d.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0),
        "cmd_disarm": mav.command_long_encode(1, 1, d.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0),
        "cmd_behaviours": mav.command_long_encode(1, 1, d.MAV_CMD_AGNAV_SET_BEHAVIOURS, 0, 1, 1, 1, 0, 0, 0, 0),
        "cmd_storage_write": mav.command_long_encode(1, 1, d.MAV_CMD_PREFLIGHT_STORAGE, 0, 1, 0, 0, 0, 0, 0, 0),
        "cmd_storage_read": mav.command_long_encode(1, 1, d.MAV_CMD_PREFLIGHT_STORAGE, 0, 0, 0, 0, 0, 0, 0, 0),
        "cmd_unknown": mav.command_long_encode(1, 1, 31000, 0, 0, 0, 0, 0, 0, 0, 0),
        "param_list": mav.param_request_list_encode(1, 1),
        "param_read_index": mav.param_request_read_encode(1, 1, b"", 3),
        "param_read_name": mav.param_request_read_encode(1, 1, b"MAX_SPEED_MM_S", -1),
        "param_set": mav.param_set_encode(1, 1, b"MAX_SPEED_MM_S", 900.0, 6),
        "param_set_range": mav.param_set_encode(1, 1, b"ENC_COUNT", 9.0, 6),
        "param_set_unknown": mav.param_set_encode(1, 1, b"NO_SUCH_PARAM", 1.0, 6),
        "calib_table": mav.agnav_calib_table_encode(
            1, 1, 0, 5, [1100, 1300, 1500, 1700, 1900] + [0] * 11, [2500, 1200, 0, -1200, -2500] + [0] * 11,
            1500, 1500, 1500),
        "calib_read": mav.agnav_calib_request_encode(1, 1, 0, 0),
        "calib_save": mav.agnav_calib_request_encode(1, 1, 1, 1),
        "calib_defaults": mav.agnav_calib_request_encode(1, 1, 2, 2),
        "statustext": mav.statustext_encode(6, b"hello robot"),
        "setup_signing": mav.setup_signing_encode(1, 1, bytes(range(32)), 1000),
        "setup_signing_clear": mav.setup_signing_encode(1, 1, bytes(32), 0),
    }
    return {name: m.pack(mav) for name, m in msgs.items()}


def _v1_frame(mav, msg) -> bytes:
    """The same message as a MAVLink 1 frame (id < 256 only)."""
    mav.WIRE_PROTOCOL_VERSION = "1.0"
    try:
        return msg.pack(mav, force_mavlink1=True)
    finally:
        mav.WIRE_PROTOCOL_VERSION = "2.0"


def write_corpus(dst: Path = CORPUS) -> int:
    """Seed corpus: the protocol vectors, one file per handled message, a few sequences."""
    dst.mkdir(parents=True, exist_ok=True)
    seeds: dict[str, bytes] = {}
    vectors = json.loads((REPO / "protocol" / "vectors" / "agnav_vectors.json").read_text(encoding="utf-8"))
    for v in vectors:
        seeds[f"vector_{v['seq']:02d}_{v['name'].lower()}"] = bytes.fromhex(v["frame_hex"])
    seeds["vectors_all"] = b"".join(bytes.fromhex(v["frame_hex"]) for v in vectors)
    frames = _handled_frames()
    for name, frame in frames.items():
        seeds[f"msg_{name}"] = frame
    mav = new_codec(255, 190)
    seeds["v1_heartbeat"] = _v1_frame(mav, mav.heartbeat_encode(6, 8, 0, 0, 4))
    seeds["v1_param_set"] = _v1_frame(mav, mav.param_set_encode(1, 1, b"MAX_SPEED_MM_S", 900.0, 6))
    seeds["seq_drive"] = frames["heartbeat"] + frames["cmd_arm"] + frames["drive_setpoint"] * 3
    seeds["seq_manual"] = frames["rc_override"] + frames["manual_control"] + frames["rc_release"]
    seeds["seq_calib"] = frames["calib_table"] + frames["calib_read"] + frames["calib_save"] + frames["calib_defaults"]
    seeds["seq_params"] = frames["param_list"] + frames["param_set"] + frames["cmd_storage_write"]
    seeds["garbage_then_frame"] = bytes(range(0, 256, 7)) + frames["heartbeat"]
    for name, data in seeds.items():
        (dst / name).write_bytes(data)
    return len(seeds)


# ---- running --------------------------------------------------------------------------------------
_STAT = re.compile(r"^stat::(\w+):\s+(\d+)", re.M)
_FINDING = re.compile(r"==\d+==\s*ERROR: (libFuzzer|AddressSanitizer|UndefinedBehaviorSanitizer|LeakSanitizer)"
                      r"|runtime error:|ERROR: libFuzzer: (timeout|out-of-memory|deadly signal)")
_COV = re.compile(r"#(\d+)\s+(?:DONE|INITED|NEW|REDUCE|pulse)\s+cov: (\d+) ft: (\d+) corp: (\d+)/")


def _count_files(d: Path) -> int:
    return sum(1 for p in d.iterdir() if p.is_file()) if d.is_dir() else 0


def run_one(binary: Path, mode: str, seconds: int, workers: int, timeout_s: int, log: Path,
            max_len: int = 512) -> dict:
    corpus = OUT / f"corpus-{mode}"  # the growing corpus of this mode; seeds come from CORPUS
    corpus.mkdir(parents=True, exist_ok=True)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    before = set(p.name for p in ARTIFACTS.iterdir())
    corpus_before = _count_files(corpus)
    args = [str(binary), str(corpus), str(CORPUS), f"-max_total_time={seconds}", f"-timeout={timeout_s}",
            "-rss_limit_mb=2048", f"-max_len={max_len}", f"-dict={DICT}", "-print_final_stats=1",
            f"-artifact_prefix={ARTIFACTS}/{mode}-"]
    if workers > 1:
        args += [f"-workers={workers}", f"-jobs={workers}"]  # job logs: build/fuzz/fuzz-<n>.log
    t0 = time.monotonic()
    with log.open("w") as f:
        f.write("$ " + shlex.join(args) + "\n")
        f.flush()
        r = subprocess.run(args, cwd=OUT, stdout=f, stderr=subprocess.STDOUT)
    wall = time.monotonic() - t0
    text = log.read_text(errors="replace")
    for extra in sorted(OUT.glob("fuzz-*.log")) if workers > 1 else []:
        text += extra.read_text(errors="replace")
    stats = {k: int(v) for k, v in _STAT.findall(text)}
    covs = _COV.findall(text)
    new_art = sorted(p.name for p in ARTIFACTS.iterdir() if p.name not in before)
    findings = _FINDING.findall(text)
    return {
        "mode": mode, "rc": r.returncode, "wall_s": wall,
        "execs": stats.get("number_of_executed_units", int(covs[-1][0]) if covs else 0),
        "exec_s": stats.get("average_exec_per_sec", 0),
        "cov": int(covs[-1][1]) if covs else 0, "ft": int(covs[-1][2]) if covs else 0,
        "corp": int(covs[-1][3]) if covs else 0,
        "corpus": _count_files(corpus), "corpus_before": corpus_before,
        "artifacts": new_art, "findings": len(findings), "log": log,
    }


def summary(res: dict) -> str:
    problems = res["findings"] + len(res["artifacts"]) + (1 if res["rc"] != 0 else 0)
    lines = [
        f"fuzz [{res['mode']}]: {res['execs']} executions in {res['wall_s']:.0f} s ({res['exec_s']} exec/s)",
        f"fuzz [{res['mode']}]: coverage {res['cov']} edges, {res['ft']} features; corpus {res['corp']} inputs in"
        f" use, {res['corpus']} files in build/fuzz/corpus-{res['mode']} (was {res['corpus_before']})",
    ]
    if problems == 0:
        lines.append(f"fuzz [{res['mode']}]: 0 crashes, 0 hangs, 0 sanitizer reports")
    else:
        lines.append(f"fuzz [{res['mode']}]: FOUND PROBLEMS: libFuzzer exit {res['rc']}, {res['findings']} reports,"
                     f" artefacts: {', '.join(res['artifacts']) or 'none'} (log {res['log']})")
    return "\n".join(lines)


def cmd_run(a: argparse.Namespace) -> int:
    bins = build_fuzzers()
    n = write_corpus()
    # all: most of the time to the deep (CRC-fixing) mode, the rest to raw framing and to signing on
    share = SHARES.get(a.mode, {a.mode: 1.0})
    modes = list(share)
    print(f"fuzz: {n} seed inputs in {CORPUS.relative_to(REPO)}, {a.seconds} s, workers {a.workers}", flush=True)
    results = []
    for mode in modes:
        secs = max(1, int(round(a.seconds * share[mode])))
        log = OUT / f"run-{mode}.log"
        results.append(run_one(bins[mode], mode, secs, a.workers, a.timeout, log, a.max_len))
        print(summary(results[-1]), flush=True)
    total = sum(r["execs"] for r in results)
    bad = sum(r["findings"] + len(r["artifacts"]) + (r["rc"] != 0) for r in results)
    print(f"fuzz: total {total} executions, {'0 problems' if bad == 0 else f'{bad} PROBLEMS'}"
          f" (artefacts in {ARTIFACTS.relative_to(REPO)})")
    return 0 if bad == 0 else 1


COVERAGE_FILES = ["link.c", "link_calib.c", "main.c", "calib_service.c", "control.c", "telemetry.c", "wheels.c",
                  "storage_records.c", "params.c", "calib.c", "signing.c"]


def cmd_coverage(a: argparse.Namespace) -> int:
    """Line coverage (gcov) of the link and handler sources reached by replaying a corpus."""
    binary = build_replay(coverage=True)
    objdir = OUT / "cov-obj"
    for mode in SHARES.get(a.mode, {a.mode: 1.0}):
        corpus = Path(a.corpus).resolve() if a.corpus else OUT / f"corpus-{mode}"
        for f in objdir.glob("*.gcda"):
            f.unlink()
        r = subprocess.run([str(binary), *REPLAY_FLAGS[mode], str(corpus)],
                           cwd=objdir, capture_output=True, text=True)
        if r.returncode != 0:
            print(r.stdout[-2000:], r.stderr[-2000:])
            return 1
        runs = r.stdout.strip().splitlines()[-1]
        g = subprocess.run(["gcov", "-n", *sorted(str(p) for p in objdir.glob("*.gcda"))], cwd=objdir,
                           capture_output=True, text=True)
        found = dict(re.findall(r"File '.*/([^/']+)'\nLines executed:([^\n]+)", g.stdout))
        cov = ", ".join(f"{name} {found.get(name, 'n/a')}" for name in COVERAGE_FILES)
        print(f"coverage [{mode}] ({runs}): {cov}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--seconds", type=int, default=60)
    r.add_argument("--mode", choices=["all", "both", "crc", "raw", "signed"], default="all")
    r.add_argument("--workers", type=int, default=1)
    r.add_argument("--timeout", type=int, default=2, help="seconds per input before it counts as a hang")
    # 512 bytes hold several whole frames (the longest is 280); longer inputs cost run time per input
    r.add_argument("--max-len", type=int, default=512, help="longest input libFuzzer generates (bytes)")
    sub.add_parser("build")
    rb = sub.add_parser("replay-build")
    rb.add_argument("--coverage", action="store_true")
    sub.add_parser("corpus")
    c = sub.add_parser("coverage")
    c.add_argument("--mode", choices=["all", "both", "crc", "raw", "signed"], default="all")
    c.add_argument("--corpus", help="folder of inputs (default build/fuzz/corpus-<mode>)")
    a = ap.parse_args(argv)
    if a.cmd == "run":
        return cmd_run(a)
    if a.cmd == "coverage":
        return cmd_coverage(a)
    if a.cmd == "build":
        for mode, p in build_fuzzers(force=True).items():
            print(f"{mode}: {p}")
    elif a.cmd == "replay-build":
        print(build_replay(force=True, coverage=a.coverage))
    elif a.cmd == "corpus":
        print(f"{write_corpus()} seed inputs in {CORPUS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
