"""newton peer (NVIDIA Newton, on Warp): ``SolverSemiImplicit`` on the CPU device.

Particles with ``ModelBuilder.add_particles`` (pinned ones with mass 0: newton's kinematic
particles), the 6 springs per particle with ``ModelBuilder.add_spring(i, j, ke, kd, control)``
(rest length = initial distance, damping ``kd ((v_i - v_j) . u) u``: the same model), y up,
gravity -9.81. ``model.particle_grid = None`` switches off particle-particle contact, which
the other implementations do not have (the solver otherwise rebuilds a hash grid every step).
Warp's CPU kernels run on one thread; each step is one spring kernel (per spring, atomic
adds) and one integration kernel, plus a force clear.
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import newton  # noqa: E402
import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
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


class NewtonCloth:
    def __init__(self, n: int) -> None:
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=GRAVITY)
        x0 = initial_positions(n).astype(np.float32)
        mass = np.full(n * n, PARTICLE_MASS)
        mass[pinned(n)] = 0.0
        builder.add_particles(
            pos=[wp.vec3(*p) for p in x0], vel=[wp.vec3(0.0, 0.0, 0.0)] * (n * n), mass=list(mass)
        )
        idx = np.arange(n * n).reshape(n, n)
        for di, dj in DIRECTIONS:
            cols_a = slice(max(0, -di), n - max(0, di))
            cols_b = slice(max(0, -di) + di, n - max(0, di) + di)
            a = idx[0 : n - dj, cols_a].ravel()
            b = idx[dj:n, cols_b].ravel()
            for ia, ib in zip(a.tolist(), b.tolist(), strict=True):
                builder.add_spring(ia, ib, K, DAMPING, 0.0)
        self.model = builder.finalize(device="cpu")
        self.model.particle_grid = None
        self.solver = newton.solvers.SolverSemiImplicit(self.model)
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        self.control = self.model.control()

    def step(self, steps: int) -> None:
        for _ in range(steps):
            self.state_0.clear_forces()
            self.solver.step(self.state_0, self.state_1, self.control, None, DT)
            self.state_0, self.state_1 = self.state_1, self.state_0
        wp.synchronize()

    @property
    def positions(self) -> np.ndarray:
        return self.state_0.particle_q.numpy()


def main() -> None:
    args = parse_args()
    if args.colliders:
        raise SystemExit("the newton peer is run without colliders")
    if args.threads != 1:
        raise SystemExit("Warp's CPU device is single-threaded")
    wp.config.quiet = True
    wp.init()
    measure(
        args,
        build=lambda: NewtonCloth(args.n),
        step=lambda sim, k: sim.step(k),
        positions=lambda sim: sim.positions,
        info={"version": f"newton {newton.__version__}, warp {wp.__version__}"},
    )


if __name__ == "__main__":
    main()
