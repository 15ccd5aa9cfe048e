"""The built-in ``shirt`` dragged hard after it is sewn: its hem's lowest front vertex grabbed
at 3 s and pulled 0.47 m (0.25 up, 0.4 forward) over 0.5 s, held 0.5 s, released, then 4 s
more. Prints the largest edge length during the drag against the same edge before it, how far
the grip's particles are from where the drag put them at its end (a pin the self-collision
pass stopped is behind its target), the largest seam gap every 0.5 s after the release
(``Simulation.seam_gap()``), the kinetic energy and the crossings at the end (by the independent
checker ``benches/peers/tri_check.py``), and the CPU time per 1/60 s frame. Compares the scene
as built in (symplectic Euler, 5 substeps of 1 ms) with implicit Euler at ``--steps`` steps a
1/60 s frame (default 1), holding the pairs ahead of each step apart inside its solve at each
``--solve-stiffness`` given (``self_collision.solve_stiffness``; default 0, the pass alone),
and prints implicit Euler's CG iterations a solve and pairs held a step.

    RAYON_NUM_THREADS=1 .venv/bin/python benches/shirt_drag.py [--integrator both] [--steps 1]
        [--solve-stiffness 0 30 100] [--sideways] [--trace]

``--sideways`` pulls the hem 0.2 m sideways, 0.25 up and 0.3 forward instead (a fold dragged
across itself); ``--trace`` prints the energies, the fastest vertex and the pairs held frame by
frame.

About a minute for each run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import rustcloth

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import tri_check  # noqa: E402


def edge_lengths(sim: rustcloth.Simulation) -> np.ndarray:
    x = sim.positions.astype(np.float64)
    t = sim.triangles
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)


def sewn_as_one(scene: rustcloth.Scene, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` with each sewn pair's higher vertex taken as its lower: sewn vertices are
    one point to the self-collision pass, and so to the crossing checker (a seam's chains hold
    no vertex twice)."""
    same = np.arange(int(triangles.max()) + 1)
    for a, b in np.asarray(scene.cloth["mesh"]["seams"]["pairs"], dtype=np.int64):
        same[max(a, b)] = min(a, b)
    return same[triangles]


def run(implicit: bool, steps: int, stiffness: float, pull: np.ndarray, trace: bool) -> None:
    scene = rustcloth.load_scene("shirt")
    if implicit:
        scene = scene.replace(integrator="implicit_euler", dt=1 / (60 * steps), substeps=1,
                              self_collision={"solve_stiffness": stiffness})
    sim = rustcloth.Simulation(scene)
    start = time.process_time()
    for _ in range(180):
        sim.advance(1 / 60)
    settled = time.process_time() - start
    before = edge_lengths(sim)
    x = sim.positions
    hem = int(np.argmin(x[:, 1] - 0.01 * x[:, 2]))
    origin = x[hem].astype(np.float64)
    sim.grab(hem)
    gripped = sim.gripped()
    grabbed_at = sim.positions[gripped].astype(np.float64)
    stretch = 0.0
    start = time.process_time()
    for frame in range(60):
        reach = min(1.0, (frame + 1) / 30)
        sim.drag_to((origin + reach * pull).tolist())
        sim.advance(1 / 60)
        stretch = max(stretch, float(np.max(edge_lengths(sim) / before)))
        if trace:
            print_frame(sim, frame)
    miss = np.linalg.norm(sim.positions[gripped] - (grabbed_at + pull), axis=1).max()
    sim.release()
    gaps = []
    for frame in range(240):
        sim.advance(1 / 60)
        if trace and frame % 10 == 9:
            print_frame(sim, 60 + frame)
        if frame % 30 == 29:
            gaps.append(round(1000 * sim.seam_gap(), 1))
    dragged = time.process_time() - start
    crossings = tri_check.count(sim.positions, sewn_as_one(scene, sim.triangles))
    name = "the scene (symplectic Euler)"
    solver = ""
    if implicit:
        name = f"implicit Euler, 1/{60 * steps} s, solve_stiffness {stiffness:g}"
        stats = sim.solver_stats() or {}
        solves = max(stats.get("solves", 0.0), 1.0)
        solver = (f"; {stats.get('iterations', 0.0) / solves:.1f} CG iterations a solve, "
                  f"{stats.get('solves', 0.0) / (480 * steps):.2f} solves and "
                  f"{stats.get('self_pairs', 0.0) / (480 * steps):.0f} pairs held a step")
    print(f"{name}: {1000 * settled / 180:.1f} CPU ms a frame sewing and settling, "
          f"{1000 * dragged / 300:.1f} dragged and after; largest edge ratio in the drag "
          f"{stretch:.2f}; the grip {1000 * miss:.1f} mm off its target at its end; seam gap "
          f"(mm) every 0.5 s after the release {gaps}; kinetic energy at the end "
          f"{sim.energy().kinetic:.2g} J; {crossings} crossings at the end{solver}", flush=True)


def print_frame(sim: rustcloth.Simulation, frame: int) -> None:
    """One line of ``--trace``: the frame (from the drag's start), the energies, the fastest
    vertex and the pairs held so far."""
    e = sim.energy()
    fastest = float(np.linalg.norm(sim.velocities, axis=1).max())
    pairs = (sim.solver_stats() or {}).get("self_pairs", 0.0)
    print(f"  frame {frame + 1:3d}: kinetic {e.kinetic:.3g} J, gravitational "
          f"{e.gravitational:.4f} J, elastic {e.elastic:.3g} J, total {e.total:.4f} J, "
          f"fastest {fastest:.3g} m/s, pairs held {pairs:.0f} so far", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--integrator", choices=["scene", "implicit", "both"], default="both")
    parser.add_argument("--steps", type=int, default=1,
                        help="implicit Euler's steps per 1/60 s frame (default 1)")
    parser.add_argument("--solve-stiffness", type=float, nargs="+", default=[0.0],
                        help="implicit Euler's self_collision.solve_stiffness, one run each "
                             "(default 0: the pass after the solve alone)")
    parser.add_argument("--sideways", action="store_true",
                        help="pull the hem 0.2 m sideways, 0.25 up and 0.3 forward instead")
    parser.add_argument("--trace", action="store_true",
                        help="print the energies, the fastest vertex and the pairs held each "
                             "frame of the drag and every 10 frames after")
    args = parser.parse_args()
    pull = np.array([0.2, 0.25, 0.3] if args.sideways else [0.0, 0.25, 0.4])
    if args.steps < 1:
        parser.error("--steps must be at least 1")
    if args.integrator in ("both", "scene"):
        run(False, args.steps, 0.0, pull, args.trace)
    if args.integrator in ("both", "implicit"):
        for stiffness in args.solve_stiffness:
            run(True, args.steps, stiffness, pull, args.trace)


if __name__ == "__main__":
    main()
