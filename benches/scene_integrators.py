"""The self-collision scenes with symplectic Euler at 1 ms steps (what they all used before
``fold`` moved) against implicit Euler at two steps per 1/60 s frame with self-contact held
inside its solve (``solve_stiffness``): CPU time per frame on one thread, crossings by the
independent ``tri_check`` every 30 frames, and what the scene must do
(``tests/test_scene_behaviour.py``: fold over its bar, pile).

    RAYON_NUM_THREADS=1 PYTHONPATH=python python benches/scene_integrators.py \
        [--scenes twist pile fold] [--stiffness 30] [--steps-per-frame 2]

``twist`` is turned by ``TwistDriver`` (2 turns in 4 s) for 4 s, ``pile`` runs 3 s, ``fold`` 5 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

here = Path(__file__).resolve().parent
sys.path.insert(0, str(here / "peers"))
sys.path.insert(0, str(here.parent / "tests"))

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
import tri_check  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402
from test_scene_behaviour import pile_shape  # noqa: E402

SECONDS = {"twist": 4.0, "pile": 3.0, "fold": 5.0}
# Symplectic Euler's substeps per 1 ms step in each scene.
SUBSTEPS = {"twist": 1, "pile": 2, "fold": 1}


def variant(name: str, implicit: bool, stiffness: float, steps: int) -> rustcloth.Scene:
    base = rustcloth.load_scene(name)
    if not implicit:
        return base.replace(integrator="symplectic_euler", dt=0.001, substeps=SUBSTEPS[name],
                            self_collision={**base.self_collision, "solve_stiffness": 0.0})
    return base.replace(integrator="implicit_euler", dt=1.0 / (60 * steps), substeps=1,
                        self_collision={**base.self_collision, "solve_stiffness": stiffness})


def behaviour(name: str, sim: rustcloth.Simulation) -> str:
    """What the scene's test checks, measured."""
    p = sim.positions
    if name == "fold":
        on_bar = int((np.abs(p[:, 1] - 0.6) < 0.05).sum())
        return (f"y {p[:, 1].min():.3f}..{p[:, 1].max():.3f} (test: > 0.05, < 0.65), "
                f"on bar {on_bar} (>= 20), halves {(p[:, 2] > 0).mean():.2f} (0.3-0.7)")
    if name == "pile":
        area, height = pile_shape(sim)
        speed = float(np.linalg.norm(sim.velocities, axis=1).max())
        return (f"footprint {area:.3f} m^2 (< 0.333), height {height:.3f} m (> 0.03), "
                f"fastest {speed:.2f} m/s (< 0.5)")
    edges = np.linalg.norm(np.diff(p.reshape(sim.ny, sim.nx, 3), axis=1), axis=2)
    rest = sim.scene.cloth["size"][0] / (sim.nx - 1)
    return f"largest stretch along the axis {edges.max() / rest - 1:.2f}"


def run(name: str, implicit: bool, stiffness: float, steps: int) -> None:
    sim = rustcloth.Simulation(variant(name, implicit, stiffness, steps))
    driver = TwistDriver(sim) if name == "twist" else None
    frames = round(SECONDS[name] * 60)
    per_frame = round(1.0 / 60 / sim.dt)
    cpu, crossings = 0.0, []
    for frame in range(1, frames + 1):
        c0 = time.process_time()
        for _ in range(per_frame):
            if driver is not None:
                driver.before_step(sim)
            sim.step()
        cpu += time.process_time() - c0
        if frame % 30 == 0:
            crossings.append(tri_check.count(sim.positions.astype(np.float64), sim.triangles))
    label = f"implicit_euler, {steps} steps a frame, solve_stiffness {stiffness:g}" if implicit \
        else f"{sim.scene.integrator}, dt {sim.dt * 1e3:g} ms x {sim.scene.substeps}"
    print(f"{name:6s} {label:56s} {1e3 * cpu / frames:8.2f} CPU ms/frame, crossings at "
          f"{len(crossings)} checks: {max(crossings)} at most; {behaviour(name, sim)}",
          flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["twist", "pile", "fold"])
    parser.add_argument("--stiffness", type=float, default=30.0)
    parser.add_argument("--steps-per-frame", type=int, default=2)
    args = parser.parse_args()
    for name in args.scenes:
        for implicit in (True, False):
            run(name, implicit, args.stiffness, args.steps_per_frame)


if __name__ == "__main__":
    main()
