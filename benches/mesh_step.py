"""The step of a mesh cloth against the grid of the same particle count.

    RAYON_NUM_THREADS=1 python benches/mesh_step.py [--n 129] [--steps 100] [--repeat 3] [--wall]
        [--stiff] [--membrane] [--bending] [--shuffle]

An `n` x `n` jittered square (``tests/test_mesh_cloth.py``'s ``jittered_square``: irregular, each
quad split along its shorter diagonal; `stretch` 60 N/m, 0.2 kg/m^2, two corners pinned) and the
`n` x `n` grid of the default material, both under symplectic Euler at 20 us (within both stable
steps). With ``--stiff``, both stiff at 1/60 s under implicit Euler with the multigrid
preconditioner (smoothed aggregation on the mesh): the grid's `k_structural` 500, `k_shear` 125
and `k_bend` 25 N/m, the mesh's `stretch` 1500 and `bend` 200 N/m, both 0.5 kg (as
``examples/mesh_implicit.rs``), at most 20 steps. Prints the best of `--repeat` runs of `--steps`
steps after 5, per step: CPU time of this process (steady on a shared machine with one thread;
``--wall`` for wall time with several). With ``--membrane``, the same mesh with
``membrane = "triangle"`` too, and its cost against the springs' in the same runs; with
``--bending``, the same mesh with ``bending = "isometric"`` (``bend_modulus`` 5e-5 N m, the
default; 2e-4 with ``--stiff``) likewise. Two builds
compare by running this once with each on
``PYTHONPATH``, one after the other. With ``--shuffle``, the mesh's vertices are numbered in a
random order (as a Delaunay mesh of dart-thrown points, or a file, may number them) instead
of row by row: the cost of a vertex order that gathers far apart.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
import rustcloth  # noqa: E402
from test_mesh_cloth import jittered_square  # noqa: E402

ITERATIONS: dict[int, float] = {}
"""CG iterations per solve of the last run of each scene (by position), with ``--stiff``."""


def per_step(scene: rustcloth.Scene, steps: int, wall: bool, key: int = 0) -> float:
    """Milliseconds per step of `steps` steps of a fresh simulation of `scene`, after 5."""
    tick = time.perf_counter if wall else time.process_time
    sim = rustcloth.Simulation(scene)
    sim.step(5)
    start = tick()
    sim.step(steps)
    elapsed = (tick() - start) / steps * 1e3
    stats = sim.solver_stats()
    if stats:
        ITERATIONS[key] = stats["iterations"] / max(stats["solves"], 1)
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=129, help="points along a side (default 129)")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--wall", action="store_true", help="wall time instead of CPU time")
    parser.add_argument("--stiff", action="store_true", help="implicit Euler, stiff, 1/60 s")
    parser.add_argument("--membrane", action="store_true",
                        help='also the mesh with membrane = "triangle"')
    parser.add_argument("--bending", action="store_true",
                        help='also the mesh with bending = "isometric"')
    parser.add_argument("--shuffle", action="store_true",
                        help="number the mesh's vertices in a random order")
    args = parser.parse_args()
    n = args.n
    vertices, triangles = jittered_square(n)
    pins = [n * n - n, n * n - 1]
    if args.shuffle:
        # `old[k]` is the vertex numbered `k` in the shuffled mesh, `new` the inverse.
        old = np.random.default_rng(1).permutation(n * n)
        new = np.empty_like(old)
        new[old] = np.arange(n * n)
        vertices, triangles = vertices[old], new[triangles]
        pins = [int(new[v]) for v in pins]
    if args.stiff:
        grid = rustcloth.Scene.from_dict({
            "integrator": "implicit_euler",
            "dt": 1 / 60,
            "preconditioner": "multigrid",
            "cloth": {"nx": n, "ny": n, "size": [1.0, 1.0], "pins": ["top_corners"],
                      "particle_mass": 0.5 / (n * n), "k_structural": 500.0,
                      "k_shear": 125.0, "k_bend": 25.0},
        })
        mesh = grid.with_cloth_mesh(
            vertices, triangles, stretch=1500.0, bend=200.0, density=0.5, pins=pins
        )
        args.steps = min(args.steps, 20)
    else:
        grid = rustcloth.Scene.from_dict({
            "integrator": "symplectic_euler",
            "dt": 2e-5,
            "cloth": {"nx": n, "ny": n, "size": [1.0, 1.0], "pins": ["top_corners"]},
        })
        mesh = grid.with_cloth_mesh(vertices, triangles, stretch=60.0, density=0.2, pins=pins)
    scenes = [grid, mesh]
    if args.membrane:
        data = mesh.to_dict()
        data["cloth"]["mesh"]["membrane"] = "triangle"
        scenes.append(rustcloth.Scene.from_dict(data))
    if args.bending:
        data = mesh.to_dict()
        data["cloth"]["mesh"]["bending"] = "isometric"
        data["cloth"]["mesh"]["bend_modulus"] = 2e-4 if args.stiff else 5e-5
        scenes.append(rustcloth.Scene.from_dict(data))
    runs = [[per_step(s, args.steps, args.wall, k) for k, s in enumerate(scenes)]
            for _ in range(args.repeat)]
    g, m = min(r[0] for r in runs), min(r[1] for r in runs)
    kind = "wall" if args.wall else "CPU"
    print(f"{rustcloth.__file__}: {rustcloth._core.instruction_set()}, "
          f"{rustcloth._core.thread_count()} thread(s), {kind} time per step")
    print(f"grid {n} x {n}: {g:.3f} ms   mesh {n * n} vertices: {m:.3f} ms   "
          f"mesh / grid {m / g:.2f}")
    if args.membrane:
        t = min(r[2] for r in runs)
        print(f"mesh with the triangle membrane: {t:.3f} ms   triangle / springs {t / m:.2f}   "
              f"triangle / grid {t / g:.2f}")
    if args.bending:
        b = min(r[-1] for r in runs)
        print(f"mesh with isometric bending: {b:.3f} ms   isometric / springs {b / m:.2f}   "
              f"isometric / grid {b / g:.2f}")
    if ITERATIONS:
        print("CG iterations a solve (grid, mesh, then --membrane's, --bending's):",
              ", ".join(f"{ITERATIONS[k]:.1f}" for k in sorted(ITERATIONS)))


if __name__ == "__main__":
    main()
