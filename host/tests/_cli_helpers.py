"""Helpers of the CLI input tests: a free TCP port, a device nobody listens on, no user config, argparse's
refusal of a command line, and a small telemetry log."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from agnav_host import cli


@pytest.fixture(autouse=True)
def _no_user_config(tmp_path, monkeypatch):
    """Keep the developer's own ~/.config/agnav out of these tests (autouse where imported)."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv("AGNAV_CONFIG", raising=False)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on (at the moment of asking)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def nowhere() -> str:
    """A device nobody listens on: a command that got as far as connecting would say "could not open"."""
    return f"tcp:127.0.0.1:{free_port()}"


def usage_error(capsys, argv: list[str]) -> str:
    """Run ``agnav argv`` expecting argparse to refuse it (exit 2); return stderr."""
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    return capsys.readouterr().err


def heartbeat_tlog(path: Path) -> Path:
    """A telemetry log of 11 robot heartbeats, 0.1 s apart."""
    from agnav_host.link.tlog import TlogWriter
    from agnav_host.protocol import dialect

    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    with TlogWriter(path) as w:
        for i in range(11):
            w.write(robot.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 4).pack(robot), 1.7e9 + 0.1 * i)
    return path
