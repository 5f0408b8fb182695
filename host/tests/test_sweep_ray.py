"""A sweep on a local Ray cluster gives the rows of the local run, bit for bit."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("ray")  # the optional extra (pip install agnav[ray]); the lock file installs it

from agnav_host.cli import main  # noqa: E402
from agnav_host.sweep.tasks import same_results  # noqa: E402

ARGS = ["bench", "yards", "--yards", "3", "--first", "10", "--planners", "apf,vfh", "--quiet"]


def _rows(out):
    return sorted((json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()), key=lambda r: r["key"])


def test_a_local_ray_cluster_gives_the_rows_of_local_processes(tmp_path, capsys):
    assert main([*ARGS, "--jobs", "1", "--out", str(tmp_path / "local")]) == 0
    local_table = capsys.readouterr().out
    assert main([*ARGS, "--ray", "local", "--jobs", "2", "--out", str(tmp_path / "ray")]) == 0
    ray_table = capsys.readouterr().out
    local, ray = _rows(tmp_path / "local"), _rows(tmp_path / "ray")
    assert len(local) == len(ray) == 6
    assert [r["key"] for r in local] == [r["key"] for r in ray]
    assert all(same_results(a, b) for a, b in zip(local, ray))
    assert [ln for ln in local_table.splitlines() if ln.startswith("| ")] == \
        [ln for ln in ray_table.splitlines() if ln.startswith("| ")]
    import ray as ray_module

    assert not ray_module.is_initialized()  # the cluster of --ray local is stopped after the run


def test_ray_with_no_cluster_at_the_address_is_a_one_line_exit_2(capsys):
    import socket

    with socket.socket() as s:  # a loopback port that nothing listens on once this socket is closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["bench", "yards", "--yards", "1", "--planners", "flb", "--ray", f"127.0.0.1:{port}", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"agnav bench yards: --ray 127.0.0.1:{port}: no Ray cluster there" in err and "Traceback" not in err
    assert main(["bench", "yards", "--yards", "1", "--planners", "flb", "--ray", "nowhere", "--quiet"]) == 2
    assert "expected local, auto, HOST:PORT or ray://HOST:PORT" in capsys.readouterr().err
