"""A small, readable numpy implementation of rustcloth's model, written from the README's
formulas and independent of the Rust code: the truth the fast solver is tested against.

Float64 throughout, one spring list, ``np.add.at`` to scatter: clarity over speed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

PIN_GROUPS = {
    "top_corners": lambda nx, ny: [(0, ny - 1), (nx - 1, ny - 1)],
    "bottom_corners": lambda nx, ny: [(0, 0), (nx - 1, 0)],
    "corners": lambda nx, ny: [(0, 0), (nx - 1, 0), (0, ny - 1), (nx - 1, ny - 1)],
    "top_edge": lambda nx, ny: [(i, ny - 1) for i in range(nx)],
    "bottom_edge": lambda nx, ny: [(i, 0) for i in range(nx)],
    "left_edge": lambda nx, ny: [(0, j) for j in range(ny)],
    "right_edge": lambda nx, ny: [(nx - 1, j) for j in range(ny)],
}


@dataclass
class ReferenceCloth:
    scene: dict[str, Any]
    x: np.ndarray = field(init=False)
    v: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        s, c = self.scene, self.scene["cloth"]
        nx, ny = c["nx"], c["ny"]
        self.nx, self.ny = nx, ny
        e1 = np.array([1.0, 0.0, 0.0])
        e2 = np.array([0.0, 0.0, 1.0]) if c["plane"] == "xz" else np.array([0.0, 1.0, 0.0])
        i, j = np.meshgrid(np.arange(nx), np.arange(ny))  # j-major: row j holds i = 0..nx-1
        u = (i.ravel() / (nx - 1) - 0.5) * c["size"][0]
        w = (j.ravel() / (ny - 1) - 0.5) * c["size"][1]
        self.x = np.array(c["center"]) + u[:, None] * e1 + w[:, None] * e2
        self.v = np.zeros_like(self.x)
        n = nx * ny
        m = c.get("particle_mass") or c["mass"] / n
        self.mass = np.full(n, m)
        self.inv_mass = 1.0 / self.mass
        for pin in c["pins"]:
            cells = PIN_GROUPS[pin](nx, ny) if isinstance(pin, str) else [tuple(pin)]
            for ci, cj in cells:
                self.inv_mass[cj * nx + ci] = 0.0
        # The 12-neighbour stencil: (di, dj) from one end to the other, with its stiffness.
        stencil = [
            ((1, 0), c["k_structural"]),
            ((0, 1), c["k_structural"]),
            ((1, 1), c["k_shear"]),
            ((-1, 1), c["k_shear"]),
            ((2, 0), c["k_bend"]),
            ((0, 2), c["k_bend"]),
        ]
        a, b, k = [], [], []
        for (di, dj), stiffness in stencil:
            if stiffness == 0:
                continue
            for jj in range(ny):
                for ii in range(nx):
                    pi, pj = ii + di, jj + dj
                    if 0 <= pi < nx and 0 <= pj < ny:
                        a.append(jj * nx + ii)
                        b.append(pj * nx + pi)
                        k.append(stiffness)
        self.a, self.b, self.k = np.array(a, int), np.array(b, int), np.array(k, float)
        self.rest = np.linalg.norm(self.x[self.b] - self.x[self.a], axis=1)
        self.c = c["damping"]
        self.g = np.array(s["gravity"], float)
        self.drag = s["air_drag"]
        self.h = s["dt"] / s["substeps"]
        self.substeps = s["substeps"]
        self.integrator = s["integrator"]

    def forces(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        f = self.mass[:, None] * self.g - self.drag * v
        d = x[self.b] - x[self.a]
        length = np.linalg.norm(d, axis=1)
        u = np.divide(d, length[:, None], out=np.zeros_like(d), where=length[:, None] > 0)
        closing = np.einsum("ij,ij->i", v[self.b] - v[self.a], u)
        fs = (self.k * (length - self.rest) + self.c * closing)[:, None] * u
        np.add.at(f, self.a, fs)
        np.add.at(f, self.b, -fs)
        return f

    def accel(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.forces(x, v) * self.inv_mass[:, None]

    def step(self, n: int = 1) -> None:
        moving = (self.inv_mass > 0)[:, None]
        h = self.h
        for _ in range(n * self.substeps):
            x0, v0 = self.x, self.v
            if self.integrator == "symplectic_euler":
                v = v0 + h * self.accel(x0, v0)
                x = x0 + h * v
            elif self.integrator == "explicit_euler":
                x = x0 + h * v0
                v = v0 + h * self.accel(x0, v0)
            elif self.integrator == "verlet":
                # Stoermer: x1 = 2 x0 - x_prev + h^2 a, v1 = (x1 - x0) / h, with the Taylor
                # start x_prev = x0 - h v0 + h^2 a / 2 on the first step.
                a = self.accel(x0, v0)
                x_prev = x0 - h * v0 + (0.5 * h * h * a if not self.verlet_primed else 0.0)
                self.verlet_primed = True
                x = 2 * x0 - x_prev + h * h * a
                v = (x - x0) / h
            elif self.integrator == "rk4":
                k1x, k1v = v0, self.accel(x0, v0)
                k2x, k2v = v0 + h / 2 * k1v, self.accel(x0 + h / 2 * k1x, v0 + h / 2 * k1v)
                k3x, k3v = v0 + h / 2 * k2v, self.accel(x0 + h / 2 * k2x, v0 + h / 2 * k2v)
                k4x, k4v = v0 + h * k3v, self.accel(x0 + h * k3x, v0 + h * k3v)
                x = x0 + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v0 + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            elif self.integrator == "implicit_euler":
                v = v0 + self.implicit_dv(x0, v0)
                x = x0 + h * v
            elif self.integrator == "projective_dynamics":
                x = self.backward_euler(x0, v0)
                v = (x - x0) / h
            else:
                raise ValueError(self.integrator)
            self.x = np.where(moving, x, self.x)
            self.v = np.where(moving, v, self.v)

    verlet_primed = False

    def backward_euler(self, x0: np.ndarray, v0: np.ndarray) -> np.ndarray:
        """The exact (not linearised) backward-Euler step, which projective dynamics converges
        to: the x with ``M (x - x0 - h v0) / h^2 = f(x, (x - x0) / h)``, found by Newton's
        method on a dense Jacobian, pinned particles held."""
        n, h = len(x0), self.h
        free = np.repeat(self.inv_mass > 0, 3)
        mass = np.repeat(self.mass, 3)
        eye = np.eye(3)
        x = x0 + h * v0
        for _ in range(50):
            v = (x - x0) / h
            residual = mass * (x - x0 - h * v0).ravel() / h**2 - self.forces(x, v).ravel()
            if np.abs(residual[free]).max() < 1e-12 * max(1.0, np.abs(mass).max() / h**2):
                break
            # -df/dx (exact, compressed springs included) and -df/dv.
            jacobian = np.diag(mass / h**2) + np.eye(3 * n) * self.drag / h
            for a, b, k, rest in zip(self.a, self.b, self.k, self.rest, strict=True):
                d = x[b] - x[a]
                length = np.linalg.norm(d)
                if length == 0:
                    continue
                u = d / length
                block = k * (np.outer(u, u) + (1 - rest / length) * (eye - np.outer(u, u)))
                block += self.c / h * np.outer(u, u)
                for p, q, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
                    jacobian[3 * p:3 * p + 3, 3 * q:3 * q + 3] += sign * block
            step = np.zeros(3 * n)
            step[free] = np.linalg.solve(jacobian[np.ix_(free, free)], -residual[free])
            x = x + step.reshape(n, 3)
        return x

    def implicit_dv(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Solve (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v) densely, pinned particles
        removed, with the compressed-spring fix g = max(0, 1 - L/l)."""
        n, h = len(x), self.h
        stiffness = np.zeros((3 * n, 3 * n))  # -df/dx
        damping = np.zeros((3 * n, 3 * n))  # -df/dv
        eye = np.eye(3)
        for a, b, k, rest in zip(self.a, self.b, self.k, self.rest, strict=True):
            d = x[b] - x[a]
            length = np.linalg.norm(d)
            u = d / length if length > 0 else np.zeros(3)
            g = max(0.0, 1.0 - rest / length) if length > 0 else 0.0
            blocks = ((stiffness, k * ((1 - g) * np.outer(u, u) + g * eye)),
                      (damping, self.c * np.outer(u, u)))
            for matrix, block in blocks:
                for p, q, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
                    matrix[3 * p:3 * p + 3, 3 * q:3 * q + 3] += sign * block
        damping += self.drag * np.eye(3 * n)
        mass = np.repeat(self.mass, 3)
        matrix = np.diag(mass) + h * damping + h * h * stiffness
        rhs = h * (self.forces(x, v).ravel() - h * stiffness @ v.ravel())
        free = np.repeat(self.inv_mass > 0, 3)
        dv = np.zeros(3 * n)
        dv[free] = np.linalg.solve(matrix[np.ix_(free, free)], rhs[free])
        return dv.reshape(n, 3)
