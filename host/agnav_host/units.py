"""Wire units <-> SI: the firmware's integers on the MAVLink link and in its parameters (mm, mm/s, ms:
thousandths; cdeg, cdeg/s: hundredths of a degree) and the host's floats (m, m/s, s; rad, rad/s).

Every conversion between the two goes through these functions (the telemetry the host reads, the setpoints
it sends, the firmware's parameters, the simulated robot's reports). From the wire they return floats; to the
wire they return floats too, for the caller to round and clamp as its field needs (:func:`to_int16`).
Each works on a number or element-wise on a numpy array.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

__all__ = ["milli_to_si", "si_to_milli", "cdeg_to_rad", "rad_to_cdeg", "to_int16"]

T = TypeVar("T", float, np.ndarray)


def milli_to_si(v: T) -> T:
    """mm -> m, mm/s -> m/s, ms -> s."""
    return v / 1000.0


def si_to_milli(v: T) -> T:
    """m -> mm, m/s -> mm/s, s -> ms."""
    return v * 1000.0


def cdeg_to_rad(v: T) -> T:
    """cdeg -> rad, cdeg/s -> rad/s (hundredths of a degree)."""
    return np.radians(v / 100.0) if isinstance(v, np.ndarray) else math.radians(v / 100.0)


def rad_to_cdeg(v: T) -> T:
    """rad -> cdeg, rad/s -> cdeg/s."""
    if isinstance(v, np.ndarray):
        cdeg: np.ndarray = np.degrees(v) * 100.0
        return cdeg
    return math.degrees(v) * 100.0


def to_int16(v: float) -> int:
    """A wire value rounded to the nearest whole number and clamped to int16."""
    return int(max(-32768, min(32767, round(v))))
