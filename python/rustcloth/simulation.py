"""The public :class:`Simulation`: the Rust solver with Python conveniences on top."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from . import _core
from .errors import StabilityWarning
from .scene import Scene, load_scene


class Energy(NamedTuple):
    """Energies of the cloth in J."""

    kinetic: float
    """``sum m v^2 / 2`` over live particles."""
    gravitational: float
    """``-sum m g . x``: zero at the origin."""
    elastic: float
    """``sum k (l - L)^2 / 2`` over live springs of the active families."""

    @property
    def total(self) -> float:
        return self.kinetic + self.gravitational + self.elastic


@dataclass(frozen=True)
class PassTime:
    name: str
    seconds: float
    """Wall time spent in the pass so far."""
    calls: int


@dataclass(frozen=True)
class Profile:
    """Where the stepping time went, pass by pass (wall clock, since start or reset)."""

    passes: dict[str, PassTime] = field(default_factory=dict)
    steps: int = 0
    total_seconds: float = 0.0
    solver: dict[str, float] | None = None
    """For ``implicit_euler``: conjugate-gradient ``solves``, ``iterations`` (total),
    ``last_iterations``, ``last_residual`` (relative) and ``not_converged`` (solves that hit
    ``cg_max_iterations``). None for the explicit integrators."""

    def per_step_ms(self) -> dict[str, float]:
        """Milliseconds per step spent in each pass."""
        n = max(self.steps, 1)
        return {name: 1e3 * p.seconds / n for name, p in self.passes.items()}

    def __str__(self) -> str:
        n = max(self.steps, 1)
        lines = [f"{self.steps} steps, {1e3 * self.total_seconds / n:.4f} ms/step"]
        for name, p in self.passes.items():
            share = p.seconds / self.total_seconds if self.total_seconds else 0.0
            lines.append(f"  {name:<20} {1e3 * p.seconds / n:9.4f} ms/step  {share:6.1%}")
        if self.solver:
            s = self.solver
            mean = s["iterations"] / max(s["solves"], 1)
            lines.append(
                f"  CG: {mean:.1f} iterations/solve, last residual {s['last_residual']:.1e}, "
                f"{s['not_converged']} of {s['solves']} solves hit the iteration cap"
            )
        return "\n".join(lines)


def _as_scene(scene: Scene | Mapping[str, Any] | str | None) -> Scene:
    if scene is None:
        return Scene()
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, str):
        return load_scene(scene)
    if isinstance(scene, Mapping):
        return Scene.from_dict(scene)
    raise TypeError(
        f"scene must be a Scene, a dict or a built-in scene name, got {type(scene).__name__}"
    )


class Simulation(_core.Simulation):
    """A running cloth simulation.

    ``Simulation(scene)`` takes a :class:`Scene`, a scene dict, or the name of a built-in
    scene. The state is exposed as ``(N, 3)`` float32 numpy arrays, particle ``(i, j)`` at row
    ``j * nx + i``. Stepping releases the GIL and runs in parallel in Rust.

    >>> sim = Simulation("hanging")
    >>> sim.step(10)
    >>> sim.positions.shape
    (1024, 3)
    """

    def __new__(cls, scene: Scene | Mapping[str, Any] | str | None = None) -> Simulation:
        return super().__new__(cls, _as_scene(scene).to_dict())

    def __init__(self, scene: Scene | Mapping[str, Any] | str | None = None) -> None:
        # The Rust object was built in __new__; here only the stability check.
        limit = self.stable_dt()
        if limit is not None and self.dt > limit:
            warnings.warn(
                f"dt = {self.dt:g} s exceeds the estimated stability limit of {limit:.3g} s for "
                f"{self.integrator} with {self.substeps} substep(s); use a smaller dt, more "
                f"substeps, softer springs or implicit_euler",
                StabilityWarning,
                stacklevel=2,
            )

    def step(self, n: int = 1) -> None:
        """Advance exactly ``n`` steps of ``dt``.

        Raises :class:`~rustcloth.errors.SimulationDiverged` if a step goes wrong (a non-finite
        value, or a spring beyond the scene's ``watchdog.max_stretch``) and is not saved by a
        retry (``watchdog.on_trouble = "substep"``); the state from before that step is kept.
        """
        super().step(n)

    @property
    def scene(self) -> Scene:
        """The scene, with the run-time settings (integrator, substeps, dt) as they are now."""
        return Scene.from_dict(self.scene_dict())

    def energy(self) -> Energy:  # type: ignore[override]
        """Kinetic, gravitational potential and elastic energy, in J."""
        return Energy(*super().energy())

    def profile(self) -> Profile:  # type: ignore[override]
        """Wall time spent in each pass since the start or the last reset."""
        passes, steps, total = super().profile()
        return Profile(
            passes={name: PassTime(name, seconds, calls) for name, seconds, calls in passes},
            steps=steps,
            total_seconds=total,
            solver=self.solver_stats(),
        )

    def __repr__(self) -> str:
        return (
            f"<Simulation {self.nx}x{self.ny} {self.integrator} dt={self.dt:g} "
            f"t={self.time:.4f}s effects={self.effects}>"
        )

    def to_mesh(self) -> Any:
        """The current frame as a :class:`rustcloth.export.Mesh`: ``vertices`` ``(N, 3)``
        float32 in m (vertex ``p`` is particle ``p``; cut particles stay, used by no triangle),
        ``triangles`` ``(T, 3)`` uint32 (the live ones), ``normals`` ``(N, 3)`` float32 unit
        vectors and ``uvs`` ``(N, 2)`` float32, particle ``(i, j)`` at
        ``(i / (nx - 1), j / (ny - 1))``."""
        from .export import to_mesh

        return to_mesh(self)

    def export(self, path: Any) -> Any:
        """Write the current frame to ``path`` (a ``str`` or ``os.PathLike``) as ``.obj``,
        ``.ply`` or ``.glb`` (glTF binary), with normals and UVs, through trimesh
        (``pip install 'rustcloth[export]'``; ``ImportError`` naming the extra otherwise).
        ``ValueError`` for another suffix. Returns the ``pathlib.Path`` written. A whole run:
        :func:`rustcloth.export.recorder`."""
        from .export import export

        return export(self, path)
