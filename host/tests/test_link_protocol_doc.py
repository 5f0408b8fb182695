"""docs/protocol.md is generated from protocol/agnav.xml and must be current."""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _gen():
    spec = importlib.util.spec_from_file_location("gen_protocol_doc", ROOT / "tools" / "gen_protocol_doc.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_protocol_doc_is_current_and_complete():
    gen = _gen()
    text = gen.render()
    assert (ROOT / "docs" / "protocol.md").read_text() == text, "run python tools/gen_protocol_doc.py"
    root = ET.parse(ROOT / "protocol" / "agnav.xml").getroot()
    for m in root.iter("message"):
        assert f"### {m.get('name')} (id {m.get('id')})" in text
        for f in m.findall("field"):
            assert f"| {f.get('name')} |" in text
    for e in root.iter("entry"):
        assert e.get("name") in text
    assert "MAV_CMD_AGNAV_ESTOP (45900)" in text


def test_generator_check_mode_detects_staleness(tmp_path):
    gen = _gen()
    stale = tmp_path / "protocol.md"
    stale.write_text("old\n")
    assert gen.main(["--check", "--out", str(stale)]) == 1
    assert gen.main(["--out", str(stale)]) == 0
    assert gen.main(["--check", "--out", str(stale)]) == 0
