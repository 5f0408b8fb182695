"""A small scenario's text with the values a test varies (duration, time step, control rate, laser, goal
tolerance, extra tables), for the simulator tests."""

from __future__ import annotations

PLAIN = """
[scenario]
name = "plain"
duration_s = %(dur)s
dt_s = %(dt)s
control_hz = %(hz)s
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0 }
[laser]
model = "tim561"
%(laser)s
[[goals]]
x_m = 3.0
y_m = 1.0
tolerance_m = %(tol)s
%(extra)s
"""


def scenario_text(**over: object) -> str:
    """:data:`PLAIN` with ``over`` replacing the defaults (40 s, dt 0.02 s, 15 Hz, tolerance 0.3 m)."""
    return PLAIN % {**dict(dur=40.0, dt=0.02, hz=15.0, laser="", tol=0.3, extra=""), **over}
