"""Fault injection suite (``agnav faults`` / ``make faults``): every fault the robot and the host
are expected to survive, injected into the SIL firmware, its radio link, its sensors, or the host's
own I/O, with the reaction measured and compared with the expected one.

Areas: ``link`` (:mod:`.link_faults`), ``firmware`` (sensors, controller, commands, signing:
:mod:`.firmware_faults`), ``host`` (:mod:`.host_faults`).
"""

from __future__ import annotations

from ._core import FaultCase, FaultOutcome, FaultRow, format_table, run_cases

__all__ = ["FaultCase", "FaultOutcome", "FaultRow", "all_cases", "format_table", "run_cases"]


def all_cases() -> list[FaultCase]:
    from .host_faults import HOST_CASES
    from .link_faults import LINK_CASES

    cases: list[FaultCase] = [*LINK_CASES]
    try:
        from .firmware_faults import FIRMWARE_CASES
    except ImportError:
        pass
    else:
        cases += FIRMWARE_CASES
    from .laser_faults import LASER_CASES

    cases += LASER_CASES
    from .command_faults import COMMAND_CASES, SIGNING_CASES

    cases += COMMAND_CASES
    cases += SIGNING_CASES
    cases += HOST_CASES
    return cases
