"""`agnav sil --stop-at-end`: when the referee ends the run, the SIL keeps serving until the robot side hangs up
(or its grace period passes), so a robot side whose own estimate reaches the goal a moment after the truth does
still sees its arrival over a live link."""

from __future__ import annotations

import dataclasses
import socket
import threading
import time

from agnav_host.sil import build_library
from agnav_host.sil.server import ServeOptions, serve
from agnav_host.sim.scenario import load_scenario
from agnav_host.types import Goal


def _at_goal_scenario():
    sc = load_scenario("timed_static")
    s = sc.start  # the referee judges "arrived" at the first step: the goal is where the robot stands
    return dataclasses.replace(sc, goals=[Goal(s.x_m, s.y_m, tolerance_m=0.3)])


def _serve(sc, grace_s: float, duration_s: float = 30.0):
    build_library()
    box: dict[str, object] = {"log": []}
    up, done = threading.Event(), threading.Event()

    def ready(addr, pty):
        box["addr"] = addr
        up.set()

    def run():
        box["result"] = serve(sc, ServeOptions(tcp=("127.0.0.1", 0), speedup=1.0, duration_s=duration_s, stop_at_end=True,
                                               end_grace_s=grace_s), log=box["log"].append, ready=ready)
        done.set()

    threading.Thread(target=run, daemon=True).start()
    assert up.wait(30)
    return box, done


def test_serving_goes_on_after_the_end_while_the_client_is_connected_and_stops_when_it_hangs_up():
    box, done = _serve(_at_goal_scenario(), grace_s=20.0)
    host, port = box["addr"]
    c = socket.create_connection((host, port), timeout=5)
    c.settimeout(0.5)
    t0 = time.monotonic()
    got = 0
    while time.monotonic() - t0 < 2.0:  # the firmware's telemetry keeps flowing after the referee's end
        try:
            got += len(c.recv(4096))
        except socket.timeout:
            pass
    assert any("referee: arrived" in m for m in box["log"]), box["log"]
    assert not done.is_set() and got > 200, (got, box["log"])
    c.close()
    assert done.wait(5.0), box["log"]  # hanging up ends it at once, not after the grace period
    assert box["result"].end_reason == "arrived"


def test_serving_stops_after_the_grace_period_when_the_client_stays():
    box, done = _serve(_at_goal_scenario(), grace_s=1.0)
    host, port = box["addr"]
    c = socket.create_connection((host, port), timeout=5)
    try:
        assert done.wait(10.0), box["log"]
        assert box["result"].t_s < 3.0 and box["result"].end_reason == "arrived", box["result"]
    finally:
        c.close()


def test_a_second_client_is_refused_with_a_statustext_and_the_first_keeps_the_link():
    from agnav_host.protocol import dialect

    D = dialect()
    box, done = _serve(load_scenario("timed_static"), grace_s=5.0, duration_s=4.0)
    host, port = box["addr"]
    first = socket.create_connection((host, port), timeout=5)
    time.sleep(0.3)
    second = socket.create_connection((host, port), timeout=5)
    second.settimeout(3.0)
    data = b""
    try:
        while True:
            chunk = second.recv(4096)
            if not chunk:
                break
            data += chunk
    except socket.timeout:
        pass
    second.close()
    mav = D.MAVLink(None)
    msgs = [m for m in (mav.parse_buffer(data) or []) if m.get_type() == "STATUSTEXT"]
    assert msgs and "owns the link" in msgs[0].text, data[:200]
    t_end = time.monotonic() + 5.0  # the serving thread logs the refusal after it has sent the STATUSTEXT and closed
    while not any("refused" in m for m in box["log"]) and time.monotonic() < t_end:
        time.sleep(0.05)
    assert any("refused" in m for m in box["log"]), box["log"]
    first.settimeout(1.0)
    got = 0
    t0 = time.monotonic()
    while time.monotonic() - t0 < 1.0:  # the first client still gets the robot's telemetry
        try:
            got += len(first.recv(4096))
        except socket.timeout:
            pass
    first.close()
    assert got > 100, got
    assert done.wait(10)
