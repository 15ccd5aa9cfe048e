"""How many drawn triangles along cuts face the wrong way: random cuts across `hanging`, the
cloth stepped frame by frame as the demo steps it, and at every frame the triangles of the drawn
mesh (``render_mesh()``) that hold a cut vertex counted when their winding's normal points
against the sum of their vertices' normals. Such a triangle is seen from its other side by the
renderer (two-sided cloth turns the normal by the winding), and shows as a dark or light speck
along the cut.

    PYTHONPATH=python python benches/cut_slivers.py [--cuts 6 --frames 240 --seed 1]
"""

from __future__ import annotations

import argparse

import numpy as np
import rustcloth

FPS = 60.0


def flipped_cut_triangles(sim: rustcloth.Simulation) -> int:
    """Drawn triangles with a cut vertex whose winding disagrees with their vertex normals."""
    mesh = sim.render_mesh()
    tris = mesh.triangles.astype(np.int64)
    cut = (tris >= sim.num_particles).any(axis=1)
    x = mesh.positions.astype(np.float64)[tris[cut]]
    face = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    normals = mesh.normals.astype(np.float64)[tris[cut]].sum(axis=1)
    return int(np.count_nonzero(np.einsum("ij,ij->i", face, normals) < 0.0))


def random_cut(sim: rustcloth.Simulation, rng: np.random.Generator) -> int:
    """A straight stroke seen from the viewer's side (+z) between two random points on the
    cloth's silhouette, sampled as the viewer samples a drag."""
    x = sim.positions
    lo, hi = x.min(axis=0), x.max(axis=0)
    a, b = rng.uniform(lo[:2], hi[:2]), rng.uniform(lo[:2], hi[:2])
    # Start and end beyond the cloth so the stroke crosses it.
    d = (b - a) / max(float(np.linalg.norm(b - a)), 1e-6)
    a, b = a - d * 0.3, b + d * 0.3
    z = float(hi[2]) + 2.0
    rays = [((*(a + (b - a) * t), z), (0.0, 0.0, -1.0)) for t in np.linspace(0.0, 1.0, 40)]
    return sim.sever_stroke(rays)


def run(cuts: int, frames: int, seed: int) -> tuple[int, int]:
    """(flipped cut triangles summed over the frames, springs severed)."""
    rng = np.random.default_rng(seed)
    sim = rustcloth.Simulation("hanging")
    sim.advance(0.5)
    every = max(1, frames // (cuts + 1))
    flipped = severed = done = 0
    for f in range(frames):
        if f % every == every - 1 and done < cuts:
            severed += random_cut(sim, rng)
            done += 1
        sim.advance(1 / FPS)
        flipped += flipped_cut_triangles(sim)
    return flipped, severed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cuts", type=int, default=6)
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3])
    args = parser.parse_args()
    for seed in args.seeds:
        flipped, severed = run(args.cuts, args.frames, seed)
        print(f"seed {seed}: {severed} springs severed, {flipped} flipped cut triangles "
              f"over {args.frames} frames")


if __name__ == "__main__":
    main()
