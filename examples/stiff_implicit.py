"""Stiff cloth with an implicit solver: a nearly inextensible sheet at one step per 60 Hz
frame. The explicit integrators need hundreds of substeps for it (the stability report says
how many); implicit Euler and projective dynamics take the frame in one step.

    python examples/stiff_implicit.py
"""

from __future__ import annotations

import time

import rustcloth
from _quick import pick, size

n = size(32, 12)
scene = rustcloth.load_scene("hanging").replace(
    dt=1 / 60, substeps=1,
    cloth={"nx": n, "ny": n, "k_structural": 20_000.0, "k_shear": 5_000.0},
)
report = scene.stability_report()
for name in rustcloth.INTEGRATORS:
    needed = report.substeps_needed(name)
    print(f"{name:>20}: stable dt {report.stable_dt[name] or float('inf'):.2e} s, "
          f"substeps needed at 1/60 s: {needed}")

seconds = pick(3.0, 0.5)
for name in ("implicit_euler", "projective_dynamics"):
    sim = rustcloth.Simulation(scene.replace(integrator=name))
    start = time.perf_counter()
    sim.advance(seconds)
    wall = time.perf_counter() - start
    print(f"{name}: {seconds:g} s in {sim.steps} steps, {wall * 1e3:.0f} ms wall; "
          f"max stretch {sim.max_stretch():.2%}, energy {sim.energy().total:.3f} J")
    stats = sim.solver_stats() or {}
    print(f"    {stats.get('solves', 0):.0f} solves, "
          f"{stats.get('iterations', 0) / max(stats.get('solves', 1), 1):.1f} iterations "
          f"each, {stats.get('not_converged', 0):.0f} short of the tolerance")
