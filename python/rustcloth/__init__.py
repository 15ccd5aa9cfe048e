"""rustcloth: interactive, real-time mass-spring cloth with a parallel Rust core.

>>> import rustcloth
>>> sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
>>> sim.advance(0.5)
500
"""

from . import _core
from .errors import (
    ParameterError,
    ParameterTypeError,
    ParticleIndexError,
    RustclothError,
    SimulationDiverged,
    StabilityWarning,
)
from .scene import Scene, StabilityReport, load_scene, scenes
from .simulation import Energy, PassTime, Profile, Simulation

INTEGRATORS: tuple[str, ...] = tuple(_core.INTEGRATORS)
"""Names of the available time integrators."""

__version__ = "0.1.0"

__all__ = [
    "INTEGRATORS",
    "Energy",
    "ParameterError",
    "ParameterTypeError",
    "ParticleIndexError",
    "PassTime",
    "Profile",
    "RustclothError",
    "Scene",
    "Simulation",
    "SimulationDiverged",
    "StabilityReport",
    "StabilityWarning",
    "load_scene",
    "scenes",
]
