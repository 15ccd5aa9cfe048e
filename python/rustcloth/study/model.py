"""The study's reference: rustcloth's model in float64 numpy, stepped by an adaptive
Dormand-Prince 5(4) integrator, a method none of the integrators under test uses.

The model is the README's: Hooke springs with damping along the spring over the 12-neighbour
stencil, gravity, air drag, pinned particles held; no colliders (the study's scenes have none:
contact is not smooth, and orders of accuracy are only visible on smooth motion). It is built
from a scene dict and the simulation's own starting state, so both start from the same float32
positions.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Dormand-Prince 5(4): nodes, stages, and the two weight rows (5th order, 4th order).
_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = [
    [],
    [1 / 5],
    [3 / 40, 9 / 40],
    [44 / 45, -56 / 15, 32 / 9],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
]
_B5 = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0])
_B4 = np.array([5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100,
                1 / 40])

_STENCIL = ((1, 0, "k_structural"), (0, 1, "k_structural"), (1, 1, "k_shear"),
            (-1, 1, "k_shear"), (2, 0, "k_bend"), (0, 2, "k_bend"))


class Cloth:
    """The cloth of ``scene`` (a scene dict) from positions ``x0`` and velocities ``v0``,
    particles held where ``pinned``; ``masses`` per particle in kg. Rest lengths are taken from
    ``rest`` (default ``x0``): the scene's starting shape, where rustcloth takes them."""

    def __init__(self, scene: dict[str, Any], x0: np.ndarray, v0: np.ndarray,
                 masses: np.ndarray, pinned: np.ndarray, rest: np.ndarray | None = None
                 ) -> None:
        cloth = scene["cloth"]
        nx, ny = cloth["nx"], cloth["ny"]
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.v = np.asarray(v0, dtype=np.float64).copy()
        self.mass = np.asarray(masses, dtype=np.float64)
        self.free = ~np.asarray(pinned, dtype=bool)
        index = np.arange(nx * ny).reshape(ny, nx)
        a, b, k = [], [], []
        for di, dj, key in _STENCIL:
            if cloth[key] == 0:
                continue
            i0, i1 = max(0, -di), nx - max(0, di)
            a.append(index[0 : ny - dj, i0:i1].ravel())
            b.append(index[dj:ny, i0 + di : i1 + di].ravel())
            k.append(np.full(a[-1].size, float(cloth[key])))
        self.a, self.b, self.k = (np.concatenate(t) for t in (a, b, k))
        shape = self.x if rest is None else np.asarray(rest, dtype=np.float64)
        self.rest = np.linalg.norm(shape[self.b] - shape[self.a], axis=1)
        self.c = float(cloth["damping"])
        self.g = np.asarray(scene["gravity"], dtype=np.float64)
        self.drag = float(scene["air_drag"])
        self.evaluations = 0

    def acceleration(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        d = x[self.b] - x[self.a]
        length = np.linalg.norm(d, axis=1)
        safe = np.where(length > 0, length, 1.0)
        u = np.where(length[:, None] > 0, d / safe[:, None], 0.0)
        closing = np.einsum("ij,ij->i", v[self.b] - v[self.a], u)
        s = (self.k * (length - self.rest) + self.c * closing)[:, None] * u
        f = self.mass[:, None] * self.g - self.drag * v
        np.add.at(f, self.a, s)
        np.add.at(f, self.b, -s)
        acc = f / self.mass[:, None]
        acc[~self.free] = 0.0
        return acc

    def advance(self, seconds: float, tolerance: float = 1e-11) -> None:
        """Integrates ``seconds`` with local error below ``tolerance`` (m, m/s) per step."""
        t, h = 0.0, 1e-4
        x, v = self.x, self.v
        free = self.free[:, None]
        while t < seconds:
            h = min(h, seconds - t)
            kx: list[np.ndarray] = []
            kv: list[np.ndarray] = []
            for stage in range(7):
                xs, vs = x.copy(), v.copy()
                for weight, dx, dv in zip(_A[stage], kx, kv, strict=False):
                    xs += h * weight * dx
                    vs += h * weight * dv
                kx.append(np.where(free, vs, 0.0))
                kv.append(self.acceleration(xs, vs))
            x5 = x + h * sum(w * k for w, k in zip(_B5, kx, strict=True))
            v5 = v + h * sum(w * k for w, k in zip(_B5, kv, strict=True))
            x4 = x + h * sum(w * k for w, k in zip(_B4, kx, strict=True))
            v4 = v + h * sum(w * k for w, k in zip(_B4, kv, strict=True))
            error = max(np.abs(x5 - x4).max(), h * np.abs(v5 - v4).max())
            if error <= tolerance or h < 1e-9:
                t += h
                x, v = x5, v5
            h *= min(4.0, max(0.2, 0.9 * (tolerance / max(error, 1e-300)) ** 0.2))
        self.x, self.v = x, v
