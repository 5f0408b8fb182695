"""MAVLink 2 signing keys (``agnav key new|show``).

A key is 32 random bytes, stored as 64 hex digits in a file readable by its owner only
(mode 0600). Default location: ``$XDG_CONFIG_HOME/agnav/signing.key`` (``~/.config/agnav/``);
``--key-file`` or ``[link] key_file`` in the host config choose another one. The same key must be
loaded into every peer that verifies signatures (the AgNav firmware does not verify them yet: it
accepts signed and unsigned frames alike; a stock ArduPilot does, after SETUP_SIGNING).
"""

from __future__ import annotations

import hashlib
import os
import secrets
from pathlib import Path

__all__ = ["KeyError_", "default_key_path", "new_key", "load_key", "fingerprint"]


class KeyError_(RuntimeError):
    """Missing, unreadable or malformed key file."""


def default_key_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "agnav" / "signing.key"


def new_key(path: str | Path | None = None, force: bool = False) -> tuple[Path, bytes]:
    """Create a fresh random key file; refuses to overwrite unless ``force``."""
    p = Path(path) if path else default_key_path()
    if p.exists() and not force:
        raise KeyError_(f"{p} exists; use --force to replace it (peers holding the old key must be updated)")
    p.parent.mkdir(parents=True, exist_ok=True)
    key = secrets.token_bytes(32)
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(key.hex() + "\n")
    os.chmod(p, 0o600)
    return p, key


def load_key(path: str | Path | None = None) -> bytes:
    p = Path(path) if path else default_key_path()
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
