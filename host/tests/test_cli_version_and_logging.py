"""``agnav --version`` and the log records on stderr: ``-v`` / ``-vv`` / ``--log-level LEVEL`` before the command."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import logging
import subprocess
import sys

import pytest

import agnav_host
from agnav_host import cli
from agnav_host.link.fake import FakeRobot
from _cli_helpers import _no_user_config  # noqa: F401 (the fixture is autouse)


def test_version_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out == f"agnav {importlib.metadata.version('agnav-host')}\n"


def test_version_of_a_package_that_is_not_installed_is_its_own(monkeypatch):
    def not_installed(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", not_installed)
    assert cli.version() == agnav_host.__version__


def test_version_of_the_console_command():
    p = subprocess.run([sys.executable, "-m", "agnav_host.cli", "--version"], capture_output=True, text=True, timeout=60)
    assert (p.returncode, p.stdout.strip(), p.stderr) == (0, f"agnav {cli.version()}", "")


def _param_get(argv_head: list[str], capsys) -> str:
    with FakeRobot() as fr:
        assert cli.main([*argv_head, "param", "get", "LINK_TIMEOUT_MS", "--device", fr.device, "--no-tlog"]) == 0
    return capsys.readouterr().err


def test_without_verbosity_no_log_record_is_shown(capsys):
    err = _param_get([], capsys)
    assert "agnav_host." not in err and "DEBUG" not in err


@pytest.mark.parametrize("head", [["-vv"], ["--log-level", "debug"], ["--log-level=DEBUG"], ["-v", "--log-level", "debug"]])
def test_debug_shows_the_links_own_records(head, capsys):
    err = _param_get(head, capsys)
    assert "DEBUG agnav_host.cli: agnav param:" in err  # the command line as parsed
    assert "DEBUG agnav_host.link.endpoint: tcp:127.0.0.1:" in err  # the endpoint's events


def test_info_shows_info_records_but_not_debug_ones(capsys, monkeypatch):
    assert "DEBUG" not in _param_get(["-v"], capsys)
    config = cli.SUBCOMMANDS["config"]
    record = logging.getLogger("agnav_host.link.config")

    def config_with_a_record(ns):
        record.info("an info record")
        return config.handler(ns)

    monkeypatch.setitem(cli.SUBCOMMANDS, "config", dataclasses.replace(config, handler=config_with_a_record))
    assert cli.main(["-v", "config"]) == 0
    assert "INFO agnav_host.link.config: an info record" in capsys.readouterr().err
    assert cli.main(["config"]) == 0
    assert "an info record" not in capsys.readouterr().err


def test_an_explicit_level_wins_over_verbosity(capsys):
    err = _param_get(["-vv", "--log-level", "warning"], capsys)
    assert "DEBUG" not in err and "agnav_host." not in err


def test_the_logging_set_up_ends_with_the_command():
    lib = logging.getLogger("agnav_host")
    before = (lib.level, list(lib.handlers))
    assert cli.main(["-vv", "scenarios"]) == 0
    assert (lib.level, list(lib.handlers)) == before


def test_a_bad_log_level_is_refused_naming_the_option(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--log-level", "loud", "scenarios"])
    assert e.value.code == 2
    assert "argument --log-level: must be one of debug, info, warning, error, critical, got 'loud'" in \
        capsys.readouterr().err
