"""rustcloth's cloth model in a page of numpy, written from the README's formulas and not from
the Rust code: the truth the fast solver is tested against (``tests/``), the numpy peer it is
timed against (``benches/bench_numpy.py``) and the float64 reference of the accuracy study
(:mod:`rustcloth.study`). Clarity first; no step here is the fast solver's algorithm.

The model:

* an ``nx`` x ``ny`` grid of particles, particle ``(i, j)`` at row ``j * nx + i``, laid out over
  the scene's ``size`` in its ``plane`` around its ``center``, each of mass ``particle_mass``
  (or ``mass / (nx ny)``, 1 g if neither is given). A pinned particle has inverse mass 0 and
  starts at rest, so that no force and no integrator moves it.
* springs from every particle to its 12 neighbours: structural ``(i + 1, j)``, ``(i, j + 1)``;
  shear ``(i + 1, j + 1)``, ``(i - 1, j + 1)``; bend ``(i + 2, j)``, ``(i, j + 2)``. A family of
  stiffness 0 is absent. Rest lengths are the starting distances.
* the force on ``a`` from spring ``(a, b)`` is ``k (l - L) u + c ((v_b - v_a) . u) u``, with
  ``l = |x_b - x_a|`` and ``u = (x_b - x_a) / l`` (no force when ``l = 0``), and its opposite on
  ``b``; every particle also feels gravity ``m g`` and air drag ``-air_drag v``.
* :meth:`ReferenceCloth.step` advances ``dt`` in ``substeps`` substeps of the scene's
  integrator, each written as its formula; :meth:`ReferenceCloth.integrate` advances any time
  with adaptive Dormand-Prince 5(4), which none of rustcloth's integrators is.

Floors, spheres, colliders, self-collision, tearing and strain limiting are not modelled: a
scene with any of them is refused.

The state is kept as grids ``x[c, j, i]`` (component ``c``), so that the springs of one
direction are one pair of grid slices and the forces are a few whole-array operations per
direction: in float32 this is the benchmark's vectorised numpy cloth. The two implicit
integrators solve dense systems, for small cloths only.

>>> import rustcloth
>>> scene = rustcloth.Scene(cloth={"nx": 4, "ny": 3}).to_dict()
>>> cloth = ReferenceCloth(scene)
>>> cloth.step(10)
>>> cloth.positions.shape, bool(cloth.positions[:, 1].min() < 1.0)
((12, 3), True)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import numpy.typing as npt

__all__ = ["PIN_GROUPS", "ReferenceCloth", "pin_indices"]

Array = npt.NDArray[Any]
GridIndex = tuple[slice, slice, slice]

#: Named pin groups, as in rustcloth's scenes: ``(nx, ny) -> [(i, j), ...]``; "top" is
#: ``j = ny - 1``.
PIN_GROUPS: dict[str, Callable[[int, int], list[tuple[int, int]]]] = {
    "top_corners": lambda nx, ny: [(0, ny - 1), (nx - 1, ny - 1)],
    "bottom_corners": lambda nx, ny: [(0, 0), (nx - 1, 0)],
    "corners": lambda nx, ny: [(0, 0), (nx - 1, 0), (0, ny - 1), (nx - 1, ny - 1)],
    "top_edge": lambda nx, ny: [(i, ny - 1) for i in range(nx)],
    "bottom_edge": lambda nx, ny: [(i, 0) for i in range(nx)],
    "left_edge": lambda nx, ny: [(0, j) for j in range(ny)],
    "right_edge": lambda nx, ny: [(nx - 1, j) for j in range(ny)],
    "center": lambda nx, ny: [(nx // 2, ny // 2)],
}

# The 6 spring directions (di, dj) from end a to end b, and the stiffness each family takes.
DIRECTIONS = (
    ((1, 0), "k_structural"),
    ((0, 1), "k_structural"),
    ((1, 1), "k_shear"),
    ((-1, 1), "k_shear"),
    ((2, 0), "k_bend"),
    ((0, 2), "k_bend"),
)

#: A particle's mass in kg where the scene gives neither ``particle_mass`` nor ``mass``, as in
#: rustcloth's scenes.
DEFAULT_PARTICLE_MASS = 1e-3

# Scene keys of effects the model leaves out; a scene that sets any is refused.
UNMODELLED = ("floor", "spheres", "colliders", "self_collision", "tearing", "strain_limit")

# Dormand-Prince 5(4): the stage coefficients and the two weight rows (5th order, 4th order).
_DP_A = [
    [],
    [1 / 5],
    [3 / 40, 9 / 40],
    [44 / 45, -56 / 15, 32 / 9],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
]
_DP_B5 = [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0]
_DP_B4 = [5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40]


def pin_indices(pins: Iterable[Any], nx: int, ny: int) -> list[int]:
    """Particle indices ``j * nx + i``, sorted, of pin group names and ``[i, j]`` pairs."""
    cells: list[tuple[int, int]] = []
    for pin in pins:
        if isinstance(pin, str):
            if pin not in PIN_GROUPS:
                raise ValueError(f"unknown pin group {pin!r}; known: {sorted(PIN_GROUPS)}")
            cells.extend(PIN_GROUPS[pin](nx, ny))
        else:
            i, j = pin
            cells.append((int(i), int(j)))
    for i, j in cells:
        if not (0 <= i < nx and 0 <= j < ny):
            raise ValueError(f"pin {[i, j]} outside the {nx} x {ny} cloth")
    return sorted({j * nx + i for i, j in cells})


@dataclass(frozen=True)
class Springs:
    """The springs of one direction: end ``a`` of each at grid slice ``a``, end ``b`` at ``b``."""

    a: GridIndex
    b: GridIndex
    k: np.floating[Any]
    rest: Array
    """Rest lengths, one per spring, shaped like the slices."""


def _ends(di: int, dj: int, nx: int, ny: int) -> tuple[GridIndex, GridIndex]:
    """Grid slices ``[c, j, i]`` of the a ends and the b ends of the springs (di, dj)."""
    all_components = slice(None)
    rows_a, rows_b = slice(0, ny - dj), slice(dj, ny)
    if di >= 0:
        cols_a, cols_b = slice(0, nx - di), slice(di, nx)
    else:
        cols_a, cols_b = slice(-di, nx), slice(0, nx + di)
    return (all_components, rows_a, cols_a), (all_components, rows_b, cols_b)


class ReferenceCloth:
    """The cloth of ``scene`` (a scene dict, :meth:`rustcloth.Scene.to_dict`), in ``dtype``.

    It starts from the scene's grid at rest, or from ``positions`` and ``velocities``
    (``(N, 3)``, e.g. a simulation's, so that both start from the same numbers), with
    ``masses`` ``(N,)`` in kg if given. Rest lengths are taken from ``rest`` (``(N, 3)``,
    default: the starting positions)."""

    def __init__(self, scene: Mapping[str, Any], *, dtype: npt.DTypeLike = np.float64,
                 positions: npt.ArrayLike | None = None,
                 velocities: npt.ArrayLike | None = None,
                 masses: npt.ArrayLike | None = None,
                 rest: npt.ArrayLike | None = None) -> None:
        for key in UNMODELLED:
            if scene.get(key):
                raise ValueError(f"the scene sets {key}, which the reference model leaves out")
        cloth = scene["cloth"]
        self.nx, self.ny = nx, ny = int(cloth["nx"]), int(cloth["ny"])
        self.dtype = np.dtype(dtype)
        self.integrator: str = scene["integrator"]
        self.substeps = int(scene["substeps"])
        self.h = self._scalar(scene["dt"] / self.substeps)

        if masses is None:
            m = cloth.get("particle_mass")
            if m is None:
                total = cloth.get("mass")
                m = DEFAULT_PARTICLE_MASS if total is None else total / (nx * ny)
            masses = np.full(nx * ny, m)
        self.mass = np.asarray(masses, self.dtype).reshape(ny, nx)
        self.pinned = np.zeros(nx * ny, bool)
        self.pinned[pin_indices(cloth["pins"], nx, ny)] = True
        self.inv_mass = np.where(self.pinned.reshape(ny, nx), 0.0, 1.0 / self.mass)
        self.inv_mass = self.inv_mass.astype(self.dtype)

        self._x = self._grid(_grid_layout(cloth) if positions is None else positions)
        self.set_velocities(np.zeros((nx * ny, 3)) if velocities is None else velocities)
        self.gravity = np.asarray(scene["gravity"], self.dtype)
        self.air_drag = self._scalar(scene["air_drag"])
        self.damping = self._scalar(cloth["damping"])

        shape = self._x if rest is None else self._grid(rest)
        self.springs: list[Springs] = []
        for (di, dj), family in DIRECTIONS:
            if cloth[family] == 0 or abs(di) >= nx or dj >= ny:
                continue
            a, b = _ends(di, dj, nx, ny)
            d = shape[b] - shape[a]
            self.springs.append(Springs(a, b, self._scalar(cloth[family]),
                                        np.sqrt((d * d).sum(axis=0))))
        self._verlet_started = False

    # -- state, as (N, 3) rows like rustcloth.Simulation's --------------------------------------

    @property
    def positions(self) -> Array:
        """``(N, 3)`` positions in m, particle ``(i, j)`` at row ``j * nx + i`` (a copy)."""
        return self._rows(self._x)

    @property
    def velocities(self) -> Array:
        """``(N, 3)`` velocities in m/s (a copy)."""
        return self._rows(self._v)

    def set_positions(self, positions: npt.ArrayLike) -> None:
        self._x = self._grid(positions)

    def set_velocities(self, velocities: npt.ArrayLike) -> None:
        """Set the velocities; a pinned particle's stays 0."""
        rows = np.array(velocities, dtype=self.dtype).reshape(-1, 3)
        rows[self.pinned] = 0.0
        self._v = self._grid(rows)

    def _scalar(self, value: float) -> np.floating[Any]:
        return cast(np.floating[Any], self.dtype.type(value))  # type: ignore[call-overload]

    def _grid(self, rows: npt.ArrayLike) -> Array:
        """``(N, 3)`` rows as a ``(3, ny, nx)`` grid of this cloth's dtype."""
        flat = np.asarray(rows, self.dtype).reshape(-1, 3)
        return np.ascontiguousarray(flat.T.reshape(3, self.ny, self.nx))

    @staticmethod
    def _rows(grid: Array) -> Array:
        return np.ascontiguousarray(grid.reshape(3, -1).T)

    # -- the model -----------------------------------------------------------------------------

    def forces(self, x: Array, v: Array) -> Array:
        """Force on every particle (N), grids ``[c, j, i]``: springs, gravity, air drag."""
        f: Array = self.mass * self.gravity[:, None, None] - self.air_drag * v
        for s in self.springs:
            d = x[s.b] - x[s.a]
            length = np.sqrt((d * d).sum(axis=0))
            u = np.divide(d, length, out=np.zeros_like(d), where=length > 0)
            closing = ((v[s.b] - v[s.a]) * u).sum(axis=0)
            pull = (s.k * (length - s.rest) + self.damping * closing) * u
            f[s.a] += pull
            f[s.b] -= pull
        return f

    def force_rows(self, positions: npt.ArrayLike, velocities: npt.ArrayLike) -> Array:
        """:meth:`forces` at ``(N, 3)`` positions and velocities, as ``(N, 3)`` rows."""
        return self._rows(self.forces(self._grid(positions), self._grid(velocities)))

    def acceleration(self, x: Array, v: Array) -> Array:
        """``f / m``, 0 for pinned particles."""
        return self.forces(x, v) * self.inv_mass

    # -- the integrators -----------------------------------------------------------------------

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``, each ``substeps`` substeps of the scene's integrator."""
        h = self.h
        for _ in range(n * self.substeps):
            x0, v0 = self._x, self._v
            if self.integrator == "symplectic_euler":
                v = v0 + h * self.acceleration(x0, v0)
                x = x0 + h * v
            elif self.integrator == "explicit_euler":
                x = x0 + h * v0
                v = v0 + h * self.acceleration(x0, v0)
            elif self.integrator == "verlet":
                # Stoermer: x1 = 2 x0 - x_prev + h^2 a, v1 = (x1 - x0) / h, with the Taylor
                # start x_prev = x0 - h v0 + h^2 a / 2 on the first step.
                a = self.acceleration(x0, v0)
                x_prev = x0 - h * v0 + (0.0 if self._verlet_started else 0.5 * h * h * a)
                self._verlet_started = True
                x = 2 * x0 - x_prev + h * h * a
                v = (x - x0) / h
            elif self.integrator == "rk4":
                k1x, k1v = v0, self.acceleration(x0, v0)
                k2x, k2v = v0 + h / 2 * k1v, self.acceleration(x0 + h / 2 * k1x, v0 + h / 2 * k1v)
                k3x, k3v = v0 + h / 2 * k2v, self.acceleration(x0 + h / 2 * k2x, v0 + h / 2 * k2v)
                k4x, k4v = v0 + h * k3v, self.acceleration(x0 + h * k3x, v0 + h * k3v)
                x = x0 + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v0 + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            elif self.integrator == "implicit_euler":
                v = v0 + self._grid(self._implicit_dv(self._rows(x0), self._rows(v0)))
                x = x0 + h * v
            elif self.integrator == "projective_dynamics":
                x = self._grid(self._backward_euler(self._rows(x0), self._rows(v0)))
                v = (x - x0) / h
            else:
                raise ValueError(f"the reference model has no integrator {self.integrator!r}")
            self._x, self._v = x, v

    def integrate(self, seconds: float, tolerance: float = 1e-11) -> None:
        """Advance ``seconds`` by adaptive Dormand-Prince 5(4), whatever the scene's integrator
        and ``dt``, keeping each step's local error below ``tolerance`` (m, and m/s times the
        step)."""
        t, h = 0.0, 1e-4
        x, v = self._x, self._v
        while t < seconds:
            h = min(h, seconds - t)
            kx: list[Array] = []
            kv: list[Array] = []
            for weights in _DP_A:
                xs, vs = x.copy(), v.copy()
                for weight, dx, dv in zip(weights, kx, kv, strict=False):
                    xs += h * weight * dx
                    vs += h * weight * dv
                kx.append(vs)
                kv.append(self.acceleration(xs, vs))
            x5 = x + h * sum(w * k for w, k in zip(_DP_B5, kx, strict=True))
            v5 = v + h * sum(w * k for w, k in zip(_DP_B5, kv, strict=True))
            x4 = x + h * sum(w * k for w, k in zip(_DP_B4, kx, strict=True))
            v4 = v + h * sum(w * k for w, k in zip(_DP_B4, kv, strict=True))
            error = max(np.abs(x5 - x4).max(), h * np.abs(v5 - v4).max())
            if error <= tolerance or h < 1e-9:
                t += h
                x, v = x5, v5
            h *= min(4.0, max(0.2, 0.9 * (tolerance / max(error, 1e-300)) ** 0.2))
        self._x, self._v = x, v

    # -- dense linear algebra for the implicit integrators, on (N, 3) rows ----------------------

    def _spring_list(self) -> Iterable[tuple[int, int, float, float]]:
        """Every spring as ``(a, b, k, rest)``, particle indices ``j * nx + i``."""
        index = np.arange(self.nx * self.ny)[None].repeat(3, 0).reshape(3, self.ny, self.nx)
        for s in self.springs:
            yield from zip(index[s.a][0].ravel(), index[s.b][0].ravel(),
                           np.full(s.rest.size, float(s.k)), s.rest.ravel(), strict=True)

    def _implicit_dv(self, x: Array, v: Array) -> Array:
        """Linearised backward Euler: solve ``(M - h df/dv - h^2 df/dx) dv = h (f + h df/dx
        v)`` densely, pinned particles removed, with the compressed-spring fix
        ``g = max(0, 1 - L / l)``."""
        n, h = len(x), float(self.h)
        stiffness = np.zeros((3 * n, 3 * n))  # -df/dx
        damping = np.zeros((3 * n, 3 * n))  # -df/dv
        eye = np.eye(3)
        for a, b, k, rest in self._spring_list():
            d = x[b] - x[a]
            length = np.linalg.norm(d)
            u = d / length if length > 0 else np.zeros(3)
            g = max(0.0, 1.0 - rest / float(length)) if length > 0 else 0.0
            blocks = ((stiffness, k * ((1 - g) * np.outer(u, u) + g * eye)),
                      (damping, float(self.damping) * np.outer(u, u)))
            for matrix, block in blocks:
                for p, q, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
                    matrix[3 * p:3 * p + 3, 3 * q:3 * q + 3] += sign * block
        damping += float(self.air_drag) * np.eye(3 * n)
        mass = np.repeat(self.mass.ravel(), 3)
        matrix = np.diag(mass) + h * damping + h * h * stiffness
        rhs = h * (self.force_rows(x, v).ravel() - h * stiffness @ v.ravel())
        free = np.repeat(~self.pinned, 3)
        dv = np.zeros(3 * n)
        dv[free] = np.linalg.solve(matrix[np.ix_(free, free)], rhs[free])
        return dv.reshape(n, 3)

    def _backward_euler(self, x0: Array, v0: Array) -> Array:
        """The exact (not linearised) backward-Euler step, which projective dynamics converges
        to: the x with ``M (x - x0 - h v0) / h^2 = f(x, (x - x0) / h)``, found by Newton's
        method on a dense Jacobian, pinned particles held."""
        n, h = len(x0), float(self.h)
        free = np.repeat(~self.pinned, 3)
        mass = np.repeat(self.mass.ravel(), 3)
        eye = np.eye(3)
        x = x0 + h * v0
        for _ in range(50):
            v = (x - x0) / h
            residual = mass * (x - x0 - h * v0).ravel() / h**2 - self.force_rows(x, v).ravel()
            if np.abs(residual[free]).max() < 1e-12 * max(1.0, np.abs(mass).max() / h**2):
                break
            # -df/dx (exact, compressed springs included) and -df/dv.
            jacobian = np.diag(mass / h**2) + np.eye(3 * n) * float(self.air_drag) / h
            for a, b, k, rest in self._spring_list():
                d = x[b] - x[a]
                length = np.linalg.norm(d)
                if length == 0:
                    continue
                u = d / length
                block = k * (np.outer(u, u) + (1 - rest / length) * (eye - np.outer(u, u)))
                block += float(self.damping) / h * np.outer(u, u)
                for p, q, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
                    jacobian[3 * p:3 * p + 3, 3 * q:3 * q + 3] += sign * block
            step = np.zeros(3 * n)
            step[free] = np.linalg.solve(jacobian[np.ix_(free, free)], -residual[free])
            x = x + step.reshape(n, 3)
        return x


def _grid_layout(cloth: Mapping[str, Any]) -> Array:
    """``(N, 3)`` starting positions of the scene's cloth, in float64."""
    nx, ny = int(cloth["nx"]), int(cloth["ny"])
    e1 = np.array([1.0, 0.0, 0.0])
    e2 = np.array([0.0, 0.0, 1.0]) if cloth["plane"] == "xz" else np.array([0.0, 1.0, 0.0])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))  # j-major: row j holds i = 0..nx-1
    u = (i.ravel() / (nx - 1) - 0.5) * cloth["size"][0]
    w = (j.ravel() / (ny - 1) - 0.5) * cloth["size"][1]
    result: Array = np.asarray(cloth["center"], float) + u[:, None] * e1 + w[:, None] * e2
    return result
