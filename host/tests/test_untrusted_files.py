"""Readers of files a user (or an attacker) hands over never raise anything but their own error.

Property-based (hypothesis): each reader gets mutated copies of real files (characters deleted, inserted
or replaced, lines duplicated, cut anywhere, deep nesting, huge and non-finite numbers spliced in) and random
bytes. A scenario, a host config, a scan CSV, a laser log and a tlog each either load or raise the module's
error (ScenarioError, ConfigError, ScanFileError, LaserLogError, TlogError): never RecursionError,
OverflowError, a numpy warning turned error, or any other traceback. 2,500 cases per reader."""

from __future__ import annotations

import io
import math
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agnav_host.lasers.log import LaserLogError, read_laser_log
from agnav_host.link.config import ConfigError, load_config
from agnav_host.link.replay import TlogError, summarize_tlog
from agnav_host.scanio import ScanFileError, load_scan_csv, save_scan_csv
from agnav_host.sim.scenario import ScenarioError, builtin_names, builtin_text, parse_scenario
from agnav_host.types import LaserScan

CASES = settings(max_examples=2500, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)

SPLICES = ["[" * 600 + "]" * 600, "{a = " * 400 + "1" + "}" * 400, "1e308", "-1e308", "nan", "inf", "-inf",
           "1e999", "99999999999999999999999", "\x00", "\"\\u0000\"", "[[", "]]", "=", "\n[robot]\n", "0x7fffffffffff",
           "\"" + "x" * 5000 + "\"", "-0.0", "1e-320", "true", "[]", "{}"]


_NUMBER = re.compile(r"(?<![\w.])-?\d+(\.\d+)?([eE][-+]?\d+)?(?![\w.])")
HUGE = ["1e308", "-1e308", "1e-320", "nan", "inf", "-inf", "1e30", "-1e30", "0", "-1", "4294967296", "1e15"]


def _mutate(text: str, data: st.DataObject) -> str:
    if data.draw(st.booleans()):  # one number of the file made huge, tiny, negative or non-finite
        nums = list(_NUMBER.finditer(text))
        if nums:
            m = nums[data.draw(st.integers(0, len(nums) - 1))]
            text = text[:m.start()] + data.draw(st.sampled_from(HUGE)) + text[m.end():]
            if data.draw(st.booleans()):
                return text
    ops = data.draw(st.lists(st.tuples(st.sampled_from(["del", "ins", "rep", "splice", "dup", "cut"]),
                                       st.floats(0, 1), st.integers(1, 40)), min_size=1, max_size=6))
    for op, where, n in ops:
        i = int(where * len(text))
        if op == "del":
            text = text[:i] + text[i + n:]
        elif op == "ins":
            text = text[:i] + data.draw(st.text(min_size=1, max_size=n)) + text[i:]
        elif op == "rep":
            text = text[:i] + data.draw(st.text(min_size=n, max_size=n)) + text[i + n:]
        elif op == "splice":
            text = text[:i] + data.draw(st.sampled_from(SPLICES)) + text[i:]
        elif op == "dup":
            lines = text.splitlines(True)
            if lines:
                k = min(len(lines) - 1, int(where * len(lines)))
                text = "".join(lines[:k + 1] + lines[k:k + 1] * n + lines[k + 1:])
        else:
            text = text[:i]
    return text


def _mutate_bytes(raw: bytes, data: st.DataObject) -> bytes:
    ops = data.draw(st.lists(st.tuples(st.sampled_from(["del", "ins", "flip", "cut"]), st.floats(0, 1),
                                       st.integers(1, 64)), min_size=1, max_size=6))
    for op, where, n in ops:
        i = int(where * len(raw))
        if op == "del":
            raw = raw[:i] + raw[i + n:]
        elif op == "ins":
            raw = raw[:i] + data.draw(st.binary(min_size=1, max_size=n)) + raw[i:]
        elif op == "flip":
            raw = raw[:i] + bytes(b ^ 0xFF for b in raw[i:i + n]) + raw[i + n:]
        else:
            raw = raw[:i]
    return raw


@pytest.fixture(autouse=True)
def _warnings_are_errors():
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy overflow on a huge number is a failure too
        yield


_SCENARIOS = [builtin_text(n) for n in builtin_names()]


@CASES
@given(st.data())
def test_a_mutated_scenario_loads_or_is_refused_with_a_scenario_error(data):
    text = _mutate(data.draw(st.sampled_from(_SCENARIOS)), data)
    try:
        sc = parse_scenario(text, "fuzzed.toml")
    except ScenarioError:
        return
    for c in sc.world.circles:  # what loads is finite
        assert all(math.isfinite(float(v)) for v in np.ravel(c)), c


_CONFIG = """[link]
device = "tcp:127.0.0.1:5760"
[run]
duration_s = 20.0
[robot]
kind = "ackermann"
"""


@CASES
@given(st.data())
def test_a_mutated_host_config_loads_or_is_refused_with_a_config_error(data):
    text = _mutate(_CONFIG, data)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "host.toml"
        try:
            p.write_text(text, encoding="utf-8", errors="surrogatepass")
        except (UnicodeEncodeError, ValueError):
            p.write_bytes(text.encode("utf-8", "replace"))
        try:
            load_config(p)
        except ConfigError:
            pass


def _scan_csv() -> str:
    scan = LaserScan(angle_min_rad=-math.pi / 2, angle_increment_rad=math.pi / 180,
                     ranges_m=np.linspace(0.5, 4.0, 181), stamp_s=1.0)
    with tempfile.TemporaryDirectory() as d:
        return save_scan_csv(scan, Path(d) / "s.csv").read_text()


_SCAN = _scan_csv()


@CASES
@given(st.data())
def test_a_mutated_scan_file_loads_or_is_refused_with_a_scan_file_error(data):
    text = _mutate(_SCAN, data)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "s.csv"
        p.write_bytes(text.encode("utf-8", "replace"))
        try:
            scan = load_scan_csv(p)
        except ScanFileError:
            return
        assert len(scan.ranges_m) > 0


def _real_files() -> tuple[bytes, bytes]:
    """A laser log and a tlog as the project's writers write them: 40 scans with poses, and 200 MAVLink frames
    of the robot's telemetry (heartbeats, SYS_STATUS, behaviour status)."""
    from agnav_host.lasers.log import LaserLogWriter
    from agnav_host.link.tlog import TlogWriter
    from agnav_host.protocol import dialect
    from agnav_host.lasers.base import LaserMount
    from agnav_host.types import Pose2D

    D = dialect()
    with tempfile.TemporaryDirectory() as d:
        alog, tlog = Path(d) / "laser.alog", Path(d) / "link.tlog"
        template = LaserScan(-2.35, 0.0175, np.full(270, 3.0), range_max_m=25.0)
        with LaserLogWriter(alog) as w:
            w.declare(0, "tim5xx://192.168.0.1", "tim5xx", "TiM561", LaserMount(0.1), template, "device", 0.002)
            for k in range(40):
                w.write(0, LaserScan(-2.35, 0.0175, np.linspace(0.5, 4.0 + k * 0.01, 270), range_max_m=25.0,
                                     stamp_s=k * 0.066), k * 0.066, Pose2D(0.01 * k, 0.0, 0.0))
        mav = D.MAVLink(None, srcSystem=1, srcComponent=1)
        tw = TlogWriter(tlog)
        for k in range(200):
            m = (D.MAVLink_heartbeat_message(D.MAV_TYPE_GROUND_ROVER, D.MAV_AUTOPILOT_GENERIC, 0, 0, 0, 3) if k % 3 == 0
                 else D.MAVLink_sys_status_message(0, 0, 0, 500, 12000, -1, -1, 0, 0, 0, 0, 0, 0))
            tw.write(m.pack(mav))
        tw.close()
        return alog.read_bytes(), tlog.read_bytes()


@pytest.fixture(scope="module")
def real_logs():
    return _real_files()


@CASES
@given(data=st.data())
def test_a_mutated_laser_log_reads_or_is_refused_with_a_laser_log_error(real_logs, data):
    raw = _mutate_bytes(real_logs[0], data)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "l.alog"
        p.write_bytes(raw)
        try:
            for _ in read_laser_log(p):
                pass
        except LaserLogError:
            pass


@CASES
@given(data=st.data())
def test_a_mutated_tlog_summarises_or_is_refused_with_a_tlog_error(real_logs, data):
    raw = _mutate_bytes(real_logs[1], data)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "l.tlog"
        p.write_bytes(raw)
        try:
            summarize_tlog(p)
        except TlogError:
            pass


def test_a_huge_plant_radius_is_refused_naming_the_field():
    text = builtin_text("crop_rows")
    assert "plant_radius_m" in text
    huge = re.sub(r"plant_radius_m\s*=\s*[0-9.eE+-]+", "plant_radius_m = 1e308", text, count=1)
    with pytest.raises(ScenarioError, match=r"plant_radius_m.*within"):
        parse_scenario(huge)


def test_the_mutations_reach_the_readers_errors():
    """The generators are not toothless: a cut scenario and a spliced deep nesting are refused."""
    with pytest.raises(ScenarioError, match="nested"):
        parse_scenario("a = " + "[" * 600 + "]" * 600)
    with pytest.raises(ScenarioError):
        parse_scenario(_SCENARIOS[0][: len(_SCENARIOS[0]) // 3])
    assert io  # imported for readers that take streams


@pytest.mark.parametrize("section, key, value", [("link", "log_dir", "lo\\u0000gs"), ("viz", "rrd_dir", "a\\nb"),
                                                 ("link", "key_file", "k\\u0001")])
def test_a_path_with_a_control_character_is_refused_naming_the_key(tmp_path, section, key, value):
    p = tmp_path / "host.toml"
    p.write_text(f'[{section}]\n{key} = "{value}"\n')
    with pytest.raises(ConfigError, match=rf"\[{section}\] {key}: must not hold control characters"):
        load_config(p)


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.999])
def test_a_scan_file_cut_short_is_refused(tmp_path, keep):
    p = tmp_path / "s.csv"
    p.write_text(_SCAN[: int(len(_SCAN) * keep)])
    with pytest.raises(ScanFileError, match="cut short|expected 2 columns"):  # a line cut before its comma
        load_scan_csv(p)
