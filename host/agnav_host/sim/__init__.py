"""World simulator: robot models, worlds, sensors, scenarios and metrics (pure Python + numpy).

Deterministic for a given seed. Public surface::

    load_scenario, parse_scenario, ScenarioError, builtin_names, builtin_descriptions, DEFAULT_SCENARIO
    run_scenario, write_outputs, RunResult
    World, Mover, Hole, Step, Rut
    DiffDrive, DiffDriveParams, Ackermann, AckermannParams
    Laser2D, TiltedLaser, LaserSpec, laser_preset, SonarRing, SonarSpec, WheelEncoder, EncoderSpec
    RunMetrics, bending_energy, path_length_m, SUMMARY_KEYS
    cast_rays, cast_rays_at
"""

from ._raycast import cast_rays, cast_rays_at
from .controller import GoalSeek, GoalSeekParams
from .metrics import SUMMARY_KEYS, RunMetrics, bending_energy, path_length_m
from .robots import Ackermann, AckermannParams, DiffDrive, DiffDriveParams, integrate_arc
from .runner import RunResult, run_scenario, write_outputs
from .scenario import (
    DEFAULT_SCENARIO,
    Scenario,
    ScenarioError,
    builtin_descriptions,
    builtin_names,
    load_scenario,
    parse_scenario,
)
from .sensors import LASER_PRESETS, EncoderSpec, Laser2D, LaserSpec, SonarRing, SonarSpec, TiltedLaser, WheelEncoder, laser_preset
from .world import Hole, Mover, Rut, Step, World

__all__ = [
    "cast_rays", "cast_rays_at", "GoalSeek", "GoalSeekParams", "SUMMARY_KEYS",
    "RunMetrics", "bending_energy", "path_length_m", "Ackermann", "AckermannParams", "DiffDrive", "DiffDriveParams",
    "integrate_arc", "RunResult", "run_scenario", "write_outputs", "DEFAULT_SCENARIO", "Scenario", "ScenarioError",
    "builtin_descriptions", "builtin_names", "load_scenario", "parse_scenario", "LASER_PRESETS", "EncoderSpec",
    "Laser2D", "LaserSpec", "SonarRing", "SonarSpec", "TiltedLaser", "WheelEncoder", "laser_preset", "Hole", "Mover",
    "Rut", "Step", "World",
]
