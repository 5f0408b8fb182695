"""Scanner emulators for the SIL (see :mod:`.base`): ``tim5xx``, ``lms1xx``, ``lms5xx`` (:mod:`.sick`), ``ust`` and
``urg`` (:mod:`.scip`), ``rplidar`` (:mod:`.rplidar`). :func:`make_emulator` builds one by kind."""

from __future__ import annotations

from typing import Any

from .base import ScanGeometry

__all__ = ["EMULATOR_KINDS", "make_emulator", "ScanGeometry", "geometry_of"]

#: kind -> (transport, default port): "tcp" serves on the device's port, "pty" on a pseudo-terminal
EMULATOR_KINDS: dict[str, tuple[str, int]] = {
    "tim5xx": ("tcp", 2112), "lms1xx": ("tcp", 2112), "lms5xx": ("tcp", 2112),
    "ust": ("tcp", 10940), "urg": ("pty", 0), "rplidar": ("pty", 0),
}


def geometry_of(spec: Any) -> ScanGeometry:
    """The emulated device's scan geometry from a simulator LaserSpec."""
    return ScanGeometry(spec.angle_min_rad, spec.resolution_rad, spec.n_beams, spec.min_range_m, spec.max_range_m,
                        spec.rate_hz)


def make_emulator(kind: str, geometry: ScanGeometry, port: int | None = None) -> Any:
    """An emulator of ``kind`` (not started). ``port``: the TCP port (SICK: CoLa-B; an LMS's CoLa-A is served on
    the port below it, 2111 beside 2112); None = the device's own, 0 = any free one. ValueError for an unknown
    kind or a geometry the device cannot have."""
    if kind not in EMULATOR_KINDS:
        raise ValueError(f"unknown scanner {kind!r}; emulated: {', '.join(EMULATOR_KINDS)}")
    if kind in ("tim5xx", "lms1xx", "lms5xx"):
        from .sick import SickEmulator

        ports = None
        if port is not None:
            ports = (port, port) if kind == "tim5xx" else ((port - 1 if port > 1 else 0), port)
            if port == 0:
                ports = (0, 0)
        return SickEmulator(kind, geometry, ports=ports)
    if kind in ("ust", "urg"):
        from .scip import ScipEmulator

        return ScipEmulator(kind, geometry, port=port if kind == "ust" else None)
    from .rplidar import RplidarEmulator

    return RplidarEmulator(kind, geometry)
