"""newton peer on the stiff drape (stiff_scene.py): ``SolverVBD`` (Vertex Block Descent, Chen et
al. 2024), the nearest large-step solver newton ships for this model, on the CPU device.

The same mass-spring model as rustcloth's: particles via ``add_particles`` (the two pinned
corners with mass 0, newton's kinematic particles), the six springs per particle via
``add_spring(i, j, ke, kd, 0)`` with rest lengths from the start, damping along the spring
(newton's VBD: ``kd / h`` times the change of length, the same force as rustcloth's
``c ((v_b - v_a) . u) u`` over a step). VBD is a Gauss-Seidel method and needs a coloring in
which no spring joins two particles of one color; newton's ``ModelBuilder.color()`` colors
triangles and tetrahedra only, so this sets the exact 5-coloring of the 12-neighbour stencil,
``(i + 2 j) mod 5``. Each 1/60 s frame is ``--substeps`` steps of ``--iterations`` VBD
iterations. Warp's CPU kernels run on one thread.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import newton  # noqa: E402
import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from stiff_scene import (  # noqa: E402
    DAMPING,
    DT,
    GRAVITY,
    K,
    initial_positions,
    particle_mass,
    pinned,
    run,
    springs,
)


class NewtonVbdCloth:
    def __init__(self, n: int, substeps: int, iterations: int) -> None:
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=GRAVITY)
        x0 = initial_positions(n).astype(np.float32)
        mass = np.full(n * n, particle_mass(n))
        mass[pinned(n)] = 0.0
        builder.add_particles(
            pos=[wp.vec3(*p) for p in x0], vel=[wp.vec3(0.0, 0.0, 0.0)] * (n * n), mass=list(mass)
        )
        a, b, family = springs(n)
        for ia, ib, f in zip(a.tolist(), b.tolist(), family.tolist(), strict=True):
            builder.add_spring(ia, ib, K[f], DAMPING, 0.0)
        i, j = np.arange(n * n) % n, np.arange(n * n) // n
        color = (i + 2 * j) % 5
        builder.set_coloring([np.flatnonzero(color == c) for c in range(5)])
        self.model = builder.finalize(device="cpu")
        self.model.particle_grid = None
        self.solver = newton.solvers.SolverVBD(self.model, iterations=iterations)
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        self.control = self.model.control()
        self.substeps = substeps

    def frame(self) -> None:
        h = DT / self.substeps
        for _ in range(self.substeps):
            self.state_0.clear_forces()
            self.solver.step(self.state_0, self.state_1, self.control, None, h)
            self.state_0, self.state_1 = self.state_1, self.state_0
        wp.synchronize()

    @property
    def positions(self) -> np.ndarray:
        return self.state_0.particle_q.numpy()


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=128)
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--substeps", type=int, default=10)
    p.add_argument("--iterations", type=int, default=10)
    p.add_argument("--name", default="newton")
    p.add_argument("--out", default=None)
    args = p.parse_args()
    wp.config.quiet = True
    wp.init()
    run(
        args.name,
        args.n,
        args.frames,
        build=lambda: NewtonVbdCloth(args.n, args.substeps, args.iterations),
        step=lambda sim: sim.frame(),
        positions=lambda sim: sim.positions,
        stats=lambda sim: {
            "threads": 1,
            "substeps": args.substeps,
            "iterations": args.iterations,
            "version": f"newton {newton.__version__}, warp {wp.__version__}",
        },
        out=args.out,
    )


if __name__ == "__main__":
    main()
