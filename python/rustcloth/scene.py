"""Scenes: what a simulation simulates, as plain data.

A :class:`Scene` is built from keyword arguments, a dict or a TOML file with the same keys. The
Rust core owns the schema: it fills in defaults and validates every value, so a scene that
exists is a scene that runs. See the README for every key, its unit and default.
"""

from __future__ import annotations

import math
import os
import stat
import tomllib
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from . import _args, _core
from .errors import ParameterError, ParameterTypeError, StabilityWarning
from .meshes import mesh_arrays, resolve_paths, wants_file

if TYPE_CHECKING:
    from .settings import (
        ClothSettings,
        ColliderSettings,
        FloorSettings,
        IntegratorName,
        PreconditionerName,
        SelfCollisionSettings,
        SphereSettings,
        StrainLimitSettings,
        TearingSettings,
        WatchdogSettings,
        WindSettings,
    )


def _check_nesting(settings: Mapping[str, Any]) -> None:
    """Refuses lists and tables nested deeper than the core reads (``_core.MAX_NESTING``),
    naming the key, before anything recursive touches them: a list nested thousands deep
    would end Python's recursion (or the stack) on the way in. Walked with a stack of its own,
    so that the check itself cannot recurse."""
    pending: list[tuple[Any, str, int]] = [(v, str(k), 1) for k, v in settings.items()]
    while pending:
        value, name, depth = pending.pop()
        # An array's numbers lie `ndim` levels below it, known without reading them.
        deepest = depth + value.ndim if isinstance(value, np.ndarray) else depth
        if deepest > _core.MAX_NESTING:
            raise ParameterError(
                f"{name}: lists and tables nest at most {_core.MAX_NESTING} deep in a scene",
                name,
            )
        if isinstance(value, Mapping):
            pending.extend((v, f"{name}.{k}", depth + 1) for k, v in value.items())
        elif isinstance(value, list | tuple):
            pending.extend((v, f"{name}[{i}]", depth + 1) for i, v in enumerate(value))


def _copy(value: Any) -> Any:
    """A deep copy of scene data that shares its read-only arrays (the core's mesh vertices
    and triangles): nothing can change them, and a mesh of a million triangles would
    otherwise be copied on every ``to_dict``."""
    if isinstance(value, dict):
        return {key: _copy(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_copy(item) for item in value]
    if isinstance(value, np.ndarray):
        return value if not value.flags.writeable else value.copy()
    return value


def _equal(a: Any, b: Any) -> bool:
    """Equality of scene data whose values may be arrays (``==`` on arrays is elementwise)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def _plain(value: Any) -> Any:
    """numpy scalars and arrays as the types the core reads: Python numbers, lists, and arrays
    of real numbers as they are (the core reads those in one pass)."""
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, np.ndarray):
        return value if value.dtype.kind in "fiu" else value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value


class Scene:
    """A validated scene description.

    >>> scene = Scene(dt=0.002, cloth={"nx": 16, "ny": 16, "pins": ["top_edge"]})
    >>> scene.cloth["k_structural"]
    200.0

    Unknown keys, values of the wrong type and values out of range raise
    :class:`~rustcloth.errors.ParameterError` (a ``ValueError``) or
    :class:`~rustcloth.errors.ParameterTypeError` (a ``TypeError``) naming the key.
    """

    __slots__ = ("_data",)

    if TYPE_CHECKING:
        # The scene keys, as __getattr__ answers them (a deep copy each time); declared for
        # type checkers only, they are not attributes of the class.
        cloth: ClothSettings
        dt: float
        substeps: int
        integrator: IntegratorName
        gravity: list[float]
        air_drag: float
        floor: FloorSettings | None
        spheres: list[SphereSettings]
        colliders: list[ColliderSettings]
        watchdog: WatchdogSettings
        strain_limit: StrainLimitSettings | None
        self_collision: SelfCollisionSettings | None
        tearing: TearingSettings | None
        wind: WindSettings | None
        preconditioner: PreconditionerName
        cg_tolerance: float
        cg_max_iterations: int
        pd_iterations: int
        pd_tolerance: float
        pd_chebyshev_rho: float

    def __init__(self, **settings: Any) -> None:
        _check_nesting(settings)
        self._data: dict[str, Any] = _core.normalize_scene(_plain(resolve_paths(settings, None)))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scene:
        """A scene from a dict with the keys of the TOML schema."""
        if not isinstance(data, Mapping):
            raise ParameterTypeError(
                f"data: must be a mapping of scene keys, got {type(data).__name__}", "data"
            )
        return cls._from_dict(data, None)

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any], base: str | None) -> Scene:
        scene = cls.__new__(cls)
        _check_nesting(data)
        # Straight to the core, which names a non-string key (`cls(**data)` would raise
        # Python's own TypeError for it).
        scene._data = _core.normalize_scene(_plain(resolve_paths(dict(data), base)))
        return scene

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> Scene:
        """A scene from a TOML file. A mesh collider's ``path`` is taken from the file's
        folder."""
        _check_path(path, "path")
        return cls._from_toml_text(_read_text(path, "path"),
                                   os.path.dirname(os.path.abspath(path)))

    @classmethod
    def from_toml_str(cls, text: str) -> Scene:
        """A scene from TOML text (a mesh collider's ``path`` from the working directory)."""
        return cls._from_toml_text(text, None)

    @classmethod
    def _from_toml_text(cls, text: str, base: str | None) -> Scene:
        # Only a scene with a mesh file to read goes through Python's TOML reader; every other
        # one (and every malformed one) is parsed by the core, for the core's messages.
        try:
            # Not text at all goes to the core too, which names the parameter.
            table = tomllib.loads(text) if isinstance(text, str) else {}
        except (tomllib.TOMLDecodeError, RecursionError):
            # Python's reader recurses per level of nesting; the core's reader stops at its
            # own limit and says so.
            table = {}
        if wants_file(table):
            return cls._from_dict(table, base)
        scene = cls.__new__(cls)
        scene._data = _core.scene_from_toml(_args.text(text, "text"))
        return scene

    def with_mesh_collider(
        self,
        vertices: npt.ArrayLike | None = None,
        triangles: npt.ArrayLike | None = None,
        *,
        path: str | os.PathLike[str] | None = None,
        **keys: Any,
    ) -> Scene:
        """A copy with a mesh collider added after the others: ``vertices`` (``(N, 3)``, m, in
        the collider's frame) and ``triangles`` (``(M, 3)`` indices, counter-clockwise seen
        from outside), or ``path``, a mesh file read with trimesh (the ``export`` extra). The
        other ``keys`` are those of any collider (``center``, ``rotation``, ``friction``,
        ``thickness``, ``velocity``, ``angular_velocity``). A scene is a value, so this returns
        a new one. Errors name ``colliders[k].vertices``, ``colliders[k].triangles[t]``,
        ``colliders[k].path``, ... as the scene's own checks do.

        A closed mesh (every edge in two triangles) is a solid; an open one is a one-sided
        sheet that pushes towards the side its triangles face (docs/colliders.md)."""
        at = f"colliders[{len(self._data['colliders'])}]"
        if path is not None:
            if vertices is not None or triangles is not None:
                raise ParameterError(
                    f"{at}.path: give a file or vertices and triangles, not both", f"{at}.path"
                )
            vertices, triangles = mesh_arrays(path, f"{at}.path")
        elif vertices is None or triangles is None:
            missing = "vertices" if vertices is None else "triangles"
            raise ParameterError(
                f"{at}.{missing}: is required for a mesh collider (or give path)", f"{at}.{missing}"
            )
        collider = {**keys, "shape": "mesh", "vertices": _mesh_array(vertices, f"{at}.vertices"),
                    "triangles": _mesh_array(triangles, f"{at}.triangles")}
        data = self.to_dict()
        data["colliders"] = [*data["colliders"], collider]
        return Scene.from_dict(data)

    def with_cloth_mesh(
        self,
        vertices: npt.ArrayLike | None = None,
        triangles: npt.ArrayLike | None = None,
        uvs: npt.ArrayLike | None = None,
        *,
        path: str | os.PathLike[str] | None = None,
        pins: list[Any] | None = None,
        pin_group: str | list[str] | None = None,
        **keys: Any,
    ) -> Scene:
        """A copy whose cloth is the triangle mesh ``vertices`` (``(N, 3)``, m, where the cloth
        starts, at rest) and ``triangles`` (``(M, 3)`` indices, wound consistently), with
        optional per-vertex ``uvs`` (``(N, 2)``), or ``path``, a mesh file read with trimesh
        (the ``export`` extra; its texture coordinates come along). ``keys`` are the mesh's
        material: ``density`` (kg/m^2), ``stretch``, ``bend`` (N/m), ``damping`` (N s/m),
        ``membrane`` (``"springs"``, default, or ``"triangle"``), ``poisson`` (the
        triangle membrane's Poisson ratio, default 1/3), ``bending`` (``"springs"``, default,
        or ``"isometric"``, which holds a curvature alike at every resolution on a flat rest
        shape) and ``bend_modulus`` (N m, the isometric bending's, default 5e-5);
        ``pins`` are vertex indices and selections: ``{"box": [[x0, y0, z0], [x1, y1, z1]]}``,
        ``{"boundary": True}``, ``{"top": 0.001}`` (default none). ``pin_group`` (with
        ``path``) names the file's vertex groups (an OBJ file's ``g`` or ``o`` names, a glTF
        file's named parts; a list for several) whose vertices are pinned too. The grid's
        keys go back to their defaults. Errors name ``cloth.mesh.vertices[k]``,
        ``cloth.mesh.triangles[t]``, ... (docs/mesh_cloth.md)."""
        if path is not None:
            if vertices is not None or triangles is not None or uvs is not None:
                raise ParameterError(
                    "cloth.mesh.path: give a file or vertices and triangles, not both",
                    "cloth.mesh.path",
                )
            mesh = {**keys, "path": path}
        elif vertices is None or triangles is None:
            missing = "vertices" if vertices is None else "triangles"
            raise ParameterError(
                f"cloth.mesh.{missing}: is required for a mesh cloth (or give path)",
                f"cloth.mesh.{missing}",
            )
        else:
            mesh = {**keys, "vertices": _mesh_array(vertices, "cloth.mesh.vertices"),
                    "triangles": _mesh_array(triangles, "cloth.mesh.triangles")}
            if uvs is not None:
                mesh["uvs"] = _mesh_array(uvs, "cloth.mesh.uvs", columns=2)
        data = self.to_dict()
        data["cloth"] = {"mesh": mesh, "pins": [] if pins is None else pins}
        if pin_group is not None:
            data["cloth"]["pin_group"] = pin_group
        return Scene.from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        """Every key with its value (defaults included); ``Scene.from_dict`` round-trips it.
        A mesh collider's ``vertices`` and ``triangles`` are read-only numpy arrays (float64,
        int64), shared with the scene rather than copied."""
        return cast("dict[str, Any]", _copy(self._data))

    def to_toml(self) -> str:
        """The scene as a TOML document; ``Scene.from_toml_str`` round-trips it."""
        return _core.scene_to_toml(self._data)

    def replace(self, **changes: Any) -> Scene:
        """A copy with some keys changed. A dict given for ``cloth`` or ``floor`` is merged into
        the existing table, so ``scene.replace(cloth={"nx": 64})`` keeps the other cloth keys."""
        data = self.to_dict()
        for key, value in changes.items():
            current = data.get(key)
            if isinstance(value, Mapping) and isinstance(current, dict):
                current.update(value)
            else:
                data[key] = value
        return Scene.from_dict(data)

    def stability_report(self, warn: bool = True) -> StabilityReport:
        """How the scene's step compares with the largest stable step of each integrator.

        Estimated from the stiffest mode of the cloth, ``omega = sqrt(4 (k_structural + k_shear
        + k_bend) / m)`` (within 5 % of the assembled stiffness matrix's largest eigenvalue), and
        that mode's damping rate ``gamma``: undamped, symplectic Euler and Verlet need
        ``omega h < 2`` with ``h = dt / substeps``, RK4 ``omega h < 2 sqrt 2``, explicit Euler
        ``h < gamma / omega^2``, implicit Euler nothing; the damped conditions are in
        docs/stability.md. With ``warn``, a scene whose integrator is past its limit raises a
        :class:`~rustcloth.errors.StabilityWarning` as well.
        """
        limits, omega = _core.scene_stability(self._data)
        report = StabilityReport(
            integrator=self._data["integrator"],
            dt=self._data["dt"],
            substeps=self._data["substeps"],
            omega=omega,
            stable_dt=dict(limits),
        )
        if warn and not report.stable:
            warnings.warn(str(report), StabilityWarning, stacklevel=2)
        return report

    def __getattr__(self, name: str) -> Any:
        # Only scene keys: private and special names are looked up (and missing) as usual.
        # Answering them from `_data` recursed while `_data` itself was unset, as it is while
        # pickle and copy rebuild a Scene.
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return _copy(self._data[name])
        except KeyError:
            raise AttributeError(f"Scene has no key {name!r}") from None

    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]:
        # Rebuilt through validation, so a pickle from another version is checked, not trusted.
        return (Scene.from_dict, (self.to_dict(),))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and _equal(self._data, other._data)

    def __hash__(self) -> int:
        return hash(self.to_toml())

    def __repr__(self) -> str:
        cloth = self._data["cloth"]
        extras = []
        if self._data["floor"] is not None:
            extras.append("floor")
        if self._data["spheres"]:
            extras.append(f"{len(self._data['spheres'])} sphere(s)")
        if self._data["colliders"]:
            extras.append(f"{len(self._data['colliders'])} collider(s)")
        return (
            f"Scene({cloth['nx']}x{cloth['ny']} cloth, {self._data['integrator']}, "
            f"dt={self._data['dt']:g}" + "".join(f", {e}" for e in extras) + ")"
        )


@dataclass(frozen=True)
class StabilityReport:
    """The result of :meth:`Scene.stability_report`. ``stable_dt`` maps each integrator to the
    largest stable ``dt`` (s) with the scene's substeps, or None where any ``dt`` is."""

    integrator: str
    dt: float
    substeps: int
    #: Angular frequency of the stiffest mode, rad/s.
    omega: float
    stable_dt: dict[str, float | None]

    @property
    def limit(self) -> float | None:
        """The largest stable ``dt`` of the scene's own integrator."""
        return self.stable_dt[self.integrator]

    @property
    def stable(self) -> bool:
        return self.limit is None or self.dt <= self.limit

    def substeps_needed(self, integrator: str | None = None) -> int | None:
        """Fewest substeps at which ``integrator`` (default: the scene's) is stable at the
        scene's ``dt``; None if it never is (explicit Euler without damping) or always is."""
        limit = self.stable_dt[integrator or self.integrator]
        if limit is None:
            return None
        per_substep = limit / self.substeps
        if per_substep <= 0.0:
            return None
        return max(1, math.ceil(self.dt / per_substep))

    def __str__(self) -> str:
        lines = [
            f"dt = {self.dt:g} s with {self.substeps} substep(s); stiffest mode "
            f"omega = {self.omega:.4g} rad/s"
        ]
        width = max(map(len, self.stable_dt), default=0)
        for name, limit in self.stable_dt.items():
            mark = "*" if name == self.integrator else " "
            if limit is None:
                # No limit: an implicit solver, or no spring to be stiff (omega = 0).
                verdict = "no springs" if self.omega == 0 else "stable at any dt"
            elif limit == 0.0:
                verdict = "never stable (no damping)"
            else:
                needed = self.substeps_needed(name)
                ok = "ok" if self.dt <= limit else f"UNSTABLE, needs {needed} substeps"
                verdict = f"stable up to dt = {limit:.3g} s: {ok}"
            lines.append(f"{mark} {name:{width}s} {verdict}")
        return "\n".join(lines)


def _mesh_array(values: npt.ArrayLike, parameter: str, columns: int = 3) -> np.ndarray:
    """An ``(n, columns)`` array of numbers, as given (the core reads it in one pass and keeps
    its own copy); a wrong shape or a non-number is named here, before the core's
    element-by-element checks."""
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as err:
        raise ParameterTypeError(
            f"{parameter}: must be an (n, {columns}) array: {err}", parameter
        ) from err
    if array.dtype.kind not in "fiu":
        raise ParameterTypeError(
            f"{parameter}: must be an (n, {columns}) array of numbers, got dtype {array.dtype}",
            parameter,
        )
    if array.ndim != 2 or array.shape[1] != columns:
        raise ParameterError(
            f"{parameter}: must have shape (n, {columns}), got {array.shape}", parameter
        )
    return array


def scenes() -> list[str]:
    """Names of the built-in scenes."""
    return list(_core.builtin_scenes())


def _check_path(path: object, parameter: str) -> None:
    """A path is a ``str`` or ``os.PathLike``: an int would be opened as a file descriptor."""
    if not isinstance(path, str | os.PathLike):
        raise ParameterTypeError(
            f"{parameter}: must be a str or os.PathLike, got {type(path).__name__} {path!r}",
            parameter,
        )


def _read_text(path: str | os.PathLike[str], parameter: str) -> str:
    """The UTF-8 text of the regular file ``path``. An error names ``parameter``: an
    ``OSError`` of the same kind for a file that cannot be opened, a ``ParameterError`` for one
    that is not a regular file (a folder; a device such as /dev/zero would be read for ever)
    or not UTF-8."""
    name = os.fspath(path)
    try:
        with open(path, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                raise ParameterError(f"{parameter}: {name!r} is not a regular file", parameter)
            data = f.read()
    except OSError as err:
        if isinstance(err, IsADirectoryError):
            raise ParameterError(f"{parameter}: {name!r} is a folder, not a file",
                                 parameter) from None
        raise type(err)(err.errno, f"{parameter}: {err.strerror}", name) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ParameterError(
            f"{parameter}: {name!r} is not UTF-8 text (byte {err.start}: {err.reason})", parameter
        ) from None


def load_scene(name: str | os.PathLike[str]) -> Scene:
    """The built-in scene ``name`` (see :func:`scenes`), or the scene in a TOML file: a path
    that ends in ``.toml`` or names an existing file."""
    _check_path(name, "name")
    if isinstance(name, os.PathLike) or str(name).endswith(".toml") or os.path.isfile(name):
        return Scene.from_toml(name)
    return Scene.from_dict(_core.builtin_scene(name))
