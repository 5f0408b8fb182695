"""docs/parameters.md matches the firmware's PARAMS table and its defaults (booted natively)."""
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
    rows = [line for line in text.splitlines() if line.startswith("| `")]
    main_c = (REPO / "firmware" / "src" / "main.c").read_text(encoding="utf-8")
    assert len(rows) == main_c.count("PARAM_U8, &") + main_c.count("PARAM_U16, &") + main_c.count("PARAM_I16, &") \
        + main_c.count("PARAM_I32, &") + main_c.count("PARAM_I8, &")
    assert any(r.startswith("| `LINK_TIMEOUT_MS` |") and r.rstrip().endswith("| 500 |") for r in rows)
