"""MAVLink 2 signing keys (``agnav key new|show|push``).

A key is 32 random bytes, stored as 64 hex digits in a file readable by its owner only
(mode 0600). Default location: ``$XDG_CONFIG_HOME/agnav/signing.key`` (``~/.config/agnav/``);
``--key-file`` or ``[link] key_file`` in the host config choose another one. The same key must be
loaded into every peer that verifies signatures.

The AgNav firmware verifies signatures once it holds a key (firmware/lib/signing, docs/safety.md
"Signing"): unsigned, wrongly signed and replayed frames are dropped and counted (SYS_STATUS
errors_count2..4), and it signs its own telemetry. The key lives in the robot's EEPROM and is set
with the standard SETUP_SIGNING message (:func:`setup_signing_message`, ``agnav key push``), which
the robot accepts only
  * signed with the key it already holds (``agnav key push --old-key-file OLD``), or
  * unsigned within 10 s of a power-on or external reset: plugging in / opening the Mega's USB
    serial port resets the board, so this means someone at the robot with a cable.
An all-zero key clears signing (``agnav key push --clear``). A stock ArduPilot takes the same
message.
"""

from __future__ import annotations

import hashlib
import os
import secrets
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = ["KeyError_", "KeyWriteError", "default_key_path", "new_key", "load_key", "fingerprint", "mavlink_timestamp",
           "setup_signing_message", "CLEAR_KEY"]

#: SETUP_SIGNING with this key switches signing off on the robot.
CLEAR_KEY = bytes(32)
_EPOCH_2015_S = 1420070400  # MAVLink signing timestamps count 10 us units from 2015-01-01 00:00 UTC


class KeyError_(RuntimeError):
    """Missing, unreadable or malformed key file."""


class KeyWriteError(KeyError_):
    """The key file cannot be written there (no such folder, read-only, a directory...)."""


def default_key_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "agnav" / "signing.key"


def new_key(path: str | Path | None = None, force: bool = False) -> tuple[Path, bytes]:
    """Create a fresh random key file; refuses to overwrite unless ``force``."""
    p = Path(path) if path else default_key_path()
    if p.is_dir():
        raise KeyWriteError(f"cannot write signing key {p}: it is a directory; give a file name")
    if p.exists() and not force:
        raise KeyError_(f"{p} exists; use --force to replace it (peers holding the old key must be updated)")
    key = secrets.token_bytes(32)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(key.hex() + "\n")
        os.chmod(p, 0o600)
    except OSError as e:
        where = f" ({e.filename})" if e.filename and str(e.filename) != str(p) else ""
        raise KeyWriteError(f"cannot write signing key {p}: {e.strerror or e}{where}") from None
    return p, key


def load_key(path: str | Path | None = None) -> bytes:
    p = Path(path) if path else default_key_path()
    if p.is_dir():
        raise KeyError_(f"cannot read signing key {p}: it is a directory, not a key file")
    try:
        text = p.read_text().strip()
    except OSError as e:
        raise KeyError_(f"cannot read signing key {p}: {e.strerror}; create one with `agnav key new`") from None
    try:
        key = bytes.fromhex(text)
    except ValueError:
        raise KeyError_(f"{p}: expected 64 hex digits") from None
    if len(key) != 32:
        raise KeyError_(f"{p}: key must be 32 bytes, got {len(key)}")
    return key


def fingerprint(key: bytes) -> str:
    """Short public fingerprint (first 8 bytes of SHA-256), safe to print and compare."""
    return hashlib.sha256(key).hexdigest()[:16]


def mavlink_timestamp(unix_s: float) -> int:
    """MAVLink 2 signing timestamp (10 us units since 2015-01-01 UTC) of a Unix time."""
    return max(0, int((unix_s - _EPOCH_2015_S) * 100_000))


def setup_signing_message(dialect: ModuleType, key: bytes, target_system: int, target_component: int = 1,
                          unix_s: float | None = None) -> Any:
    """SETUP_SIGNING for the robot: ``key`` (32 bytes; :data:`CLEAR_KEY` clears) and the initial
    timestamp (now, unless ``unix_s``). Pack it with the codec that should (or should not) sign it."""
    import time

    if len(key) != 32:
        raise ValueError("MAVLink signing key must be 32 bytes")
    ts = mavlink_timestamp(time.time() if unix_s is None else unix_s)
    return dialect.MAVLink_setup_signing_message(target_system, target_component, list(key), ts)
