"""Property tests of the host link layer (hypothesis): whatever bytes arrive - random, truncated
frames, frames with a flipped byte, garbage between frames - nothing raises out of the codec, the
endpoint's receive path or the tlog reader; bad input is counted, and a valid frame that follows
the garbage (once a maximum-length frame's worth of bytes has gone by) still decodes.

Deterministic: every @given runs under the "agnav-link" profile (derandomize=True, no example
database), so CI sees the same examples on every run.
"""

from __future__ import annotations

import json
import random
import socket
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agnav_host.link import Endpoint
from agnav_host.link.replay import summarize_tlog
from agnav_host.link.state import RobotState
from agnav_host.link.tlog import TlogWriter, read_tlog
from agnav_host.protocol import dialect, new_codec

settings.register_profile("agnav-link", derandomize=True, database=None, deadline=None, max_examples=150,
                          suppress_health_check=[HealthCheck.too_slow])
PROFILE = settings.get_profile("agnav-link")

REPO = Path(__file__).resolve().parents[2]
# The longest MAVLink 2 frame: 10 header + 255 payload + 2 CRC + 13 signature bytes. After that
# many bytes without a frame start, whatever half-frame the garbage began has been consumed.
MAX_FRAME = 280
PAD = bytes(MAX_FRAME)


def _robot_frames() -> list[bytes]:
    """Frames a robot sends (sysid 1), the protocol vectors, a MAVLink 1 frame and a signed one."""
    d = dialect()
    mav = new_codec(1, 1)
    msgs = [
        mav.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, d.MAV_AUTOPILOT_GENERIC, 0, 5, d.MAV_STATE_ACTIVE),
        mav.agnav_odometry_encode(1000, 1500, -250, 9000, 300, -45),
        mav.agnav_behaviour_status_encode(1020, 2, 5, 8, -300, 200),
        mav.agnav_sonar_ring_encode(1040, [300 + 100 * i for i in range(12)], [0] * 12, 12, 7),
        mav.agnav_encoder_status_encode(1060, [10, -20, 0, 0], [100, 100, 0, 0], [0, 1, 0, 0], 2),
        mav.agnav_calib_ack_encode(0, 0, 255, 32),
        mav.param_value_encode(b"MAX_SPEED_MM_S", 900.0, d.MAV_PARAM_TYPE_INT32, 36, 10),
        mav.command_ack_encode(d.MAV_CMD_AGNAV_ESTOP, d.MAV_RESULT_ACCEPTED, 0, 0, 255, 190),
        mav.statustext_encode(d.MAV_SEVERITY_WARNING, b"calib: defaults in use"),
        mav.named_value_int_encode(2000, b"T_link", 412),
    ]
    frames = [m.pack(mav) for m in msgs]
    vectors = json.loads((REPO / "protocol" / "vectors" / "agnav_vectors.json").read_text(encoding="utf-8"))
    frames += [bytes.fromhex(v["frame_hex"]) for v in vectors]
    v1 = new_codec(1, 1)
    v1.WIRE_PROTOCOL_VERSION = "1.0"
    frames.append(msgs[0].pack(v1, force_mavlink1=True))
    signer = new_codec(1, 1)
    signer.signing.secret_key = bytes(range(32))
    signer.signing.sign_outgoing = True
    signer.signing.link_id = 1
    frames.append(mav.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 4).pack(signer))
    return frames


FRAMES = _robot_frames()
frame_st = st.sampled_from(FRAMES)
# Garbage rich in frame starts (0xFD, 0xFE) and in bytes that look like lengths and flags.
garbage_st = st.lists(st.one_of(st.integers(0, 255), st.sampled_from([0xFD, 0xFE, 0x00, 0x01, 0xFF])),
                      max_size=400).map(bytes)


def _parse(data: bytes, codec: Any = None) -> list[Any]:
    codec = codec or new_codec(255, 190)
    return list(codec.parse_buffer(data) or [])


def _good(msgs: list[Any]) -> list[Any]:
    """Messages of the dialect. pymavlink cannot check the CRC of an id it does not know (no
    crc_extra), so a frame whose id was damaged into an unknown one comes out as UNKNOWN_<id>."""
    return [m for m in msgs if m.get_type() != "BAD_DATA" and not m.get_type().startswith("UNKNOWN_")]


# ---- the codec (what Endpoint, the SIL bridge and the tlog reader all use) --------------------------
@PROFILE
@given(st.binary(max_size=600))
def test_codec_never_raises_on_random_bytes(data: bytes) -> None:
    for m in _parse(data):
        assert isinstance(m.get_type(), str)


@PROFILE
@given(garbage_st, frame_st)
def test_codec_decodes_a_frame_after_garbage(garbage: bytes, frame: bytes) -> None:
    good = _good(_parse(garbage + PAD + frame))
    assert good, "the valid frame after the garbage was lost"
    assert bytes(good[-1].get_msgbuf()) == frame


def test_codec_truncated_frames_decode_nothing_and_complete_later() -> None:
    for frame in FRAMES:
        for cut in range(len(frame)):
            codec = new_codec(255, 190)
            assert _good(_parse(frame[:cut], codec)) == [], f"{frame.hex()} cut at {cut} decoded something"
            rest = _good(_parse(frame[cut:], codec))  # the rest arrives later: one whole frame
            assert [bytes(m.get_msgbuf()) for m in rest] == [frame], f"{frame.hex()} split at {cut}"
            # a frame cut short for good, then padding and a whole frame: the whole one decodes
            after = _good(_parse(frame[:cut] + PAD + frame))
            assert after and bytes(after[-1].get_msgbuf()) == frame, f"{frame.hex()} cut at {cut}, then whole"


@PROFILE
@given(frame_st, st.data())
def test_codec_rejects_a_frame_with_one_flipped_byte(frame: bytes, data: st.DataObject) -> None:
    i = data.draw(st.integers(0, len(frame) - 1), label="index")
    flip = data.draw(st.integers(1, 255), label="xor")
    bad = bytearray(frame)
    bad[i] ^= flip
    codec = new_codec(255, 190)
    got = _good(_parse(bytes(bad), codec))
    # The CRC-16 catches any single changed byte, so no dialect message decodes (a changed start byte,
    # length or signing flag only leaves the parser waiting for bytes that never come).
    assert got == [], f"flipped byte {i} (^{flip:#04x}) of {frame.hex()} decoded as {got}"
    assert bytes(_good(_parse(PAD + frame, codec))[-1].get_msgbuf()) == frame, "no recovery after the bad frame"


# ---- the endpoint's receive path ----------------------------------------------------------------------
class _ChunkConn:
    """Stands in for a mavutil connection: recv() hands out the prepared chunks one by one."""

    fd = None

    def __init__(self, chunks: list[bytes]) -> None:
        self.chunks = list(chunks)

    def recv(self, n: int = 4096) -> bytes:
        return self.chunks.pop(0) if self.chunks else b""

    def write(self, buf: bytes) -> int:
        return len(buf)

    def close(self) -> None:
        pass


def _stream(garbage: list[bytes], frames: list[bytes]) -> bytes:
    return b"".join(g + PAD + f for g, f in zip(garbage, frames))


@PROFILE
@given(st.lists(st.tuples(garbage_st, frame_st), min_size=1, max_size=6), st.randoms(use_true_random=False))
def test_endpoint_receive_path_survives_garbage_and_counts_it(pairs: list[tuple[bytes, bytes]],
                                                              rnd: random.Random) -> None:
    # Endpoint._service is one pass of the I/O thread: an exception there is taken as a transport
    # failure (the connection is closed and reopened), so noise on a radio must never raise.
    data = _stream([g for g, _ in pairs], [f for _, f in pairs])
    chunks, i = [], 0
    while i < len(data):
        n = rnd.randint(1, 300)
        chunks.append(data[i:i + n])
        i += n
    ep = Endpoint("tcp:127.0.0.1:9", heartbeat_hz=0)
    ep._conn = _ChunkConn(chunks)
    for _ in range(len(chunks)):
        ep._service(time.monotonic())
    assert ep.stats.rx_bytes == len(data)
    assert ep.stats.rx_msgs >= len(pairs), f"{ep.stats.rx_msgs} messages decoded from {len(pairs)} valid frames"
    assert ep.stats.rx_parse_errors > 0, "the padding between frames is noise and must be counted"
    assert sum(ep.state.msg_counts.values()) == ep.stats.rx_msgs


def test_endpoint_over_tcp_keeps_the_session_through_garbage() -> None:
    """The public API end to end: a peer sends noise between telemetry frames; the endpoint decodes
    the frames, counts the noise, and never drops the connection."""
    rnd = random.Random(20240611)
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    good = [FRAMES[0], FRAMES[1], FRAMES[2], FRAMES[0]]
    noise = [bytes(rnd.choice([0xFD, 0xFE, rnd.randrange(256)]) for _ in range(300)) for _ in good]
    payload = _stream(noise, good)

    def serve() -> None:
        conn, _ = srv.accept()
        with conn:
            for k in range(0, len(payload), 97):
                conn.sendall(payload[k:k + 97])
                time.sleep(0.002)
            time.sleep(0.5)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    ep = Endpoint(f"tcp:127.0.0.1:{port}", heartbeat_hz=0)
    try:
        ep.start(wait_heartbeat_s=3.0)
        deadline = time.monotonic() + 3.0
        while ep.stats.rx_bytes < len(payload) and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.1)
        assert ep.stats.rx_bytes == len(payload)
        assert ep.stats.reconnects == 0, "garbage made the endpoint reopen the transport"
        assert ep.stats.rx_parse_errors > 0
        assert ep.state.pose is not None and ep.state.pose.x_m == pytest.approx(1.5)
        assert ep.state.behaviour is not None and ep.state.behaviour.layer == 2
    finally:
        ep.close()
        srv.close()
        t.join(timeout=2)


# ---- robot state: decoded messages with arbitrary field values ------------------------------------
@PROFILE
@given(st.integers(0, 255), st.lists(st.integers(-2**31, 2**31 - 1), min_size=4, max_size=4),
       st.binary(max_size=50), st.binary(max_size=16), st.integers(0, 65535), st.integers(0, 65535))
def test_robot_state_takes_any_field_values(wheels: int, counts: list[int], text: bytes, pid: bytes,
                                           pindex: int, seq: int) -> None:
    mav = new_codec(1, 1)
    msgs = [
        mav.agnav_encoder_status_encode(0, counts, [0] * 4, [0] * 4, wheels),
        mav.statustext_encode(0, text),
        mav.param_value_encode(pid, float("nan"), 6, 65535 - pindex, pindex),
        mav.agnav_sonar_ring_encode(0, [65535] * 12, [255] * 12, wheels, seq),
        mav.agnav_behaviour_status_encode(2**32 - 1, 255, 255, 0xFFFF, -32768, 32767),
    ]
    state = RobotState()
    for m in _good(_parse(b"".join(x.pack(mav) for x in msgs))):
        state.update(m, 1.0)
    assert state.encoders is not None and 0 <= state.encoders.wheels <= 4
    assert len(state.statustexts) == 1 and state.sonar is not None


# ---- telemetry logs ---------------------------------------------------------------------------------------
def _write_tlog(path: Path, frames: list[bytes]) -> None:
    with TlogWriter(path) as w:
        for k, f in enumerate(frames):
            w.write(f, t_s=1_700_000_000.0 + 0.1 * k)


def test_tlog_truncated_anywhere_yields_a_prefix_of_its_frames(tmp_path: Path) -> None:
    frames = FRAMES[:6]
    whole = tmp_path / "whole.tlog"
    _write_tlog(whole, frames)
    blob = whole.read_bytes()
    cut_path = tmp_path / "cut.tlog"
    for cut in range(len(blob) + 1):
        cut_path.write_bytes(blob[:cut])
        got = [bytes(m.get_msgbuf()) for _, m in read_tlog(cut_path)]
        assert got == frames[:len(got)], f"cut at {cut}: not a prefix"
        complete = sum(1 for k in range(len(frames)) if sum(8 + len(f) for f in frames[:k + 1]) <= cut)
        assert len(got) >= complete, f"cut at {cut}: {len(got)} frames read, {complete} complete in the file"
        summarize_tlog(cut_path)


@PROFILE
@given(st.binary(max_size=800), st.data())
def test_tlog_reader_never_raises_on_random_or_damaged_files(noise: bytes, data: st.DataObject) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "noise.tlog"
        path.write_bytes(noise)
        list(read_tlog(path))
        summarize_tlog(path)
        path = Path(tmp) / "damaged.tlog"
        _write_tlog(path, FRAMES[:4])
        blob = bytearray(path.read_bytes())
        i = data.draw(st.integers(0, len(blob) - 1), label="index")
        blob[i] ^= data.draw(st.integers(1, 255), label="xor")
        path.write_bytes(bytes(blob))
        got = [bytes(m.get_msgbuf()) for m in _good([m for _, m in read_tlog(path)])]
        assert all(g in FRAMES for g in got), "a damaged record decoded as a frame that was never written"
        summarize_tlog(path)
