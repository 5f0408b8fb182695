"""docs/parameters.md matches the firmware's parameter groups and their defaults (booted natively)."""
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_parameter_doc_is_up_to_date():
    r = subprocess.run([sys.executable, str(REPO / "tools" / "gen_param_doc.py"), "--check"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def test_every_firmware_parameter_is_documented_with_a_default():
    text = (REPO / "docs" / "parameters.md").read_text(encoding="utf-8")
    rows = [line for line in text.splitlines() if re.match(r"\| \d+ \| `", line)]
    sources = [p.read_text(encoding="utf-8") for p in (REPO / "firmware" / "lib").glob("*/*_params.c")]
    declared = sum(len(re.findall(r'\{"[A-Z0-9_]+", \d+, PARAM_(?:U8|U16|I16|I32|I8), &', t)) for t in sources)
    assert declared > 0 and len(rows) == declared
    assert any(r.startswith("| 9 | `LINK_TIMEOUT_MS` |") and r.rstrip().endswith("| 500 |") for r in rows)
