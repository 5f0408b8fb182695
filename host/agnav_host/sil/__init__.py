"""Native software-in-the-loop: the real firmware (built for the PC against the simulated HAL)
in lock-step with the world simulator, a radio link model and the host endpoint.

    build_library            (re)build libagnav_sil.so when sources are newer (build/sil in a checkout,
                             the user cache in an installed package: agnav_host._paths)
    build_avr_library        (re)build libagnav_avr_sil.so (the same C API on libsimavr
                             running the real ATmega2560 ELF; build_avr_elf rebuilds the ELF)
    Firmware                 ctypes binding (one pristine firmware per instance; backend
                             "native" or "avr")
    LinkParams, LinkChannel  radio model (latency, 57600 baud, loss); Tlog telemetry log
    HostEndpoint             the host's MAVLink endpoint
    Plant                    robot + world + sensors <-> firmware pins
    SilSession, SilConfig    lock-step loop; PlannerHost; run_sil_scenario, write_sil_outputs
"""

from .avr_build import AVR_ELF_PATH, AVR_LIB_PATH, build_avr_elf, build_avr_library
from .binding import BACKENDS, Firmware, Outputs
from .build import LIB_PATH, SilBuildError, build_library
from .host import HostEndpoint
from .link import LinkChannel, LinkFaults, LinkParams, MavFramer, Tlog, random_bursts
from .plant import Plant, PlantConfig, hbridge_table
from .session import PlannerHost, SilConfig, SilRunResult, SilSession, run_sil_scenario, write_sil_outputs

__all__ = ["AVR_ELF_PATH", "AVR_LIB_PATH", "BACKENDS", "build_avr_elf", "build_avr_library", "Firmware", "Outputs", "LIB_PATH", "SilBuildError", "build_library", "HostEndpoint", "LinkChannel",
           "LinkFaults", "LinkParams", "random_bursts", "MavFramer", "Tlog", "Plant", "PlantConfig", "hbridge_table", "PlannerHost", "SilConfig",
           "SilRunResult", "SilSession", "run_sil_scenario", "write_sil_outputs"]
