"""Where the stiff mesh step's time goes: setup and solve ms a step (the solver's own wall-clock
timers from ``solver_stats()``), CPU ms a step and CG iterations a solve, steps 6 to 25 of the
16k stiff drape of ``benches/mesh_step.py --stiff``, best of 3 by CPU time.

    RAYON_NUM_THREADS=1 python benches/mesh_solve_split.py [--shuffle]

``--shuffle`` numbers the mesh at random, as ``mesh_step.py --shuffle`` does. Compare builds by
running it with each build's package on ``PYTHONPATH``, alternated, in one window.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import rustcloth  # noqa: E402
from test_mesh_cloth import jittered_square  # noqa: E402

N = 129


def main() -> None:
    shuffle = "--shuffle" in sys.argv
    vertices, triangles = jittered_square(N)
    pins = [N * N - N, N * N - 1]
    if shuffle:
        old = np.random.default_rng(1).permutation(N * N)
        new = np.empty_like(old)
        new[old] = np.arange(N * N)
        vertices, triangles = vertices[old], new[triangles]
        pins = [int(new[v]) for v in pins]
    grid = rustcloth.Scene.from_dict({
        "integrator": "implicit_euler", "dt": 1 / 60, "preconditioner": "multigrid",
        "cloth": {"nx": N, "ny": N, "size": [1.0, 1.0], "pins": ["top_corners"],
                  "particle_mass": 0.5 / (N * N), "k_structural": 500.0, "k_shear": 125.0,
                  "k_bend": 25.0}})
    mesh = grid.with_cloth_mesh(vertices, triangles, stretch=1500.0, bend=200.0, density=0.5,
                                pins=pins)
    best = None
    for _ in range(3):
        sim = rustcloth.Simulation(mesh)
        sim.step(5)
        s0 = sim.solver_stats()
        t = time.process_time()
        sim.step(20)
        cpu = (time.process_time() - t) / 20 * 1e3
        s1 = sim.solver_stats()
        setup = (s1["setup_seconds"] - s0["setup_seconds"]) / 20 * 1e3
        solve = (s1["solve_seconds"] - s0["solve_seconds"]) / 20 * 1e3
        iterations = (s1["iterations"] - s0["iterations"]) / (s1["solves"] - s0["solves"])
        run = (cpu, setup, solve, iterations)
        best = run if best is None or run[0] < best[0] else best
    assert best is not None
    print(f"{rustcloth.__file__}: mesh CPU {best[0]:.2f} ms a step, setup {best[1]:.2f} ms, "
          f"solve {best[2]:.2f} ms (wall, the solver's timers), CG iterations a solve "
          f"{best[3]:.2f}")


if __name__ == "__main__":
    main()
