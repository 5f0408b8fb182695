"""`agnav param save FILE` / `load FILE` / `store` against the real firmware (the SIL on loopback TCP): the
.parm file MAVProxy and Mission Planner read, loaded back with every name checked first, and stored in the
firmware's EEPROM (answered IN_PROGRESS, then ACCEPTED when both slots are written)."""

from __future__ import annotations

import pytest

from agnav_host.cli import main
from agnav_host.link.parm import read_parm


@pytest.fixture(scope="module")
def sil_device():
    from agnav_host.sim import load_scenario

    from _sil_server import serve_sil

    yield serve_sil(load_scenario("corridor_obstacles"), speedup=4.0, duration_s=200.0)


def _common(dev):
    return ["--device", dev, "--no-tlog", "--wait", "10", "--timeout", "1.0"]


def test_save_edit_load_and_store_round_trip(sil_device, tmp_path, capsys):
    f = tmp_path / "robot.parm"
    assert main(["param", "save", str(f), *_common(sil_device)]) == 0, capsys.readouterr().err
    params = read_parm(f)
    assert len(params) >= 40 and params["MAX_SPEED_MM_S"] == 1000, params
    f.write_text(f.read_text().replace("MAX_SPEED_MM_S 1000", "MAX_SPEED_MM_S 640"))
    assert main(["param", "load", str(f), *_common(sil_device)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "1 of" in out and "stored in the robot's EEPROM" in out, out
    assert main(["param", "get", "MAX_SPEED_MM_S", *_common(sil_device)]) == 0
    assert "MAX_SPEED_MM_S 640" in capsys.readouterr().out


def test_load_with_an_unknown_name_sends_nothing(sil_device, tmp_path, capsys):
    f = tmp_path / "bad.parm"
    f.write_text("MAX_SPEED_MM_S 300\nNO_SUCH_PARAM 1\n")
    assert main(["param", "load", str(f), *_common(sil_device)]) == 2
    err = capsys.readouterr().err
    assert "no parameter NO_SUCH_PARAM; nothing sent" in err, err
    assert main(["param", "get", "MAX_SPEED_MM_S", *_common(sil_device)]) == 0
    assert "MAX_SPEED_MM_S 300" not in capsys.readouterr().out


def test_a_bad_parm_file_is_refused_before_connecting(tmp_path, capsys):
    f = tmp_path / "bad.parm"
    f.write_text("MAX_SPEED_MM_S fast\n")
    assert main(["param", "load", str(f), "--device", "tcp:127.0.0.1:9", "--no-tlog"]) == 2
    assert "bad.parm:1: MAX_SPEED_MM_S: value 'fast' is not a number" in capsys.readouterr().err


def test_store_answers_after_the_background_write(sil_device, capsys):
    assert main(["param", "store", *_common(sil_device)]) == 0, capsys.readouterr().err
    assert "stored in the robot's EEPROM" in capsys.readouterr().out
