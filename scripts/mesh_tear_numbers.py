"""Measures tearing and cutting on a mesh cloth at about 1k, 4k and 16k vertices: the mean
step, the tearing pass's share of it (the strain check over every spring, which is all it does
while nothing tears), and one scissor cut (``sever_stroke`` across the middle), each against
the same on a grid cloth of as many particles, timed in the same process. Timings on a shared
machine are noisy: read the ratios, not the milliseconds.

Run ``PYTHONPATH=python python scripts/mesh_tear_numbers.py`` (under a minute; ``--steps`` for
more steps per size). Prints a Markdown table (the one in docs/notes/mesh_cloth.md, "Tearing
and cuts: measurements")."""

from __future__ import annotations

import argparse
import time

import numpy as np
import rustcloth


def jittered_square(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """An ``n`` x ``n`` irregular triangulation of a 1 m square centred at (0, 1, 0)."""
    rng = np.random.default_rng(seed)
    h = 1.0 / (n - 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    inner = (i > 0) & (i < n - 1) & (j > 0) & (j < n - 1)
    x = i * h - 0.5 + np.where(inner, rng.uniform(-0.3, 0.3, i.shape) * h, 0)
    y = j * h - 0.5 + np.where(inner, rng.uniform(-0.3, 0.3, j.shape) * h, 0)
    vertices = np.stack([x.ravel(), y.ravel() + 1.0, np.zeros(n * n)], axis=1)
    a = (j[:-1, :-1] * n + i[:-1, :-1]).ravel()
    b, c, d = a + 1, a + n, a + n + 1
    triangles = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return vertices, triangles.astype(np.int64)


#: Tearing on, past a strain neither cloth reaches: the pass runs its check every step and
#: breaks nothing, so both cloths stay whole for the cut.
TEARING = {"max_strain": 10.0}


def stable(scene: rustcloth.Scene) -> rustcloth.Scene:
    """``scene`` at 70 % of its integrator's largest stable step."""
    limit = scene.stability_report(warn=False).limit
    assert limit is not None
    return scene.replace(dt=0.7 * limit)


def mesh_scene(n: int) -> rustcloth.Scene:
    vertices, triangles = jittered_square(n)
    scene = rustcloth.Scene(tearing=TEARING)
    return stable(scene.with_cloth_mesh(vertices, triangles, pins=[{"top": 1e-9}]))


def grid_scene(n: int) -> rustcloth.Scene:
    cloth = {"nx": n, "ny": n, "plane": "xy", "center": [0.0, 1.0, 0.0], "size": [1.0, 1.0],
             "pins": [[i, n - 1] for i in range(n)]}  # held by its top row, as the mesh
    return stable(rustcloth.Scene(tearing=TEARING).replace(cloth=cloth))


def across() -> list[tuple[np.ndarray, np.ndarray]]:
    """A stroke along -z through the middle of either cloth, whatever its plane."""
    return [(np.array([x, 1.0, 2.0]), np.array([0.0, 0.0, -1.0])) for x in np.linspace(-1, 1, 41)]


#: Cuts timed per cloth (each the first on its cloth); the median is reported.
CUTS = 5


def time_cut(sim: rustcloth.Simulation) -> float:
    """Seconds for one ``sever_stroke`` across the middle of ``sim``."""
    started = time.perf_counter()
    severed = sim.sever_stroke(across())
    elapsed = time.perf_counter() - started
    assert severed > 0, "the stroke missed the cloth"
    return elapsed


def measure(scene: rustcloth.Scene, steps: int) -> tuple[int, float, float, float]:
    """Particles, mean step (s), mean tearing pass (s), one cut (s, the median of CUTS)."""
    sim = rustcloth.Simulation(scene)
    sim.step(5)  # first-step setup out of the timing
    before = sim.profile()
    sim.step(steps)
    after = sim.profile()
    step = (after.total_seconds - before.total_seconds) / steps
    tear = (after.passes["tearing"].seconds - before.passes["tearing"].seconds) / steps
    cuts = [time_cut(sim)] + [time_cut(rustcloth.Simulation(scene)) for _ in range(CUTS - 1)]
    cut = sorted(cuts)[CUTS // 2]
    return sim.num_particles, step, tear, cut


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="steps timed per size (400)")
    args = parser.parse_args()
    print("| vertices | step (ms) | tearing pass (ms) | tearing / step | one cut (ms) "
          "| cut / step | mesh / grid: step, tearing, cut |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    for n in (32, 64, 128):
        count, step, tear, cut = measure(mesh_scene(n), args.steps)
        _, g_step, g_tear, g_cut = measure(grid_scene(n), args.steps)
        print(f"| {count} | {step * 1e3:.2f} | {tear * 1e3:.3f} | {tear / step:.3f} "
              f"| {cut * 1e3:.2f} | {cut / step:.2f} "
              f"| {step / g_step:.2f}, {tear / g_tear:.2f}, {cut / g_cut:.2f} |")


if __name__ == "__main__":
    main()
