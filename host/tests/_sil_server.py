"""A SIL firmware served on a loopback TCP port from a background thread, for link and CLI tests."""

from __future__ import annotations

import threading


def serve_sil(scenario: object, speedup: float, duration_s: float) -> str:
    """Start serving ``scenario`` (the firmware powers on now) and return its device string."""
    from agnav_host.sil import build_library
    from agnav_host.sil.server import ServeOptions, serve

    build_library()
    box: dict[str, object] = {}
    up = threading.Event()

    def ready(addr, pty):
        box["addr"] = addr
        up.set()

    opt = ServeOptions(tcp=("127.0.0.1", 0), speedup=speedup, duration_s=duration_s)
    threading.Thread(target=lambda: serve(scenario, opt, log=lambda m: None, ready=ready), daemon=True).start()
    assert up.wait(30), "the SIL server did not start listening"
    host, port = box["addr"]  # type: ignore[misc]
    return f"tcp:{host}:{port}"
