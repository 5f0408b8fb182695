"""Signing keys on the host: SETUP_SIGNING for the robot, and `agnav key push` against the SIL
firmware served over TCP (the robot takes an unsigned key only just after power-on; later only
one signed with the key it holds)."""

from __future__ import annotations

import pytest

from agnav_host.link.keys import CLEAR_KEY, mavlink_timestamp, new_key, setup_signing_message
from agnav_host.protocol import dialect


def test_mavlink_timestamp_counts_10us_since_2015():
    assert mavlink_timestamp(1420070400.0) == 0
    assert mavlink_timestamp(1420070401.5) == 150_000
    assert mavlink_timestamp(0.0) == 0


def test_setup_signing_message_round_trips_and_checks_the_key_length():
    d = dialect()
    key = bytes(range(32))
    msg = setup_signing_message(d, key, 7, unix_s=1420070402.0)
    mav = d.MAVLink(None, srcSystem=255, srcComponent=190)
    back = d.MAVLink(None).parse_buffer(msg.pack(mav))[0]
    assert (back.target_system, back.target_component) == (7, 1)
    assert bytes(back.secret_key) == key and back.initial_timestamp == 200_000
    assert bytes(setup_signing_message(d, CLEAR_KEY, 1).secret_key) == bytes(32)
    with pytest.raises(ValueError):
        setup_signing_message(d, b"short", 1)


@pytest.fixture()
def sil_server():
    """The SIL firmware (power-on at t = 0) served on a loopback TCP port at 4x real time."""
    from agnav_host.sim import load_scenario

    from _sil_server import serve_sil

    yield serve_sil(load_scenario("corridor_obstacles"), speedup=4.0, duration_s=80.0)  # 20 s of wall time


def test_key_push_sets_the_key_and_a_later_unsigned_push_is_refused(sil_server, tmp_path, capsys):
    from agnav_host.cli import main

    k1, _ = new_key(tmp_path / "k1.key")
    k2, _ = new_key(tmp_path / "k2.key")
    common = ["--device", sil_server, "--no-tlog", "--wait", "10", "--timeout", "1.0"]
    assert main(["key", "push", "--key-file", str(k1), *common]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "set; it refuses unsigned requests and answered one signed accordingly" in out, out
    # 10 simulated s later (2.5 s of wall time at 4x) the provisioning window is closed: an unsigned
    # change is refused, so requests signed with the new key go unanswered.
    import time

    time.sleep(3.0)
    assert main(["key", "push", "--key-file", str(k2), *common]) != 0
    # Signed with the key the robot holds, the change is taken.
    assert main(["key", "push", "--key-file", str(k2), "--old-key-file", str(k1), *common]) == 0


def test_key_push_to_a_keyless_robot_after_its_window_is_refused(sil_server, tmp_path, capsys):
    # A robot without a key answers requests signed with any key: the push must not take that for
    # success. 12 simulated s after power-on (3 s of wall time at 4x) the unsigned push is refused.
    import time

    from agnav_host.cli import main

    k1, _ = new_key(tmp_path / "k1.key")
    common = ["--device", sil_server, "--no-tlog", "--wait", "10", "--timeout", "1.0"]
    time.sleep(3.0)
    assert main(["key", "push", "--key-file", str(k1), *common]) == 1
    err = capsys.readouterr().err
    assert "did not take the key" in err and "refused SETUP_SIGNING" in err, err
    # and the robot still takes unsigned requests: nothing was set
    assert main(["param", "get", "SYSID_THISMAV", "--device", sil_server, "--no-tlog"]) == 0


def test_require_signed_without_a_key_is_refused_before_connecting(tmp_path, capsys):
    from agnav_host.cli import main

    cfg = tmp_path / "host.toml"
    cfg.write_text("[link]\nrequire_signed = true\n")
    # the device is never opened: the configuration is refused first (exit 2, no tlog left behind)
    assert main(["param", "get", "LINK_TIMEOUT_MS", "--config", str(cfg), "--device", str(tmp_path / "nowhere"),
                 "--tlog", str(tmp_path / "t.tlog")]) == 2
    assert "require_signed = true needs a signing key" in capsys.readouterr().err
    assert not (tmp_path / "t.tlog").exists()
