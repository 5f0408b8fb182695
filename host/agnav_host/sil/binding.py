"""ctypes binding of the SIL libraries (the C API of hil/sil/sil_api.h).

Two backends implement that API: ``native`` (libagnav_sil.so, in build/sil of a checkout: the firmware built for
the PC against the simulated HAL) and ``avr`` (libagnav_avr_sil.so: libsimavr running
the real ATmega2560 ELF at 16 MHz, hil/simavr/avr_sil.c). ``Firmware(backend="avr")`` picks the
second (both are built on demand).

Each :class:`Firmware` loads its own private copy of ``libagnav_sil.so`` (copied to a temporary
file, opened, then unlinked), so every instance is a pristine power-on: the firmware's file-scope
state is fresh, several instances can run side by side in one process, and two runs with the same
inputs are bit-identical.
"""

from __future__ import annotations

import ctypes as C
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .build import build_library

__all__ = ["Firmware", "Outputs", "PARAMS_RESULT", "BACKENDS", "ENCODER_FAULTS", "SONAR_FAULTS", "EEPROM_RECORDS",
           "RESET_CAUSES"]

BACKENDS = ("native", "avr")

PARAMS_RESULT = {0: "ok", -1: "unknown", -2: "out of range", -3: "storage", -4: "corrupt"}


class _COutputs(C.Structure):
    _fields_ = [("servo_us", C.c_uint16 * 2), ("duty", C.c_uint8 * 2), ("reverse", C.c_uint8 * 2),
                ("wdt_kicks", C.c_uint32), ("wdt_timeout_ms", C.c_uint16), ("reserved", C.c_uint16)]


@dataclass(frozen=True)
class Outputs:
    """Actuator outputs: servo pulses (steer, throttle) in us, H-bridge duty and direction per side."""

    steer_us: int
    throttle_us: int
    duty_left: int
    duty_right: int
    reverse_left: bool
    reverse_right: bool
    wdt_kicks: int


_SIGS: dict[str, tuple[object, list[object]]] = {
    "sil_api_version": (C.c_uint32, []),
    "sil_init": (None, []),
    "sil_boot": (None, []),
    "sil_reset": (None, []),
    "sil_reboot": (None, []),
    "sil_time_us": (C.c_uint64, []),
    "sil_set_tick_us": (None, [C.c_uint32]),
    "sil_set_stop_on_trigger": (None, [C.c_int]),
    "sil_step": (C.c_uint32, [C.c_uint32]),
    "sil_step_to": (C.c_uint64, [C.c_uint64]),
    "sil_loop_passes": (C.c_uint64, []),
    "sil_uart_write": (C.c_uint32, [C.c_char_p, C.c_uint32]),
    "sil_uart_read": (C.c_uint32, [C.c_void_p, C.c_uint32]),
    "sil_encoder_edge": (None, [C.c_uint8, C.c_uint8]),
    "sil_queue_encoder_edges": (C.c_uint32, [C.c_uint8, C.c_void_p, C.c_void_p, C.c_uint32]),
    "sil_queue_echo": (C.c_int, [C.c_uint8, C.c_uint64, C.c_uint8]),
    "sil_take_triggers": (C.c_uint32, [C.c_void_p, C.c_void_p, C.c_uint32]),
    "sil_sonar_trigger_count": (C.c_uint32, [C.c_uint8]),
    "sil_sonar_echo_edge": (None, [C.c_uint8, C.c_uint8]),
    "sil_pending_events": (C.c_uint32, []),
    "sil_late_events": (C.c_uint32, []),
    "sil_outputs": (None, [C.POINTER(_COutputs)]),
    "sil_param_set": (C.c_int, [C.c_char_p, C.c_int32]),
    "sil_param_get": (C.c_int, [C.c_char_p, C.POINTER(C.c_int32)]),
    "sil_param_save": (C.c_int, []),
    "sil_eeprom_size": (C.c_uint32, []),
    "sil_eeprom_read": (None, [C.c_uint32, C.c_void_p, C.c_uint32]),
    "sil_eeprom_write": (None, [C.c_uint32, C.c_char_p, C.c_uint32]),
    # fault injection (SIL API 2, hil/sil/sil_api.h)
    "sil_fault_encoder": (C.c_int, [C.c_uint8, C.c_int]),
    "sil_fault_sonar": (C.c_int, [C.c_uint8, C.c_int]),
    "sil_eeprom_record": (C.c_int, [C.c_int, C.POINTER(C.c_uint32), C.POINTER(C.c_uint32)]),
    "sil_eeprom_corrupt": (None, [C.c_uint32, C.c_uint32, C.c_uint8]),
    "sil_fault_reset": (None, [C.c_int]),
    "sil_resets": (C.c_uint32, []),
    "sil_kick_gap_max_us": (C.c_uint32, []),
    "sil_isr_burst": (C.c_uint32, [C.c_uint8, C.c_uint32, C.c_uint32]),
    "sil_set_isr_cost_us": (None, [C.c_uint32]),
}

#: Fault modes and names of sil_api.h's fault-injection hooks.
ENCODER_FAULTS = {"none": 0, "stuck": 1, "disconnected": 2, "noise": 3}
SONAR_FAULTS = {"none": 0, "timeout": 1, "zero": 2}
EEPROM_RECORDS = {"calib": 0, "params": 1, "signing": 2, "signing_ts": 3, "calib_copy": 4, "params_copy": 5,
                  "signing_copy": 6}
RESET_CAUSES = {"power_on": 0, "watchdog": 1, "external": 2, "brown_out": 3}

_NATIVE_SIGS: dict[str, tuple[object, list[object]]] = {
    "sil_eeprom_idle_calls": (C.c_uint32, []),
    "sil_eeprom_writes": (C.c_uint32, []),
}

_AVR_SIGS: dict[str, tuple[object, list[object]]] = {
    "sil_avr_set_elf": (None, [C.c_char_p]),
    "sil_avr_param_count": (C.c_int, []),
    "sil_avr_param_name": (C.c_char_p, [C.c_int]),
    "sil_avr_cycles": (C.c_uint64, []),
    "sil_avr_instructions": (C.c_uint64, []),
    "sil_avr_state": (C.c_int, []),
    "sil_avr_uart_rx_pending": (C.c_uint32, []),
    "sil_avr_resets": (C.c_uint32, []),
    "sil_avr_set_host_baud": (None, [C.c_uint32]),
    "sil_avr_uart_link_stats": (None, [C.POINTER(C.c_uint32)]),
    "sil_avr_set_uart_divisor": (None, [C.c_uint32, C.c_int]),
    "sil_avr_set_eeprom_write_us": (None, [C.c_uint32]),
    "sil_avr_eeprom_writes": (C.c_uint32, []),
    "sil_avr_control_ticks": (C.c_uint32, []),
    "sil_avr_control_gap_max_us": (C.c_uint32, []),
}


class Firmware:
    """One simulated robot controller running the real firmware.

    ``params`` (name -> value) are stored to the simulated EEPROM and the firmware is rebooted
    with them before any time passes, as if they had been saved on the robot before the run.

    ``backend``: ``"native"`` (default) or ``"avr"`` (the real AVR ELF under simavr; ``elf``
    overrides the ELF path, default the PlatformIO build, rebuilt when stale). On the AVR the
    boot itself takes simulated time (~5 ms: C start-up, EEPROM loads), ``tick_us`` is ignored
    (the real main loop runs free) and ``loop_passes`` is 0.
    """

    def __init__(self, params: dict[str, int] | None = None, lib_path: Path | None = None, tick_us: int = 100,
                 backend: str = "native", elf: str | Path | None = None) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"unknown SIL backend {backend!r}; known: {', '.join(BACKENDS)}")
        self.backend = backend
        self.elf: Path | None = None
        if backend == "avr":
            from .avr_build import build_avr_elf, build_avr_library

            src = Path(lib_path) if lib_path is not None else build_avr_library()
            self.elf = Path(elf) if elf is not None else build_avr_elf()
            if not self.elf.exists():
                raise FileNotFoundError(f"AVR firmware ELF not found: {self.elf}")
        else:
            src = Path(lib_path) if lib_path is not None else build_library()
        fd, tmp = tempfile.mkstemp(prefix="agnav_sil_", suffix=".so")
        os.close(fd)
        try:
            shutil.copyfile(src, tmp)
            self._lib = C.CDLL(tmp, mode=os.RTLD_LOCAL)
        finally:
            os.unlink(tmp)  # the mapping stays valid
        for name, (res, args) in _SIGS.items():
            f = getattr(self._lib, name)
            f.restype = res
            f.argtypes = args
        for name, (res, args) in (_AVR_SIGS if backend == "avr" else _NATIVE_SIGS).items():
            f = getattr(self._lib, name)
            f.restype = res
            f.argtypes = args
        if backend == "avr":
            self._lib.sil_avr_set_elf(str(self.elf).encode())
        self._buf = C.create_string_buffer(65536)
        self._trig_idx = (C.c_uint8 * 256)()
        self._trig_t = (C.c_uint64 * 256)()
        self._out = _COutputs()
        self._lib.sil_reset()
        if backend == "avr" and self._lib.sil_avr_param_count() < 0:
            raise RuntimeError(f"AVR SIL: no PARAMS table in {self.elf}")
        if params:
            for k, v in params.items():
                self.param_set(k, v)
            rc = self._lib.sil_param_save()
            if rc != 0:
                raise RuntimeError(f"SIL: storing parameters failed ({PARAMS_RESULT.get(rc, rc)})")
            self._lib.sil_reboot()
        self._lib.sil_set_tick_us(tick_us)
        self._take = self._lib.sil_take_triggers
        self.step_us = self._lib.sil_step  # fast path: bound C function
        self.step_to = self._lib.sil_step_to

    # ---- life cycle -----------------------------------------------------------------------------
    def close(self) -> None:
        lib = vars(self).pop("_lib", None)  # a closed Firmware has no library left to call
        if lib is not None:
            import _ctypes

            _ctypes.dlclose(lib._handle)

    def __enter__(self) -> "Firmware":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def reboot(self) -> None:
        self._lib.sil_reboot()

    # ---- time -------------------------------------------------------------------------------------
    @property
    def time_us(self) -> int:
        return int(self._lib.sil_time_us())

    def set_tick_us(self, us: int) -> None:
        self._lib.sil_set_tick_us(us)

    def set_stop_on_trigger(self, on: bool) -> None:
        self._lib.sil_set_stop_on_trigger(1 if on else 0)

    @property
    def loop_passes(self) -> int:
        return int(self._lib.sil_loop_passes())

    # ---- link ---------------------------------------------------------------------------------------
    def uart_write(self, data: bytes) -> int:
        return int(self._lib.sil_uart_write(data, len(data)))

    def uart_read(self) -> bytes:
        out = b""
        while True:
            n = self._lib.sil_uart_read(self._buf, len(self._buf))
            out += self._buf.raw[:n]
            if n < len(self._buf):
                return out

    # ---- encoders and sonar ------------------------------------------------------------------------
    def encoder_edge(self, idx: int, ab: int) -> None:
        self._lib.sil_encoder_edge(idx, ab)

    def queue_encoder_edges(self, idx: int, t_us: np.ndarray, ab: np.ndarray) -> int:
        t = np.ascontiguousarray(t_us, dtype=np.uint64)
        a = np.ascontiguousarray(ab, dtype=np.uint8)
        n = len(t)
        if n == 0:
            return 0
        k = int(self._lib.sil_queue_encoder_edges(idx, t.ctypes.data, a.ctypes.data, n))
        if k != n:
            raise RuntimeError(f"SIL event queue full: {k} of {n} encoder edges queued")
        return k

    def queue_echo(self, idx: int, t_us: int, level: int) -> None:
        if not self._lib.sil_queue_echo(idx, t_us, level):
            raise RuntimeError("SIL event queue full (echo)")

    def take_triggers(self) -> list[tuple[int, int]]:
        n = self._take(self._trig_idx, self._trig_t, 256)
        if n == 0:
            return []
        return list(zip(self._trig_idx[:n], self._trig_t[:n]))

    def trigger_count(self, idx: int) -> int:
        return int(self._lib.sil_sonar_trigger_count(idx))

    @property
    def pending_events(self) -> int:
        return int(self._lib.sil_pending_events())

    @property
    def late_events(self) -> int:
        return int(self._lib.sil_late_events())

    # ---- outputs --------------------------------------------------------------------------------------
    def outputs(self) -> Outputs:
        o = self._out
        self._lib.sil_outputs(C.byref(o))
        return Outputs(o.servo_us[0], o.servo_us[1], o.duty[0], o.duty[1], bool(o.reverse[0]), bool(o.reverse[1]),
                       o.wdt_kicks)

    # ---- parameters ------------------------------------------------------------------------------------
    def param_set(self, name: str, value: int) -> None:
        rc = self._lib.sil_param_set(name.encode(), int(value))
        if rc != 0:
            raise ValueError(f"SIL parameter {name}={value}: {PARAMS_RESULT.get(rc, rc)}")

    def param_get(self, name: str) -> int:
        v = C.c_int32()
        if self._lib.sil_param_get(name.encode(), C.byref(v)) != 0:
            raise KeyError(name)
        return int(v.value)

    # ---- fault injection (hil/sil/sil_api.h "FAULT INJECTION") ----------------------------------------
    def fault_encoder(self, idx: int, mode: str) -> None:
        """Encoder idx: "stuck" (edges swallowed), "disconnected" (lines float high, then silence),
        "noise" (every edge an illegal jump) or "none"."""
        if self._lib.sil_fault_encoder(idx, ENCODER_FAULTS[mode]) != 0:
            raise ValueError(f"encoder {idx}: bad index")

    def fault_sonar(self, idx: int, mode: str) -> None:
        """Sonar idx: "timeout" (echo never rises), "zero" (a ~10 mm echo after every trigger) or "none"."""
        if self._lib.sil_fault_sonar(idx, SONAR_FAULTS[mode]) != 0:
            raise ValueError(f"sonar {idx}: bad index")

    def eeprom_idle_calls(self) -> int:
        """How often the firmware said the robot is at rest (hal_eeprom_idle) since reset; native backend only."""
        if self.backend != "native":
            raise NotImplementedError("eeprom_idle_calls: the AVR firmware's hal_eeprom_idle is not observable")
        return int(self._lib.sil_eeprom_idle_calls())

    def eeprom_record(self, name: str) -> tuple[int, int]:
        """(address, length) of an EEPROM record: "calib", "params", "signing", "signing_ts"."""
        a, n = C.c_uint32(), C.c_uint32()
        if self._lib.sil_eeprom_record(EEPROM_RECORDS[name], C.byref(a), C.byref(n)) != 0:
            raise KeyError(name)
        return int(a.value), int(n.value)

    def eeprom_corrupt(self, addr: int, length: int, xor_mask: int = 0xFF) -> None:
        """Flip bits of EEPROM bytes [addr, addr + length); the firmware sees it at its next boot."""
        self._lib.sil_eeprom_corrupt(addr, length, xor_mask)

    def corrupt_record(self, name: str, offset: int = 0, length: int = 1, xor_mask: int = 0x01) -> None:
        a, n = self.eeprom_record(name)
        if offset + length > n:
            raise ValueError(f"{name} record is {n} bytes")
        self.eeprom_corrupt(a + offset, length, xor_mask)

    def fault_reset(self, cause: str) -> None:
        """Core reset now with the given cause ("watchdog", "brown_out", "external", "power_on"):
        the world (SIL clock, queued edges, EEPROM) goes on, the firmware starts afresh."""
        self._lib.sil_fault_reset(RESET_CAUSES[cause])

    @property
    def reset_count(self) -> int:
        """Core resets since power-on: sil_fault_reset() and (native model / simavr) watchdog."""
        return int(self._lib.sil_resets())

    def kick_gap_max_us(self) -> int:
        """Longest gap between two watchdog kicks (= control ticks) since the last call."""
        return int(self._lib.sil_kick_gap_max_us())

    def isr_burst(self, idx: int, n: int, period_us: int) -> int:
        """Queue n legal quadrature edges of encoder idx, one every period_us from now."""
        return int(self._lib.sil_isr_burst(idx, n, period_us))

    def set_isr_cost_us(self, us: int) -> None:
        """Native backend: CPU time each delivered edge takes (the loop waits); simavr ignores it."""
        self._lib.sil_set_isr_cost_us(us)

    # ---- AVR backend ---------------------------------------------------------------------------------------
    @property
    def cycles(self) -> int:
        """CPU cycles since power-on (AVR backend; native: time_us x 16 for comparisons)."""
        if self.backend == "avr":
            return int(self._lib.sil_avr_cycles())
        return self.time_us * 16

    def avr_param_names(self) -> list[str]:
        """The parameter table as found in the AVR ELF (flash), in table order."""
        if self.backend != "avr":
            raise RuntimeError("avr_param_names: AVR backend only")
        return [self._lib.sil_avr_param_name(i).decode() for i in range(self._lib.sil_avr_param_count())]

    @property
    def core_state(self) -> int:
        """0 while the AVR core runs; simavr's cpu state once it crashed or stopped (native: 0)."""
        return int(self._lib.sil_avr_state()) if self.backend == "avr" else 0

    @property
    def resets(self) -> int:
        """Core resets since power-on other than sil_reboot() (AVR: watchdog; native: 0)."""
        return int(self._lib.sil_avr_resets()) if self.backend == "avr" else 0

    def eeprom(self) -> bytes:
        n = int(self._lib.sil_eeprom_size())
        buf = C.create_string_buffer(n)
        self._lib.sil_eeprom_read(0, buf, n)
        return buf.raw
