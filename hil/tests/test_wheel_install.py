"""The host package as a user installs it: a wheel built from the repository, installed into a fresh venv, run
from a folder outside the checkout. The MAVLink bindings and the SIL libraries are built on first use into the
cache folder ($AGNAV_CACHE_DIR) from the sources the wheel carries.

The fresh venv gets agnav_host from the wheel only; its third-party packages (numpy, pymavlink, ...) come from the
project's .venv through a .pth line, which puts that site-packages on sys.path without running its .pth files
(so the editable install of the checkout stays out)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=kw.pop("timeout", 240), **kw)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    r = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(out), str(REPO)])
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = out.glob("agnav_host-*.whl")
    return whl


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> dict:
    """A fresh venv with the wheel installed: its python, agnav script and an environment for it."""
    root = tmp_path_factory.mktemp("installed")
    venv = root / "venv"
    r = _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    assert r.returncode == 0, r.stderr
    py = venv / "bin" / "python"
    r = _run([sys.executable, "-m", "pip", "--python", str(py), "install", "--quiet", "--no-deps", "--no-index",
              str(wheel)])
    assert r.returncode == 0, r.stdout + r.stderr
    purelib = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    (purelib / "agnav_third_party.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    home = root / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "AGNAV_MAVLINK_BUILD_DIR", "AGNAV_CACHE_DIR", "CC")}
    env.update(HOME=str(home), AGNAV_CACHE_DIR=str(root / "cache"), PYTHONUNBUFFERED="1")
    return {"root": root, "py": py, "agnav": venv / "bin" / "agnav", "env": env, "cache": root / "cache"}


def test_the_wheel_carries_the_package_and_the_sources_it_builds_but_no_tests(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {"agnav_host", "agnav_host-0.1.0.dist-info"}
    for src in ("protocol/agnav.xml", "protocol/generate.py", "firmware/src/main.c", "firmware/lib/hal/sim/hal_sim.c",
                "firmware/lib/signing/agnav_sha256.h", "hil/sil/sil_api.c", "hil/sil/sil_api.h",
                "hil/simavr/avr_sil.c"):
        assert f"agnav_host/_data/{src}" in names, src
        assert (REPO / src).read_bytes() == zipfile.ZipFile(wheel).read(f"agnav_host/_data/{src}"), src
    assert "agnav_host/sil/world_kernels.c" in names
    assert "agnav_host/sim/scenarios/corridor_obstacles.toml" in names


def test_the_installed_package_runs_sim_sil_and_replay_outside_the_checkout(installed):
    py, agnav, env, cwd, cache = installed["py"], installed["agnav"], installed["env"], installed["root"], installed["cache"]
    where = _run([str(py), "-c", "import agnav_host, agnav_host._paths as p; print(agnav_host.__file__); "
                  "print(p.CHECKOUT_ROOT)"], cwd=cwd, env=env)
    assert where.returncode == 0, where.stderr
    module_file, checkout = where.stdout.split()
    assert Path(module_file).is_relative_to(py.parent.parent) and checkout == "None"

    # agnav sim through the native SIL: the bindings and the libraries are built into the cache on first use
    r = _run([str(agnav), "sim", "--firmware", "sil", "--duration", "3", "--out", "sim", "--no-plot", "--no-rrd",
              "--quiet"], cwd=cwd, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    assert json.loads((cwd / "sim" / "summary.json").read_text())
    assert (cwd / "sim" / "link.tlog").stat().st_size > 1000
    (sil_lib,) = cache.glob("sil-*/libagnav_sil.so")
    assert list(cache.glob("mavlink-*/python/agnav.py")) and list(cache.glob("mavlink-*/c/agnav_mavlink.h"))
    built_at = sil_lib.stat().st_mtime_ns

    # agnav sil serving the firmware on loopback TCP, with `agnav param` as its client
    sil = subprocess.Popen([str(agnav), "sil", "--tcp", "tcp:127.0.0.1:0", "--tlog", "sil.tlog", "--speedup", "2"],
                           cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        while "MAVLink on tcp:" not in line:
            line = sil.stderr.readline()
            assert line, f"agnav sil ended before serving: {sil.stdout.read()}"
        endpoint = line.split("MAVLink on ")[1].split()[0]
        client = _run([str(agnav), "param", "get", "LINK_TIMEOUT_MS", "--device", endpoint, "--no-tlog"],
                      cwd=cwd, env=env, timeout=60)
        assert client.returncode == 0, client.stdout + client.stderr
        assert client.stdout.strip().splitlines()[-1].startswith("LINK_TIMEOUT_MS ")
    finally:
        sil.send_signal(signal.SIGTERM)
        out, err = sil.communicate(timeout=30)
    assert sil.returncode == 0 and "stopped at t = " in out, out + err
    assert sil_lib.stat().st_mtime_ns == built_at  # the cached library is reused, not rebuilt

    # agnav replay on the logs both runs wrote
    for log in ("sim/link.tlog", "sil.tlog"):
        r = _run([str(agnav), "replay", log], cwd=cwd, env=env)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "received" in r.stdout and "AGNAV_ODOMETRY" in r.stdout, r.stdout


def test_a_changed_source_moves_the_installed_library_to_a_new_cache_folder(installed):
    py, env = installed["py"], installed["env"]
    show = [str(py), "-c", "from agnav_host.sil.build import library_path; print(library_path())"]
    before = _run(show, env=env).stdout.strip()
    src = Path(_run([str(py), "-c", "import agnav_host._paths as p; print(p.SOURCE_ROOT)"], env=env).stdout.strip())
    api = src / "hil" / "sil" / "sil_api.c"
    text = api.read_text()
    try:
        api.write_text(text + "\n/* a local change */\n")
        after = _run(show, env=env).stdout.strip()
    finally:
        api.write_text(text)
    assert before.startswith(str(installed["cache"])) and after.startswith(str(installed["cache"]))
    assert Path(before).parent != Path(after).parent and Path(before).name == Path(after).name
    assert _run(show, env=env).stdout.strip() == before


def test_a_missing_compiler_is_named_with_its_debian_package_on_first_use(installed):
    env = dict(installed["env"], CC="agnav-no-such-cc", AGNAV_CACHE_DIR=str(installed["root"] / "cache-no-cc"))
    r = _run([str(installed["agnav"]), "sil", "--tcp", "tcp:127.0.0.1:0", "--duration", "1"], cwd=installed["root"],
             env=env)
    assert r.returncode == 1
    assert "'agnav-no-such-cc' is not installed" in r.stderr and "apt-get install gcc" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    r = _run([str(installed["agnav"]), "sim", "corridor_obstacles", "--firmware", "sil", "--duration", "1",
              "--out", str(installed["root"] / "no-cc")], cwd=installed["root"], env=env)
    assert r.returncode == 1 and "apt-get install gcc" in r.stderr and "Traceback" not in r.stderr, r.stderr
