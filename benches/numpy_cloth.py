"""A vectorised numpy implementation of rustcloth's mass-spring model, for the benchmarks.

The cloth is an ``nx`` x ``ny`` grid; particle ``(i, j)`` is row ``j * nx + i`` of
:attr:`NumpyCloth.positions`. Internally the state is stored as structure-of-arrays grids,
``x[c, j, i]`` (component ``c``), so that every spring family is one pair of grid slices and
every operation is a plain elementwise numpy call on 2-D float32 arrays: no Python loop over
particles or springs, only over the (up to) 6 spring directions.

Model (the README's):

* springs: structural ``(i,j)-(i+1,j)``, ``(i,j)-(i,j+1)``; shear ``(i,j)-(i+1,j+1)``,
  ``(i+1,j)-(i,j+1)``; bend ``(i,j)-(i+2,j)``, ``(i,j)-(i,j+2)``. A family with ``k = 0`` is
  absent (no damping either). Rest lengths are the initial distances.
* force on ``a`` from spring ``(a, b)``: ``k (l - L) u + c ((v_b - v_a) . u) u`` with
  ``l = |x_b - x_a|``, ``u = (x_b - x_a) / l`` (no force when ``l = 0``), opposite on ``b``;
  plus gravity ``m g`` and air drag ``-air_drag v``.
* symplectic Euler, ``v += h f / m; x += h v``, ``h = dt / substeps``; pinned particles have
  inverse mass 0 and never move.

Floors, spheres and the other integrators are not modelled (``from_scene`` refuses them).

Run ``python benches/numpy_cloth.py`` for the self-check.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["NumpyCloth", "pin_indices", "self_check"]

# Named pin groups, as in rustcloth's scenes: (nx, ny) -> list of (i, j). "top" is j = ny - 1.
PIN_GROUPS = {
    "top_corners": lambda nx, ny: [(0, ny - 1), (nx - 1, ny - 1)],
    "bottom_corners": lambda nx, ny: [(0, 0), (nx - 1, 0)],
    "corners": lambda nx, ny: [(0, 0), (nx - 1, 0), (0, ny - 1), (nx - 1, ny - 1)],
    "top_edge": lambda nx, ny: [(i, ny - 1) for i in range(nx)],
    "bottom_edge": lambda nx, ny: [(i, 0) for i in range(nx)],
    "left_edge": lambda nx, ny: [(0, j) for j in range(ny)],
    "right_edge": lambda nx, ny: [(nx - 1, j) for j in range(ny)],
}

# The 6 spring directions (di, dj) from end a to end b, with the family each belongs to.
DIRECTIONS = (
    ((1, 0), "structural"),
    ((0, 1), "structural"),
    ((1, 1), "shear"),
    ((-1, 1), "shear"),
    ((2, 0), "bend"),
    ((0, 2), "bend"),
)


def pin_indices(pins: Iterable[Any], nx: int, ny: int) -> list[int]:
    """Particle indices ``j * nx + i`` for pin names and ``[i, j]`` pairs (or plain indices)."""
    out: list[int] = []
    for pin in pins:
        if isinstance(pin, str):
            if pin not in PIN_GROUPS:
                raise ValueError(f"unknown pin group {pin!r}; known: {sorted(PIN_GROUPS)}")
            out.extend(j * nx + i for i, j in PIN_GROUPS[pin](nx, ny))
        elif isinstance(pin, int | np.integer):
            out.append(int(pin))
        else:
            i, j = pin
            out.append(int(j) * nx + int(i))
    for p in out:
        if not 0 <= p < nx * ny:
            raise ValueError(f"pin {p} outside the {nx} x {ny} cloth")
    return sorted(set(out))


def _slices(di: int, dj: int, nx: int, ny: int) -> tuple[tuple[slice, slice], tuple[slice, slice]]:
    """Grid slices ``[j, i]`` of the a ends and the b ends of the springs in direction (di, dj)."""
    rows_a, rows_b = slice(0, ny - dj), slice(dj, ny)
    if di >= 0:
        cols_a, cols_b = slice(0, nx - di), slice(di, nx)
    else:
        cols_a, cols_b = slice(-di, nx), slice(0, nx + di)
    return (rows_a, cols_a), (rows_b, cols_b)


class NumpyCloth:
    """rustcloth's cloth model, vectorised with numpy grid slicing, float32 state."""

    def __init__(
        self,
        nx: int,
        ny: int,
        spacing: float | None = None,
        size: Sequence[float] | None = None,
        center: Sequence[float] = (0.0, 0.0, 0.0),
        plane: str = "xy",
        particle_mass: float = 1e-3,
        k_structural: float = 50.0,
        k_shear: float = 50.0,
        k_bend: float = 50.0,
        damping: float = 0.01,
        gravity: Sequence[float] = (0.0, -9.81, 0.0),
        air_drag: float = 0.0,
        pins: Iterable[Any] = (),
        dt: float = 1e-3,
        substeps: int = 1,
    ) -> None:
        if nx < 2 or ny < 2:
            raise ValueError("the cloth needs at least 2 x 2 particles")
        if (spacing is None) == (size is None):
            raise ValueError("give exactly one of spacing and size")
        if size is None:
            size = (spacing * (nx - 1), spacing * (ny - 1))
        if plane not in ("xz", "xy"):
            raise ValueError(f"plane must be 'xz' or 'xy', got {plane!r}")
        self.nx, self.ny = int(nx), int(ny)
        self.dt, self.substeps = float(dt), int(substeps)
        self.h = np.float32(self.dt / self.substeps)
        f32 = np.float32

        # Initial positions, computed in float64 then stored as float32 grids x[c, j, i].
        e1 = np.array([1.0, 0.0, 0.0])
        e2 = np.array([0.0, 0.0, 1.0]) if plane == "xz" else np.array([0.0, 1.0, 0.0])
        u = (np.arange(nx) / (nx - 1) - 0.5) * size[0]
        w = (np.arange(ny) / (ny - 1) - 0.5) * size[1]
        x64 = (
            np.asarray(center, float)[:, None, None]
            + e1[:, None, None] * u[None, None, :]
            + e2[:, None, None] * w[None, :, None]
        )
        self.x = np.ascontiguousarray(x64, dtype=f32)
        self.v = np.zeros_like(self.x)

        self.mass = f32(particle_mass)
        self.inv_mass = np.full((ny, nx), 1.0 / particle_mass, dtype=f32)
        self.pins = pin_indices(pins, nx, ny)
        for p in self.pins:
            self.inv_mass[p // nx, p % nx] = 0.0
        self.gravity_force = (np.asarray(gravity, float) * particle_mass).astype(f32)
        self.air_drag = f32(air_drag)
        self.damping = f32(damping)

        # Springs: one entry per present direction: slices of both ends, k, rest lengths.
        ks = {"structural": k_structural, "shear": k_shear, "bend": k_bend}
        self.springs = []
        for (di, dj), family in DIRECTIONS:
            k = ks[family]
            if k == 0 or abs(di) >= nx or dj >= ny:
                continue
            sa, sb = _slices(di, dj, nx, ny)
            # From the float32 positions, in the order the step uses: exactly 0 force at rest.
            d = self.x[:, sb[0], sb[1]] - self.x[:, sa[0], sa[1]]
            rest = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            self.springs.append((sa, sb, f32(k), rest))

        # Scratch buffers, one set per direction shape, reused every step.
        self._f = np.empty_like(self.x)
        self._scratch = {}
        for *_, rest in self.springs:
            if rest.shape not in self._scratch:
                self._scratch[rest.shape] = [np.empty(rest.shape, f32) for _ in range(9)]

    @classmethod
    def from_scene(cls, scene: Mapping[str, Any]) -> NumpyCloth:
        """Build from rustcloth's scene dict (``rustcloth.Scene.to_dict()`` form)."""
        integrator = scene.get("integrator", "symplectic_euler")
        if integrator != "symplectic_euler":
            raise NotImplementedError(f"NumpyCloth only does symplectic_euler, not {integrator}")
        if scene.get("floor") or scene.get("spheres"):
            raise NotImplementedError("NumpyCloth has no colliders (floor, spheres)")
        c = scene["cloth"]
        nx, ny = int(c["nx"]), int(c["ny"])
        if c.get("particle_mass") is not None and c.get("mass") is not None:
            raise ValueError("give particle_mass or mass, not both")
        m = c.get("particle_mass")
        if m is None:
            m = c["mass"] / (nx * ny)
        return cls(
            nx,
            ny,
            size=c.get("size", (1.0, 1.0)),
            center=c.get("center", (0.0, 0.0, 0.0)),
            plane=c.get("plane", "xz"),
            particle_mass=m,
            k_structural=c.get("k_structural", 0.0),
            k_shear=c.get("k_shear", 0.0),
            k_bend=c.get("k_bend", 0.0),
            damping=c.get("damping", 0.0),
            gravity=scene.get("gravity", (0.0, -9.81, 0.0)),
            air_drag=scene.get("air_drag", 0.0),
            pins=c.get("pins", ()),
            dt=scene.get("dt", 1e-3),
            substeps=scene.get("substeps", 1),
        )

    # -- state ------------------------------------------------------------------------------

    @property
    def n_particles(self) -> int:
        return self.nx * self.ny

    @property
    def n_springs(self) -> int:
        return sum(rest.size for *_, rest in self.springs)

    @property
    def positions(self) -> np.ndarray:
        """``(N, 3)`` float32 positions, particle ``(i, j)`` at row ``j * nx + i`` (a copy)."""
        return np.ascontiguousarray(self.x.reshape(3, -1).T)

    @property
    def velocities(self) -> np.ndarray:
        return np.ascontiguousarray(self.v.reshape(3, -1).T)

    # -- dynamics ---------------------------------------------------------------------------

    def spring_forces(self, out: np.ndarray | None = None) -> np.ndarray:
        """Spring forces ``f[c, j, i]`` (N) for the current state, without gravity or drag."""
        f = np.zeros_like(self.x) if out is None else out
        if out is not None:
            f.fill(0.0)
        x, v, c = self.x, self.v, self.damping
        for sa, sb, k, rest in self.springs:
            dx, dy, dz, dvx, dvy, dvz, length, inv, s = self._scratch[rest.shape]
            ja, ia = sa
            jb, ib = sb
            np.subtract(x[0, jb, ib], x[0, ja, ia], out=dx)
            np.subtract(x[1, jb, ib], x[1, ja, ia], out=dy)
            np.subtract(x[2, jb, ib], x[2, ja, ia], out=dz)
            # length = |d|, inv = 1/|d| (0 where |d| = 0: then d = 0 and the force is 0)
            np.multiply(dx, dx, out=length)
            np.multiply(dy, dy, out=s)
            length += s
            np.multiply(dz, dz, out=s)
            length += s
            np.sqrt(length, out=length)
            inv.fill(0.0)
            np.divide(1.0, length, out=inv, where=length > 0)
            # s = (k (l - L) + c ((v_b - v_a) . d) / l) / l: the force is s d
            length -= rest
            length *= k
            if c != 0:
                np.subtract(v[0, jb, ib], v[0, ja, ia], out=dvx)
                np.subtract(v[1, jb, ib], v[1, ja, ia], out=dvy)
                np.subtract(v[2, jb, ib], v[2, ja, ia], out=dvz)
                dvx *= dx
                dvy *= dy
                dvz *= dz
                dvx += dvy
                dvx += dvz
                dvx *= inv
                dvx *= c
                length += dvx
            np.multiply(length, inv, out=s)
            for comp, d in enumerate((dx, dy, dz)):
                d *= s
                f[comp, ja, ia] += d
                f[comp, jb, ib] -= d
        return f

    def forces(self) -> np.ndarray:
        """Total forces: springs, gravity and air drag."""
        f = self.spring_forces(out=self._f)
        for comp in range(3):
            f[comp] += self.gravity_force[comp]
            if self.air_drag != 0:
                f[comp] -= self.air_drag * self.v[comp]
        return f

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt`` (each ``substeps`` symplectic Euler substeps)."""
        h = self.h
        hw = h * self.inv_mass  # h / m, 0 for pinned particles
        for _ in range(int(n) * self.substeps):
            f = self.forces()
            f *= hw
            self.v += f
            np.multiply(self.v, h, out=f)
            self.x += f


def self_check(verbose: bool = True) -> None:
    """Spring forces conserve momentum; a 2x2 cloth at rest feels no spring force; pins hold."""
    rng = np.random.default_rng(1)
    cloth = NumpyCloth(
        7, 5, spacing=0.1, k_structural=30.0, k_shear=20.0, k_bend=10.0, damping=0.05, plane="xz"
    )
    cloth.x += rng.normal(scale=0.02, size=cloth.x.shape).astype(np.float32)
    cloth.v += rng.normal(scale=0.5, size=cloth.v.shape).astype(np.float32)
    f = cloth.spring_forces().astype(np.float64)
    total = f.reshape(3, -1).sum(axis=1)
    scale = np.abs(f).max()
    assert np.all(np.abs(total) < 1e-5 * scale * f[0].size), (total, scale)
    # torque too (central forces): sum x cross f = 0
    x = cloth.x.reshape(3, -1).T.astype(np.float64)
    torque = np.cross(x, f.reshape(3, -1).T).sum(axis=0)
    assert np.all(np.abs(torque) < 1e-5 * scale * f[0].size), torque

    for plane in ("xz", "xy"):
        rest = NumpyCloth(2, 2, size=(0.3, 0.2), plane=plane, center=(1.0, 2.0, 3.0))
        assert rest.n_springs == 6  # 2 + 2 structural, 2 shear, no bend in a 2x2 grid
        assert np.all(rest.spring_forces() == 0.0)

    hanging = NumpyCloth(6, 6, spacing=0.05, plane="xy", pins=["top_corners"])
    before = hanging.positions
    hanging.step(20)
    after = hanging.positions
    pinned = pin_indices(["top_corners"], 6, 6)
    assert np.array_equal(before[pinned], after[pinned])
    assert after[:, 1].min() < before[:, 1].min()

    # Against a straightforward spring-list implementation (float64, np.add.at).
    scene = {
        "integrator": "symplectic_euler",
        "dt": 1e-3,
        "substeps": 2,
        "gravity": [0.0, -9.81, 0.0],
        "air_drag": 0.001,
        "cloth": {
            "nx": 5,
            "ny": 4,
            "size": [0.4, 0.3],
            "center": [0, 1, 0],
            "plane": "xz",
            "particle_mass": 0.002,
            "k_structural": 40.0,
            "k_shear": 0.0,
            "k_bend": 5.0,
            "damping": 0.02,
            "pins": ["top_corners", [2, 0]],
        },
    }
    fast = NumpyCloth.from_scene(scene)
    x, v, a, b, k, rest, inv_m = _spring_list(fast)
    for _ in range(30 * 2):
        d = x[b] - x[a]
        length = np.linalg.norm(d, axis=1)
        u = d / length[:, None]
        fs = (k * (length - rest) + 0.02 * np.einsum("ij,ij->i", v[b] - v[a], u))[:, None] * u
        fo = 0.002 * np.array([0.0, -9.81, 0.0]) - 0.001 * v
        np.add.at(fo, a, fs)
        np.add.at(fo, b, -fs)
        v = v + 0.5e-3 * fo * inv_m[:, None]
        x = x + 0.5e-3 * v
    fast.step(30)
    err = np.abs(fast.positions - x).max()
    assert err < 1e-5, err
    if verbose:
        print(
            f"numpy_cloth self-check passed: |sum f| = {np.abs(total).max():.2e} N, "
            f"|sum x*f| = {np.abs(torque).max():.2e} N m, vs spring list {err:.1e} m"
        )


def _spring_list(cloth: NumpyCloth):
    nx, ny = cloth.nx, cloth.ny
    idx = np.arange(nx * ny).reshape(ny, nx)
    a = np.concatenate([idx[sa].ravel() for sa, _, _, _ in cloth.springs])
    b = np.concatenate([idx[sb].ravel() for _, sb, _, _ in cloth.springs])
    k = np.concatenate([np.full(r.size, kk, float) for _, _, kk, r in cloth.springs])
    x = cloth.positions.astype(np.float64)
    rest = np.linalg.norm(x[b] - x[a], axis=1)
    inv_m = cloth.inv_mass.ravel().astype(np.float64)
    return x, np.zeros_like(x), a, b, k, rest, inv_m


if __name__ == "__main__":
    self_check()
