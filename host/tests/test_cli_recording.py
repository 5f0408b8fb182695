"""`agnav sim` saves a rerun recording of the run next to the summary."""
import json

import pytest

from agnav_host.cli import main


def test_sim_writes_a_rerun_recording(tmp_path):
    pytest.importorskip("rerun")
    assert main(["sim", "--out", str(tmp_path), "--duration", "3", "--quiet", "--no-plot"]) == 0
    rrd = tmp_path / "recording.rrd"
    assert rrd.is_file() and rrd.stat().st_size > 1000, "recording.rrd missing or empty"
    assert rrd.read_bytes()[:4] == b"RRF2", "not a rerun recording file"
    assert set(json.loads((tmp_path / "summary.json").read_text())) >= {"success", "time_s"}


def test_sim_no_rrd_skips_the_recording(tmp_path):
    assert main(["sim", "--out", str(tmp_path), "--duration", "1", "--quiet", "--no-plot", "--no-rrd"]) == 0
    assert not (tmp_path / "recording.rrd").exists()
