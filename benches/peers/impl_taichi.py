"""Taichi peer, CPU backend: one kernel per step.

``--variant gather`` (default): one thread per particle sums the forces of its (up to) 12
neighbours, writing the new state to a second buffer (ping-pong), so each spring is evaluated
twice and there are no atomics. ``--variant atomic``: one thread per spring, atomic adds into a
force field, then a per-particle update (each spring evaluated once), for reference.

Rest lengths are stored per spring (per particle and direction), computed from the initial
positions, as a general implementation must; pinned particles have inverse mass 0.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402
import taichi as ti  # noqa: E402
from common import (  # noqa: E402
    DAMPING,
    DIRECTIONS,
    DT,
    GRAVITY,
    PARTICLE_MASS,
    K,
    initial_positions,
    measure,
    parse_args,
    pinned,
)


def add_variant(p) -> None:
    p.add_argument("--variant", choices=("gather", "atomic"), default="gather")


class TaichiCloth:
    def __init__(self, n: int, variant: str) -> None:
        self.n, self.variant = n, variant
        x0 = initial_positions(n).astype(np.float32).reshape(n, n, 3)
        inv_m = np.full((n, n), 1.0 / PARTICLE_MASS, np.float32)
        for p in pinned(n):
            inv_m[p // n, p % n] = 0.0
        rest = np.zeros((n, n, 6), np.float32)
        for d, (di, dj) in enumerate(DIRECTIONS):
            for_j = slice(0, n - dj)
            for_i = slice(max(0, -di), n - max(0, di))
            xa = x0[for_j, for_i]
            xb = x0[dj : dj + (n - dj), max(0, -di) + di : n - max(0, di) + di]
            diff = xb - xa
            rest[for_j, for_i, d] = np.sqrt((diff * diff).sum(axis=-1))
        vec = ti.types.vector(3, ti.f32)
        self.x = [ti.field(vec, shape=(n, n)) for _ in range(2)]
        self.v = [ti.field(vec, shape=(n, n)) for _ in range(2)]
        self.f = ti.field(vec, shape=(n, n))
        self.inv_m = ti.field(ti.f32, shape=(n, n))
        self.rest = ti.field(ti.f32, shape=(n, n, 6))
        self.x[0].from_numpy(x0)
        self.v[0].from_numpy(np.zeros_like(x0))
        self.inv_m.from_numpy(inv_m)
        self.rest.from_numpy(rest)
        self.cur = 0
        self._build_kernels()

    def _build_kernels(self) -> None:
        n = self.n
        dirs = DIRECTIONS
        k, c, h, m = K, DAMPING, DT, PARTICLE_MASS
        g = ti.Vector(GRAVITY)
        inv_m, rest, f = self.inv_m, self.rest, self.f

        @ti.func
        def spring(xa, xb, va, vb, r):
            # force on a from the spring (a, b)
            d = xb - xa
            length = d.norm()
            out = ti.Vector([0.0, 0.0, 0.0])
            if length > 0:
                inv = 1.0 / length
                s = (k * (length - r) + c * (vb - va).dot(d) * inv) * inv
                out = s * d
            return out

        @ti.kernel
        def gather(x: ti.template(), v: ti.template(), xo: ti.template(), vo: ti.template()):
            for j, i in x:
                w = inv_m[j, i]
                if w == 0:
                    xo[j, i] = x[j, i]
                    vo[j, i] = v[j, i]
                else:
                    xa, va = x[j, i], v[j, i]
                    fa = m * g
                    for d in ti.static(range(6)):
                        di, dj = ti.static(dirs[d])
                        # as end a of the spring (i, j) -> (i+di, j+dj)
                        if 0 <= i + di < n and j + dj < n:
                            fa += spring(
                                xa, x[j + dj, i + di], va, v[j + dj, i + di], rest[j, i, d]
                            )
                        # as end b of the spring (i-di, j-dj) -> (i, j)
                        if 0 <= i - di < n and j - dj >= 0:
                            fa += spring(
                                xa,
                                x[j - dj, i - di],
                                va,
                                v[j - dj, i - di],
                                rest[j - dj, i - di, d],
                            )
                    vn = va + h * w * fa
                    vo[j, i] = vn
                    xo[j, i] = xa + h * vn

        @ti.kernel
        def springs_atomic(x: ti.template(), v: ti.template()):
            for j, i in f:
                f[j, i] = m * g
            for j, i in f:
                for d in ti.static(range(6)):
                    di, dj = ti.static(dirs[d])
                    if 0 <= i + di < n and j + dj < n:
                        fs = spring(
                            x[j, i], x[j + dj, i + di], v[j, i], v[j + dj, i + di], rest[j, i, d]
                        )
                        ti.atomic_add(f[j, i], fs)
                        ti.atomic_sub(f[j + dj, i + di], fs)

        @ti.kernel
        def integrate(x: ti.template(), v: ti.template()):
            for j, i in x:
                w = inv_m[j, i]
                v[j, i] += h * w * f[j, i]
                x[j, i] += h * v[j, i]

        self._gather, self._springs_atomic, self._integrate = gather, springs_atomic, integrate

    def step(self, steps: int) -> None:
        for _ in range(steps):
            if self.variant == "gather":
                a, b = self.cur, 1 - self.cur
                self._gather(self.x[a], self.v[a], self.x[b], self.v[b])
                self.cur = b
            else:
                x, v = self.x[self.cur], self.v[self.cur]
                self._springs_atomic(x, v)
                self._integrate(x, v)
        ti.sync()

    @property
    def positions(self) -> np.ndarray:
        return self.x[self.cur].to_numpy().reshape(-1, 3)


def main() -> None:
    args = parse_args(add_variant)
    if args.colliders:
        raise SystemExit("the Taichi peer has no colliders")
    ti.init(arch=ti.cpu, cpu_max_num_threads=args.threads, default_fp=ti.f32, log_level=ti.WARN)
    measure(
        args,
        build=lambda: TaichiCloth(args.n, args.variant),
        step=lambda sim, k: sim.step(k),
        positions=lambda sim: sim.positions,
        info={
            "version": ti.__version__ and ".".join(map(str, ti.__version__)),
            "variant": args.variant,
        },
    )


if __name__ == "__main__":
    main()
