"""Types of a scene's settings as :class:`rustcloth.Scene` answers them (``scene.cloth``,
``scene.floor``, ...; the keys of the scene TOML, README.md), and the names of the integrators.

These are for type checkers: at run time each is a plain ``dict``, ``list`` or ``str``.

>>> import rustcloth
>>> cloth: ClothSettings = rustcloth.load_scene("hanging").cloth
>>> cloth["nx"], cloth["plane"]
(32, 'xz')
"""

from __future__ import annotations

from typing import Any, Literal, NotRequired, TypeAlias, TypedDict

IntegratorName: TypeAlias = Literal[
    "explicit_euler",
    "symplectic_euler",
    "verlet",
    "rk4",
    "implicit_euler",
    "projective_dynamics",
]
"""The names of the time integrators, in the order of ``rustcloth.INTEGRATORS`` (the compiled
module's list; tests/test_typing.py checks that the two agree)."""

PreconditionerName: TypeAlias = Literal["jacobi", "block_jacobi", "multigrid"]
"""The preconditioners of ``implicit_euler``'s conjugate gradient."""

Pin: TypeAlias = (
    str | list[int] | int | dict[str, list[list[float]]] | dict[str, bool] | dict[str, float]
)
"""A named set of particles (``"top_corners"``, ``"top_edge"``, ...) or one ``[i, j]`` (the
grid's), one particle index (a mesh cloth's vertex), or a selection on either cloth:
``{"box": [[x0, y0, z0], [x1, y1, z1]]}`` (every particle that starts inside the box),
``{"boundary": True}`` (the outline and the rims of holes) or ``{"top": 0.001}`` (the particles
within 1 mm of the highest)."""


class SeamsSettings(TypedDict):
    """``scene.cloth["mesh"]["seams"]``: vertex pairs sewn together, as a garment compiles
    to (docs/garments.md)."""

    pairs: list[list[int]]
    sew_time: float
    stiffness: float
    damping: float


class MeshSettings(TypedDict):
    """``scene.cloth["mesh"]``: a cloth from a triangle mesh (docs/mesh_cloth.md)."""

    vertices: Any
    triangles: Any
    uvs: NotRequired[Any]
    density: float
    stretch: float
    bend: float
    damping: float
    membrane: Literal["springs", "triangle"]
    poisson: float
    bending: Literal["springs", "isometric"]
    bend_modulus: float
    seams: NotRequired[SeamsSettings]
    panels: NotRequired[PanelsSettings]


class PanelsSettings(TypedDict):
    """``scene.cloth["mesh"]["panels"]``: each triangle of a garment on its flat panel, as a
    garment compiles to (its panel's index and its three corners there, m): what a live cut
    holds its stroke on (docs/cutting.md)."""

    panel: list[int]
    corners: list[list[list[float]]]


class CutSettings(TypedDict):
    """One of ``scene.cloth["cuts"]``: a polyline (m) severed as the cloth is built, whole or
    in ``dash`` = ``[cut, gap]`` (m)."""

    points: list[list[float]]
    dash: NotRequired[list[float]]


class ClothSettings(TypedDict):
    """``scene.cloth``: the grid, its placement, mass and springs."""

    nx: int
    ny: int
    size: list[float]
    center: list[float]
    plane: Literal["xz", "xy"]
    particle_mass: float
    k_structural: float
    k_shear: float
    k_bend: float
    damping: float
    pins: list[Pin]
    cuts: list[CutSettings]
    mesh: NotRequired[MeshSettings]


class FloorSettings(TypedDict):
    """``scene.floor`` (None: no floor)."""

    height: float
    friction: float
    thickness: float


class SphereSettings(TypedDict):
    """One of ``scene.spheres``."""

    center: list[float]
    radius: float
    friction: float
    thickness: float


class WatchdogSettings(TypedDict):
    """``scene.watchdog``: what a step does when it goes wrong (docs/stability.md)."""

    max_stretch: float | None
    on_trouble: Literal["raise", "substep"]
    max_substeps: int
    hold_steps: int


class StrainLimitSettings(TypedDict):
    """``scene.strain_limit`` (None: no pass)."""

    max_strain: float
    iterations: int


class SelfCollisionSettings(TypedDict):
    """``scene.self_collision`` (None: no pass)."""

    thickness: float
    friction: float
    iterations: int
    solve_stiffness: float


class TearingSettings(TypedDict):
    """``scene.tearing`` (None: no pass)."""

    max_strain: float
    max_per_step: int


class WindSettings(TypedDict):
    """``scene.wind`` (None: no pass): air in m/s with gusts and turbulence (src/wind.rs)."""

    velocity: list[float]
    gust: float
    gust_period: float
    turbulence: float
    turbulence_scale: float
    seed: int
    drag: float
    lift: float
    air_density: float


ColliderSettings: TypeAlias = dict[str, Any]
"""One of ``scene.colliders``: ``shape`` and the keys of that shape (docs/colliders.md)."""
