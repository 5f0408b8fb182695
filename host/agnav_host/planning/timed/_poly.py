"""Boundary-value polynomials of ref 003 (chapter 4) and a rotation-invariant variant.

Ref 003 plans a car-like robot from a start state to a goal state reached at a set time T with
``x(t)`` a cubic and ``y(t)`` a quintic. The state at each end is (x, y, heading theta, steering
phi, speed v). The equations of its sections 4.2-4.4 were lost in the text conversion; what follows is
reconstructed from the surrounding text (kinematic model 4.1, "boundary conditions", "chain rule"):

* x(t) = a0 + a1 t + a2 t^2 + a3 t^3 with x(0) = x0, x(T) = xT, dx/dt(0) = v0 cos(theta0),
  dx/dt(T) = vT cos(thetaT) (four conditions, hence a cubic).
* y(t) = b0 + ... + b5 t^5 with y(0), y(T), dy/dt = v sin(theta) at both ends and d2y/dt2 at both
  ends from the steering angle. By the chain rule, with dy/dx = tan(theta) and the curvature of the
  bicycle model kappa = tan(phi) / l (l = wheelbase):
      d2y/dt2 = (d2y/dx2) (dx/dt)^2 + (dy/dx) d2x/dt2
              = kappa / cos(theta)^3 * (dx/dt)^2 + tan(theta) * d2x/dt2.
  (six conditions, hence a quintic). With v = 0 at an end, the direction of travel there is set by
  the accelerations (d2y/dt2 = tan(theta) d2x/dt2), which is how 003 starts and stops at rest.

This form is singular where cos(theta) = 0 (003 restricts theta to (-pi/2, pi/2)). AgNav evaluates it
in the frame of the start->goal chord, where both end headings are usually well inside that range,
and falls back to :func:`hermite5_coeffs` (x and y both quintic, tangent and curvature matched at
both ends, no preferred axis) when they are not.

All functions are pure; coefficient arrays are lowest order first; units SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...types import FloatArray

__all__ = [
    "BoundaryState",
    "cubic_coeffs",
    "quintic_coeffs",
    "y_accel_from_steer",
    "poly003_coeffs",
    "hermite5_coeffs",
    "poly_eval",
]


@dataclass(frozen=True)
class BoundaryState:
    """One end of a timed trajectory: pose (m, rad), steering angle (rad, + = left), speed (m/s)."""

    x_m: float
    y_m: float
    yaw_rad: float
    steer_rad: float = 0.0
    speed_m_s: float = 0.0


def cubic_coeffs(p0: float, pT: float, v0: float, vT: float, T: float) -> FloatArray:
    """Cubic through p0 -> pT over [0, T] with end slopes v0, vT; (4,) lowest order first."""
    d = pT - p0
    return np.array([p0, v0, (3.0 * d - (2.0 * v0 + vT) * T) / T**2, (-2.0 * d + (v0 + vT) * T) / T**3])


def quintic_coeffs(p0: float, v0: float, a0: float, pT: float, vT: float, aT: float, T: float) -> FloatArray:
    """Quintic with value, slope and second derivative set at 0 and T; (6,) lowest order first."""
    T2, T3 = T * T, T**3
    c0, c1, c2 = p0, v0, 0.5 * a0
    # remaining three from the end conditions (closed form of the 3x3 solve)
    r0 = pT - (c0 + c1 * T + c2 * T2)
    r1 = vT - (c1 + 2.0 * c2 * T)
    r2 = aT - 2.0 * c2
    c3 = (20.0 * r0 - 8.0 * r1 * T + r2 * T2) / (2.0 * T3)
    c4 = (-30.0 * r0 + 14.0 * r1 * T - 2.0 * r2 * T2) / (2.0 * T**4)
    c5 = (12.0 * r0 - 6.0 * r1 * T + r2 * T2) / (2.0 * T**5)
    return np.array([c0, c1, c2, c3, c4, c5])


def y_accel_from_steer(yaw_rad: float, steer_rad: float, wheelbase_m: float, xd: float, xdd: float) -> float:
    """d2y/dt2 from heading, steering and the x derivatives (ref 003 chain rule, reconstructed above)."""
    c = math.cos(yaw_rad)
    kappa = math.tan(steer_rad) / wheelbase_m
    return kappa * xd * xd / (c**3) + math.tan(yaw_rad) * xdd


def poly003_coeffs(start: BoundaryState, goal: BoundaryState, T: float, wheelbase_m: float,
                   min_cos: float = 0.2) -> tuple[FloatArray, FloatArray]:
    """Ref 003 trajectory: x(t) cubic (4,), y(t) quintic (6,) over [0, T] s, in the states' frame.

    Raises ValueError when T <= 0 or an end heading is within acos(min_cos) of +-90 deg (the form is
    singular there; use :func:`hermite5_coeffs` or another frame).
    """
    if not T > 0:
        raise ValueError(f"T must be > 0, got {T}")
    for name, st in (("start", start), ("goal", goal)):
        if abs(math.cos(st.yaw_rad)) < min_cos:
            raise ValueError(f"{name} heading {math.degrees(st.yaw_rad):.1f} deg is too close to +-90 deg for x(t)/y(t) polynomials")
    vx0 = start.speed_m_s * math.cos(start.yaw_rad)
    vxT = goal.speed_m_s * math.cos(goal.yaw_rad)
    a = cubic_coeffs(start.x_m, goal.x_m, vx0, vxT, T)
    xdd0 = 2.0 * a[2]
    xddT = 2.0 * a[2] + 6.0 * a[3] * T
    vy0 = vx0 * math.tan(start.yaw_rad)
    vyT = vxT * math.tan(goal.yaw_rad)
    ay0 = y_accel_from_steer(start.yaw_rad, start.steer_rad, wheelbase_m, vx0, xdd0)
    ayT = y_accel_from_steer(goal.yaw_rad, goal.steer_rad, wheelbase_m, vxT, xddT)
    b = quintic_coeffs(start.y_m, vy0, ay0, goal.y_m, vyT, ayT, T)
    return a, b


def hermite5_coeffs(start: BoundaryState, goal: BoundaryState, T: float, wheelbase_m: float) -> tuple[FloatArray, FloatArray]:
    """x(t) and y(t) both quintic (6,) over [0, T]: position, velocity v (cos, sin) and the normal
    acceleration v^2 kappa at both ends (no tangential acceleration). Rotation invariant; needs v > 0."""
    if not T > 0:
        raise ValueError(f"T must be > 0, got {T}")
    out = []
    for axis in (0, 1):
        ends = []
        for st in (start, goal):
            c, s = math.cos(st.yaw_rad), math.sin(st.yaw_rad)
            kappa = math.tan(st.steer_rad) / wheelbase_m
            v = st.speed_m_s
            p = st.x_m if axis == 0 else st.y_m
            vel = v * (c if axis == 0 else s)
            acc = v * v * kappa * (-s if axis == 0 else c)
            ends.append((p, vel, acc))
        (p0, v0, a0), (pT, vT, aT) = ends
        out.append(quintic_coeffs(p0, v0, a0, pT, vT, aT, T))
    return out[0], out[1]


def poly_eval(c: FloatArray, t: FloatArray | float, der: int = 0) -> FloatArray:
    """Value (der=0) or derivative (der=1, 2) of a polynomial with coefficients lowest order first."""
    t = np.asarray(t, dtype=float)
    cc = np.asarray(c, dtype=float)
    for _ in range(der):
        cc = cc[1:] * np.arange(1, len(cc))
    out = np.zeros_like(t)
    for k in range(len(cc) - 1, -1, -1):  # Horner
        out = out * t + cc[k]
    return out
