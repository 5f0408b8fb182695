"""The committed byte vectors, encoded and decoded by the generated Python binding.

firmware/test/test_protocol_vectors checks the same file with the generated C binding,
so both sides agree on every byte of every AgNav message.
"""
import json
from pathlib import Path

import pytest

from agnav_host.protocol import dialect

VECTORS_PATH = Path(__file__).resolve().parents[2] / "protocol" / "vectors" / "agnav_vectors.json"
VECTORS = json.loads(VECTORS_PATH.read_text(encoding="utf-8"))


def encode(vec: dict) -> bytes:
    d = dialect()
    mav = d.MAVLink(None, srcSystem=vec["sysid"], srcComponent=vec["compid"])
    mav.seq = vec["seq"]
    cls = getattr(d, f"MAVLink_{vec['name'].lower()}_message")
    return cls(**vec["fields"]).pack(mav)


def decode(frame: bytes):
    mav = dialect().MAVLink(None)
    msgs = mav.parse_buffer(frame) or []
    return msgs


def check_vector(vec: dict) -> list[str]:
    """Return the list of disagreements between the binding and the vector (empty = agree)."""
    problems = []
    frame = bytes.fromhex(vec["frame_hex"])
    encoded = encode(vec)
    if encoded != frame:
        problems.append(f"encoded {encoded.hex()} != committed {frame.hex()}")
    try:
        msgs = decode(frame)
    except Exception as exc:  # a bad CRC raises in pymavlink's strict parser
        return problems + [f"decode failed: {exc}"]
    if len(msgs) != 1:
        return problems + [f"decoded {len(msgs)} messages"]
    msg = msgs[0]
    if msg.get_msgId() != vec["msgid"] or msg.get_type() != vec["name"]:
        return problems + [f"decoded {msg.get_type()} (id {msg.get_msgId()}), not {vec['name']}"]
    for name, want in vec["fields"].items():
        got = getattr(msg, name)
        if isinstance(want, list):
            got = list(got)
        if got != want:
            problems.append(f"{name}: decoded {got} != {want}")
    return problems


@pytest.mark.parametrize("vec", VECTORS, ids=[f"{i}-{v['name']}" for i, v in enumerate(VECTORS)])
def test_vector_encodes_and_decodes_byte_exact(vec):
    assert check_vector(vec) == []


def test_every_agnav_message_has_a_vector():
    d = dialect()
    agnav_ids = {cls.id for name, cls in vars(d).items()
                 if name.startswith("MAVLink_agnav_") and name.endswith("_message")}
    assert agnav_ids, "no AgNav messages in the dialect"
    assert agnav_ids <= {v["msgid"] for v in VECTORS}


@pytest.mark.parametrize("index", range(len(VECTORS)))
def test_one_changed_byte_in_a_vector_is_detected(index):
    vec = dict(VECTORS[index])
    frame = bytearray.fromhex(vec["frame_hex"])
    pos = len(frame) // 2
    frame[pos] ^= 0x01
    vec["frame_hex"] = frame.hex()
    assert check_vector(vec), f"flipping byte {pos} went unnoticed"
