"""A full disk never ends a run and never lies: output files are whole or absent (no cut, no empty file), the
SIL's tlog says once that it stopped and the SIL goes on serving, and `agnav sim` lists only whole files."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest

from agnav_host.atomic import write_atomic
from agnav_host.sil.link import Tlog


def _enospc(*a, **k):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_write_atomic_on_a_full_disk_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    p = tmp_path / "summary.json"
    write_atomic(p, "old\n")
    monkeypatch.setattr(os, "fsync", _enospc)
    with pytest.raises(OSError):
        write_atomic(p, "new and longer\n" * 1000)
    assert p.read_text() == "old\n"
    assert [q.name for q in tmp_path.iterdir()] == ["summary.json"]
    with pytest.raises(OSError):
        write_atomic(tmp_path / "fresh.csv", "x")
    assert not (tmp_path / "fresh.csv").exists(), "no empty file"


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs Linux's /dev/full")
def test_tlog_on_a_full_disk_says_so_once_and_goes_on():
    said: list[str] = []
    t = Tlog("/dev/full", on_error=said.append)
    for k in range(5000):  # past the write buffer: the device refuses every byte
        t.write(k * 1000, b"\xfd" + bytes(40))
    t.close()
    assert len(said) == 1 and "No space left on device" in said[0] and "partial, 0 B on the disk" in said[0], said
    assert t.frames == 5000 and t.frames_dropped > 0


def test_tlog_that_never_wrote_a_byte_leaves_no_empty_file(tmp_path, monkeypatch):
    p = tmp_path / "link.tlog"
    t = Tlog(p)

    class Full:
        def write(self, b):
            _enospc()

        def close(self):
            pass
    t._f = Full()
    t.write(1, b"\xfd\x00")
    assert t.error is not None and not p.exists()


def test_sim_outputs_on_a_full_disk_list_only_whole_files(tmp_path, monkeypatch, capsys):
    from agnav_host.cli import main

    calls = {"n": 0}
    real = os.fsync

    def third_fails(fd):
        calls["n"] += 1
        if calls["n"] >= 3:
            _enospc()
        return real(fd)
    monkeypatch.setattr(os, "fsync", third_fails)
    out = tmp_path / "o"
    rc = main(["sim", "corridor_obstacles", "--duration", "2", "--no-rrd", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc != 0 and "No space left on device" in err and "Traceback" not in err, err
    files = {p.name: p.stat().st_size for p in out.iterdir()}
    assert all(n > 0 for n in files.values()), files
    assert not [n for n in files if n.endswith(".part")], files
    for name in files:  # what is there is whole
        if name.endswith(".json"):
            json.loads((out / name).read_text())
    for name in files:
        assert name in err, (name, err)  # every kept file is listed


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs Linux's /dev/full")
def test_agnav_sil_with_its_tlog_on_a_full_disk_keeps_serving_its_client():
    import socket
    import threading

    from agnav_host.sil import build_library
    from agnav_host.sil.server import ServeOptions, serve
    from agnav_host.sim.scenario import load_scenario

    build_library()
    said: list[str] = []
    box: dict[str, object] = {}
    up = threading.Event()

    def ready(addr, pty):
        box["addr"] = addr
        up.set()

    def run():
        box["result"] = serve(load_scenario("corridor_obstacles"),
                              ServeOptions(tcp=("127.0.0.1", 0), speedup=4.0, duration_s=12.0, tlog_path="/dev/full"),
                              log=said.append, ready=ready)
    th = threading.Thread(target=run, daemon=True)
    th.start()
    assert up.wait(30)
    c = socket.create_connection(box["addr"], timeout=5)
    got = 0
    c.settimeout(1.0)
    try:
        while th.is_alive():
            try:
                got += len(c.recv(65536))
            except socket.timeout:
                pass
    finally:
        c.close()
    th.join(5)
    assert "result" in box, said  # served to the end, no exception
    assert sum("No space left on device" in m for m in said) == 1, said
    assert got > 5000, got  # the client kept getting telemetry after the tlog stopped


def test_a_fresh_sil_tlog_has_no_break_in_its_time_stamps(tmp_path):
    from agnav_host.cli import main
    from agnav_host.link.replay import summarize_tlog

    out = tmp_path / "o"
    assert main(["sim", "corridor_obstacles", "--firmware", "sil", "--duration", "3", "--no-rrd", "--no-plot",
                 "--quiet", "--out", str(out)]) == 0
    s = summarize_tlog(out / "link.tlog")
    assert s.breaks == 0 and sum(s.rx_msgs.values()) > 50, s
