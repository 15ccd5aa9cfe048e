"""What the thread-count tests run in a subprocess (rayon's pool is global: its size is fixed by
``RAYON_NUM_THREADS`` when the process first steps). ``python reliability_worker.py`` prints one
JSON object: a digest of the state after stepping each grid shape of :data:`SHAPES`, of each
integrator with every optional pass on a grid of many chunks, and the exact bits of
``energy()`` on states with many chunks. The parent runs it at several thread counts, and in
process, and compares."""

from __future__ import annotations

import json
import os
import random
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

import rustcloth  # noqa: E402
from conftest import full_digest, small_scene  # noqa: E402

# Grids where the force pass's chunks meet the rows unevenly (1025 x 2, 2049 x 2, and 1500 x 64,
# which splits differently at 16 threads), very wide and very tall grids on both sides of the
# 2,048-particle chunk and its multiples, and a seeded sample of other shapes.
EDGE_SHAPES = [
    (1025, 2), (2049, 2), (1500, 64), (2, 1025), (2, 2049), (4097, 2), (2, 4097),
    (2048, 2), (1024, 2), (2047, 3), (3, 2047), (683, 3), (64, 64), (129, 127),
    (8193, 2), (2, 8193),
]


def _sampled_shapes(count: int, seed: int = 11) -> list[tuple[int, int]]:
    rng = random.Random(seed)
    shapes = []
    while len(shapes) < count:
        nx = rng.choice([2, 3, 5, rng.randint(2, 40), rng.randint(40, 700), rng.randint(700, 5000)])
        ny = rng.choice([2, 3, rng.randint(2, 40), rng.randint(40, 400)])
        if rng.random() < 0.5:
            nx, ny = ny, nx
        if nx * ny <= 60_000:
            shapes.append((nx, ny))
    return shapes


SHAPES = list(dict.fromkeys(EDGE_SHAPES + _sampled_shapes(14)))


def shape_scene(nx: int, ny: int) -> rustcloth.Scene:
    # Soft enough to be stable at dt = 1 ms for any spacing (stability depends on k / m only).
    return small_scene(cloth={"nx": nx, "ny": ny, "size": [1.0, 0.5], "pins": ["top_edge"]})


def every_pass_scene(integrator: str, nx: int = 160, ny: int = 100) -> rustcloth.Scene:
    """A cloth over a sphere and a floor with drag, strain limiting and the watchdog on: every
    optional pass of the step. Explicit Euler gets the substeps it needs."""
    substeps = {"explicit_euler": 24}.get(integrator, 2)
    return rustcloth.load_scene("drape").replace(
        integrator=integrator,
        substeps=substeps,
        air_drag=0.001,
        cloth={"nx": nx, "ny": ny, "pins": ["corners"]},
        strain_limit={"max_strain": 0.1, "iterations": 3},
        watchdog={"max_stretch": 3.0, "on_trouble": "substep"},
    )


def energy_bits(sim: rustcloth.Simulation) -> list[str]:
    return [float(x).hex() for x in sim.energy()]


def run() -> dict[str, object]:
    out: dict[str, object] = {"threads": os.environ.get("RAYON_NUM_THREADS")}
    shapes = {}
    for nx, ny in SHAPES:
        sim = rustcloth.Simulation(shape_scene(nx, ny))
        sim.step(3)
        assert np.isfinite(sim.positions).all()
        shapes[f"{nx}x{ny}"] = full_digest(sim)
    out["shapes"] = shapes
    integrators = {}
    energies = {}
    for name in rustcloth.INTEGRATORS:
        sim = rustcloth.Simulation(every_pass_scene(name))
        sim.step(4)
        integrators[name] = full_digest(sim)
        energies[name] = energy_bits(sim)
    out["integrators"] = integrators
    big = rustcloth.Simulation(shape_scene(300, 200))  # 60,000 particles: 15 sum chunks
    big.step(2)
    rng = np.random.default_rng(7)
    big.set_velocities(rng.normal(size=(big.num_particles, 3)).astype(np.float32))
    energies["random_velocities"] = energy_bits(big)
    big.set_velocities(np.full((big.num_particles, 3), 1e20, np.float32))
    energies["1e20_m_per_s"] = energy_bits(big)
    out["energies"] = energies
    return out


if __name__ == "__main__":
    print(json.dumps(run()))
