"""Input files the commands read: a scan CSV with a misspelt metadata key (``rows``), a telemetry log that is
partly or mostly not MAVLink (``replay``), a host config with a bad value (``config``): each named with its line,
in one message, never a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

from agnav_host import cli
from _cli_helpers import _no_user_config, heartbeat_tlog  # noqa: F401 (the fixture is autouse)


# ---- rows: a misspelt key on a scan's metadata line ---------------------------------------------------
def _scan(path: Path, meta: str) -> Path:
    n = 271
    lines = ["# agnav-scan v1", meta, "angle_rad,range_m"]
    lines += [f"{-2.35 + 4.7 * i / (n - 1)!r},1.5" for i in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("meta, why", [
    ("# stamp_s=1.0,range_mx_m=1.0", "unknown metadata key 'range_mx_m'; did you mean range_max_m? known: pose_x_m,"),
    ("# stamp_s=1.0,operator=Anna", "unknown metadata key 'operator'; known: pose_x_m, pose_y_m, pose_yaw_rad, "
                                    "range_max_m, range_min_m, stamp_s"),
    ("# range_max=1.0", "unknown metadata key 'range_max'; did you mean range_max_m?"),
    ("# range_max_m: 1.0", "metadata is written key=value (range_max_m=...), got 'range_max_m: 1.0'"),
])
def test_rows_refuses_an_unknown_or_misspelt_metadata_key_naming_the_line(tmp_path, capsys, meta, why):
    f = _scan(tmp_path / "s.csv", meta)
    assert cli.main(["rows", "--scan", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"agnav rows: {f}:2: {why}" or err.startswith(f"agnav rows: {f}:2: {why}"), err


def test_rows_free_text_comments_and_good_metadata_still_read(tmp_path, capsys):
    from agnav_host.scanio import load_scan_csv

    assert load_scan_csv(_scan(tmp_path / "a.csv", "# operator=Anna, left row")).range_max_m == float("inf")
    assert load_scan_csv(_scan(tmp_path / "b.csv", "# stamp_s=1.0,range_max_m=1.0")).range_max_m == 1.0
    assert cli.main(["rows", "--scan", str(tmp_path / "b.csv")]) == 3  # nothing within the 1 m limit
    assert "in 0.05..1 m" in capsys.readouterr().err


# ---- replay counts the bytes it could not decode, and refuses a file that is mostly not MAVLink -------
def test_replay_says_how_much_of_the_file_was_skipped(tmp_path, capsys):
    import numpy as np

    good = heartbeat_tlog(tmp_path / "good.tlog")
    assert cli.main(["replay", str(good)]) == 0
    assert "could not be decoded" not in capsys.readouterr().out
    damaged = tmp_path / "damaged.tlog"
    raw = good.read_bytes()
    damaged.write_bytes(raw + bytes(40))  # a tail of zeros, as a log cut short by a crash can end
    assert cli.main(["replay", str(damaged)]) == 0
    assert f"40 B of {len(raw) + 40} (" in capsys.readouterr().out
    noise = tmp_path / "random.tlog"
    noise.write_bytes(np.random.default_rng(3).bytes(100_000))
    rc = cli.main(["replay", str(noise)])
    cap = capsys.readouterr()
    assert rc == 2 and "Traceback" not in cap.err
    assert "could not be decoded as MAVLink frames and were skipped" in cap.out
    assert cap.err.strip().startswith(f"agnav replay: {noise}: ") and "is not MAVLink frames: not a .tlog" in cap.err



# ---- config: a bad value names its line --------------------------------------------------------------
@pytest.mark.parametrize("text, line, what", [
    ('# host config\n[link]\ndevice = "tcp:127.0.0.1:5760"\n\nheartbeat_hz = nan\n', 5, "[link] heartbeat_hz: must be a finite"),
    ('[link]\ndevice = "tcp:x:1"\n[run]\nmax_speed_m_s = 0.5\nbogus = 3\n', 5, "[run] unknown key 'bogus'"),
    ('[link]\n[weird]\na = 1\n', 2, "unknown section [weird]"),
    ('[run]\nmax_speed_m_s = "fast"\n', 2, "[run] max_speed_m_s: must be a number"),
])
def test_config_value_errors_name_the_line(tmp_path, capsys, text, line, what):
    cfg = tmp_path / "agnav.toml"
    cfg.write_text(text)
    assert cli.main(["config", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}:{line}: {what}" in err and "Traceback" not in err
