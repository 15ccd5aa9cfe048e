"""Exceptions raised by rustcloth.

Each one subclasses :class:`RustclothError` *and* the built-in exception a caller would
naturally catch, so ``except ValueError`` works as well as ``except rustcloth.RustclothError``.
The Rust core raises them by name (``src/python/errors.rs``).
"""

from __future__ import annotations


class RustclothError(Exception):
    """Base class of every rustcloth error."""


class ParameterError(RustclothError, ValueError):
    """A value that makes no sense: a negative stiffness, ``dt = nan``, an unknown scene key,
    an array of the wrong shape. ``parameter`` names it."""

    def __init__(self, message: str, parameter: str = "") -> None:
        super().__init__(message)
        self.parameter = parameter


class ParameterTypeError(RustclothError, TypeError):
    """A value of the wrong type: a string where a number belongs, an integer array where
    floats belong. ``parameter`` names it."""

    def __init__(self, message: str, parameter: str = "") -> None:
        super().__init__(message)
        self.parameter = parameter


class ParticleIndexError(RustclothError, IndexError):
    """A particle index outside ``0 .. num_particles - 1``."""

    def __init__(self, message: str, parameter: str = "", index: int = 0) -> None:
        super().__init__(message)
        self.parameter = parameter
        self.index = index


class SimulationDiverged(RustclothError, FloatingPointError):
    """A step went wrong and was not saved. The simulation was restored to the state before
    that step, so ``Simulation.steps`` reads ``step - 1``.

    ``step`` is the 1-based number of the step that failed, ``particle`` the first particle at
    fault, ``reason`` ``"non_finite"`` (a value became infinite or NaN), ``"overstretched"``
    (a spring grew beyond the scene's ``watchdog.max_stretch``) or ``"unresolved"`` (with
    self-collision and an integrator past its estimated stable step: more than 1 % of the edges
    changed length by over half the cloth's spacing within one substep, a runaway the pass
    would otherwise hold in a bounded boil), and ``substeps`` the most
    substeps the step was tried with (more than the scene's when ``watchdog.on_trouble =
    "substep"`` retried it)."""

    def __init__(
        self,
        message: str,
        step: int = 0,
        particle: int = 0,
        reason: str = "non_finite",
        substeps: int = 1,
    ) -> None:
        super().__init__(message)
        self.step = step
        self.particle = particle
        self.reason = reason
        self.substeps = substeps


class InternalError(RustclothError, RuntimeError):
    """A bug in rustcloth: the Rust core panicked. The simulation was put back where the call
    started (a step that panicked is rolled back like a diverged one) and stays usable; please
    report the message."""


class SimulationBusy(RustclothError, RuntimeError):
    """A call on a :class:`~rustcloth.Simulation` came from the thread that is already inside
    another call on it (a signal handler or a warning filter running during a long ``step``):
    it cannot wait for itself. Calls from other threads wait their turn instead."""


class StabilityWarning(RuntimeWarning):
    """The scene's ``dt`` exceeds the largest step its integrator is estimated to be stable
    at (``Simulation.stable_dt()``); expect ``SimulationDiverged``."""
