"""The case table of docs/stability.md: every hard case of the stability suite run with every
integrator, with the stable dt the estimate gives and what happened.

    .venv/bin/python benches/stability_table.py > /tmp/table.md

Each cell: "holds" (every step finite, bounded, outside the colliders, pins put), "rescued"
(the watchdog retried steps with more substeps: how many, and the most substeps used), or
"reported" (SimulationDiverged with the state rolled back; the reason and the step). The
checks are those of tests/stability/checks.py, which the tests assert.
"""

from __future__ import annotations

import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

import rustcloth  # noqa: E402
from stability.checks import hanging, run_checked, stable  # noqa: E402

warnings.simplefilter("ignore", rustcloth.StabilityWarning)
warnings.simplefilter("ignore", RuntimeWarning)

INTEGRATORS = list(rustcloth.INTEGRATORS)


def outcome(sim: rustcloth.Simulation, steps: int, bound: float = 100.0,
            dragged: frozenset[int] = frozenset()) -> str:
    e = run_checked(sim, steps, bound, dragged)
    stats = sim.watchdog_stats()
    if e is not None:
        return f"reported ({e.reason}, step {e.step})"
    if stats["retried"]:
        return f"rescued ({stats['retried']}x, <= {stats['max_substeps_used']} substeps)"
    return "holds"


def stiff(integrator: str, retry: bool) -> tuple[rustcloth.Simulation, int]:
    watchdog = {"max_stretch": 1.2, "on_trouble": "substep" if retry else "raise"}
    scene = hanging(integrator=integrator, cloth={"k_structural": 1e5}, watchdog=watchdog)
    return rustcloth.Simulation(scene), 200


def large_dt(integrator: str, dt: float) -> tuple[rustcloth.Simulation, int]:
    scene = hanging(integrator=integrator, dt=dt, substeps=2, air_drag=0.001,
                    watchdog={"max_stretch": 1.3, "on_trouble": "substep"})
    return rustcloth.Simulation(scene), 30


def mass_ratio(integrator: str) -> tuple[rustcloth.Simulation, int]:
    scene = stable(hanging(16, integrator=integrator, air_drag=0.01, floor={"height": 0.0},
                           cloth={"k_structural": 2000.0, "damping": 0.05}))
    sim = rustcloth.Simulation(scene)
    i, j = np.meshgrid(np.arange(16), np.arange(16))
    sim.set_masses(np.where((i + j).ravel() % 2 == 0, 1e-3, 1.0))
    return sim, 120 if integrator == "implicit_euler" else 400


def light(integrator: str) -> tuple[rustcloth.Simulation, int]:
    scene = stable(hanging(integrator=integrator, cloth={"particle_mass": 1e-6}))
    return rustcloth.Simulation(scene), 300


def start_from(integrator: str, kind: str) -> tuple[rustcloth.Simulation, int]:
    scene = stable(hanging(integrator=integrator, air_drag=0.002, cloth={"damping": 0.05}))
    sim = rustcloth.Simulation(scene)
    x = sim.positions.copy()
    if kind == "point":
        x[:] = [0.3, 1.0, -0.2]
    elif kind == "pairs":
        odd = np.arange(sim.num_particles) % sim.nx % 2 == 1
        x[odd] = x[np.flatnonzero(odd) - 1]
    else:
        x = np.random.default_rng(6).uniform(-0.5, 0.5, x.shape) + [0, 1.5, 0]
        probe = rustcloth.Simulation(scene)
        probe.set_positions(x)
        limit = 2 * (1 + probe.max_stretch())
        sim = rustcloth.Simulation(scene.replace(watchdog={"max_stretch": limit}))
    sim.set_positions(x)
    return sim, 1500


def impact(integrator: str, speed: float) -> tuple[rustcloth.Simulation, int]:
    scene = rustcloth.load_scene("drape").replace(
        integrator=integrator, cloth={"nx": 20, "ny": 20, "pins": []},
        substeps=32 if integrator == "explicit_euler" else 2)
    sim = rustcloth.Simulation(scene)
    sim.set_velocities(np.tile([0.0, -speed, 0.0], (sim.num_particles, 1)))
    return sim, 150


def drag(integrator: str) -> tuple[rustcloth.Simulation, int, frozenset[int]]:
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator, air_drag=0.002)))
    corner = sim.num_particles - 1
    sim.pin(corner, sim.positions[corner] + [10.0, 0.0, 0.0])
    run_checked(sim, 1, dragged={corner})
    sim.unpin(corner)
    return sim, 300, frozenset()


def cut(integrator: str, how: str) -> tuple[rustcloth.Simulation, int]:
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator, air_drag=0.002,
                                              floor={"height": 0.0})))
    if how == "stretched":
        grabbed = sim.nx // 2
        sim.pin(grabbed, sim.positions[grabbed] - [0, 0.5, 0])
        run_checked(sim, 100, dragged={grabbed})
        for i in range(sim.nx):
            sim.cut(sim.ny // 2 * sim.nx + i)
        sim.unpin(grabbed)
    else:
        step = 2 if how == "every other" else 1
        for p in range(0, sim.num_particles, step):
            sim.cut(p)
    return sim, 300


def far(integrator: str) -> tuple[rustcloth.Simulation, int]:
    scene = stable(hanging(integrator=integrator, air_drag=0.002,
                           cloth={"center": [1e4, 1e4, 0.0]}))
    return rustcloth.Simulation(scene), 300


CASES = [
    ("very stiff springs, k dt^2/m = 100, watchdog raise", lambda i: stiff(i, False)),
    ("very stiff springs, watchdog substep", lambda i: stiff(i, True)),
    ("dt = 1/30 s, 2 substeps, watchdog substep", lambda i: large_dt(i, 1 / 30)),
    ("dt = 1/15 s, 2 substeps, watchdog substep", lambda i: large_dt(i, 1 / 15)),
    ("1000:1 masses (checkerboard), floor", mass_ratio),
    ("1e-6 kg particles", light),
    ("collapsed into one point", lambda i: start_from(i, "point")),
    ("coincident particle pairs", lambda i: start_from(i, "pairs")),
    ("scrambled start, watchdog at 2x its stretch", lambda i: start_from(i, "scrambled")),
    ("10 m/s into floor and sphere", lambda i: impact(i, 10.0)),
    ("100 m/s into floor and sphere", lambda i: impact(i, 100.0)),
    ("pin dragged 10 m in one step, released", drag),
    ("cut across while stretched", lambda i: cut(i, "stretched")),
    ("every other particle cut", lambda i: cut(i, "every other")),
    ("every particle cut", lambda i: cut(i, "all")),
    ("10 km from the origin", far),
]


def main() -> None:
    print("| case | " + " | ".join(INTEGRATORS) + " |")
    print("|---|" + "---|" * len(INTEGRATORS))
    for name, build in CASES:
        cells = []
        for integrator in INTEGRATORS:
            made = build(integrator)
            sim, steps = made[0], made[1]
            dragged = made[2] if len(made) > 2 else frozenset()
            limit = sim.stable_dt()
            dt = f"dt {sim.dt:.2g}" + ("" if limit is None else f" / {limit:.2g}")
            bound = 2e4 if "10 km" in name else 100.0
            try:
                cells.append(f"{outcome(sim, steps, bound, dragged)}; {dt}")
            except AssertionError as e:
                # run_checked asserts finiteness first: this state is finite.
                cells.append(f"finite, but {str(e).splitlines()[0]}; {dt}")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
