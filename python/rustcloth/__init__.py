"""rustcloth: interactive, real-time mass-spring cloth with a parallel Rust core.

>>> import rustcloth
>>> sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
>>> sim.advance(0.5)
500
"""

from importlib import metadata as _metadata
from typing import cast as _cast

from . import _core
from .errors import (
    InternalError,
    ParameterError,
    ParameterTypeError,
    ParticleIndexError,
    RustclothError,
    SimulationBusy,
    SimulationDiverged,
    StabilityWarning,
)
from .scene import Scene, StabilityReport, load_scene, scenes
from .settings import IntegratorName as _IntegratorName
from .simulation import Energy, PassTime, Profile, RenderMesh, Simulation

INTEGRATORS: tuple[_IntegratorName, ...] = _cast(
    "tuple[_IntegratorName, ...]", tuple(_core.INTEGRATORS))
"""Names of the available time integrators (``rustcloth.settings.IntegratorName``)."""

# One source for the version: Cargo.toml's, which maturin writes into the installed metadata
# (absent only when the package is imported from a source tree that was never installed).
try:
    __version__: str = _metadata.version("rustcloth")
except _metadata.PackageNotFoundError:
    __version__ = "0+unknown"

__all__ = [
    "INTEGRATORS",
    "Energy",
    "InternalError",
    "ParameterError",
    "ParameterTypeError",
    "ParticleIndexError",
    "PassTime",
    "Profile",
    "RenderMesh",
    "RustclothError",
    "Scene",
    "Simulation",
    "SimulationBusy",
    "SimulationDiverged",
    "StabilityReport",
    "StabilityWarning",
    "load_scene",
    "scenes",
]
