"""MAVProxy's habits: PATH,BAUD device strings, and .parm parameter files (MAVProxy and Mission Planner forms)."""

from __future__ import annotations

import pytest

from agnav_host.link.endpoint import parse_device
from agnav_host.link.parm import ParmError, format_parm, read_parm, write_parm


@pytest.mark.parametrize("text, address, baud", [
    ("/dev/ttyUSB0,57600", "/dev/ttyUSB0", 57600),
    ("serial:/dev/ttyACM0,115200", "/dev/ttyACM0", 115200),
    ("COM3,57600", "COM3", 57600),
    ("/dev/serial/by-id/usb-FTDI_FT232R-if00-port0,9600", "/dev/serial/by-id/usb-FTDI_FT232R-if00-port0", 9600),
])
def test_mavproxy_device_strings_give_path_and_baud(text, address, baud):
    d = parse_device(text)
    assert (d.kind, d.address, d.baud) == ("serial", address, baud)


@pytest.mark.parametrize("text", ["/dev/ttyUSB0,fast", ",57600", "/dev/ttyUSB0,", "/dev/ttyUSB0,-5"])
def test_bad_mavproxy_device_strings_are_refused(text):
    with pytest.raises(ValueError):
        parse_device(text)


def test_parm_round_trip_in_mavproxy_form(tmp_path):
    params = {"MAX_SPEED_MM_S": 700.0, "SYSID_THISMAV": 1.0, "WALL_TIE_DIR": -1.0}
    p = write_parm(params, tmp_path / "robot.parm", header="AgNav robot 1")
    text = p.read_text()
    assert text.splitlines() == ["# AgNav robot 1", "MAX_SPEED_MM_S 700", "SYSID_THISMAV 1", "WALL_TIE_DIR -1"]
    assert read_parm(p) == params
    assert not [q for q in tmp_path.iterdir() if q.name != "robot.parm"], "no temporary file left"


def test_parm_reads_mission_planner_form_and_comments(tmp_path):
    p = tmp_path / "mp.param"
    p.write_text("#NOTE: 02.12.2026 from Mission Planner\nMAX_SPEED_MM_S,650\n\nTRACK_MM,191  # measured\n")
    assert read_parm(p) == {"MAX_SPEED_MM_S": 650.0, "TRACK_MM": 191.0}


@pytest.mark.parametrize("body, line, what", [
    ("MAX_SPEED_MM_S\n", 1, "expected NAME VALUE"),
    ("A 1\nMAX_SPEED_MM_S fast\n", 2, "is not a number"),
    ("MAX_SPEED_MM_S nan\n", 1, "finite"),
    ("THIS_NAME_IS_FAR_TOO_LONG 1\n", 1, "not a parameter name"),
    ("A 1\nA 2\n", 2, "given twice"),
])
def test_bad_parm_lines_are_refused_naming_the_line(tmp_path, body, line, what):
    p = tmp_path / "bad.parm"
    p.write_text(body)
    with pytest.raises(ParmError, match=what) as e:
        read_parm(p)
    assert e.value.line == line


def test_a_binary_or_missing_parm_file_is_refused(tmp_path):
    p = tmp_path / "b.parm"
    p.write_bytes(b"A 1\n\xff\xfe\x00")
    with pytest.raises(ParmError, match="not a text file"):
        read_parm(p)
    with pytest.raises(ParmError, match="cannot read"):
        read_parm(tmp_path / "none.parm")


def test_a_failed_write_leaves_the_old_file(tmp_path, monkeypatch):
    p = write_parm({"A": 1.0}, tmp_path / "r.parm")
    import os as _os

    def full(*a, **k):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(_os, "fsync", full)
    with pytest.raises(OSError):
        write_parm({"A": 2.0}, p)
    assert read_parm(p) == {"A": 1.0}
    assert [q.name for q in tmp_path.iterdir()] == ["r.parm"]
    assert format_parm({"X": 0.5}) == "X 0.5\n"
