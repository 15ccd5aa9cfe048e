"""Energy of cloth landing on contacts at display-frame steps: the table in docs/contact.md.

The ``pile`` scene's square dropped edge first (floor, a 4 cm ball, self-collision;
tests/test_contact_energy.py's ``pile``) with its lower edge 10 cm, 40 cm and 1 m above the
floor, and the 16 x 16 cloth of tests/test_contact_energy.py falling
onto a bare 2 cm ball, for every integrator at 1/60, 1/120 and 1/240 s (explicit schemes take
the substeps their stability report asks for). Nothing does work on the cloth, so its total
energy (kinetic + gravitational + elastic) may only fall: the table gives the start, the
highest total after it, the end, and the gain (highest - start) / start.

    python benches/contact_energy.py                  # every case, about a minute
    python benches/contact_energy.py --integrators implicit_euler --dts 60
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import rustcloth
from rustcloth import Scene, Simulation

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_contact_energy import BALL, CLOTH, pile  # noqa: E402

HEIGHTS = {"pile 10 cm": 0.1, "pile 40 cm": 0.4, "pile 1 m": 1.0}


def bare_ball() -> Scene:
    return Scene(air_drag=0.0, cloth=CLOTH, spheres=[BALL])


def case(base: Scene, integrator: str, dt: float) -> Scene:
    scene = base.replace(integrator=integrator, dt=dt, substeps=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rustcloth.StabilityWarning)
        needed = scene.stability_report(warn=False).substeps_needed() or 1
    return scene.replace(substeps=max(1, needed))


def drive(sim: Simulation, steps: int) -> tuple[float, float]:
    """Runs ``steps`` steps one at a time: the highest total energy (J) at their ends or at the
    start, and the seconds a step took."""
    highest = sim.energy().total
    took = 0.0
    for _ in range(steps):
        t = time.perf_counter()
        sim.step(1)
        took += time.perf_counter() - t
        highest = max(highest, sim.energy().total)
    return highest, took / steps


def run(scene: Scene, seconds: float) -> tuple[float, float, float, float, float]:
    """Start, highest and final total energy (J), the seconds a step took, and the implicit
    solves a step ran (0 for the explicit integrators)."""
    sim = Simulation(scene)
    start = sim.energy().total
    steps = math.ceil(seconds / scene.dt)
    highest, step = drive(sim, steps)
    solves = (sim.profile().solver or {}).get("solves", 0)
    return start, highest, sim.energy().total, step, solves / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--integrators", nargs="*", default=list(rustcloth.INTEGRATORS))
    parser.add_argument("--dts", nargs="*", type=int, default=[60, 120, 240],
                        help="steps per second")
    parser.add_argument("--cases", nargs="*", default=[*HEIGHTS, "bare ball"])
    parser.add_argument("--seconds", type=float, default=1.2,
                        help="simulated time after the drop (the 1 m fall takes 0.45 s)")
    args = parser.parse_args()
    print("| case | integrator | dt | start J | highest J | end J | gain | ms/step | solves/step |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.cases:
        base = bare_ball() if name == "bare ball" else pile(HEIGHTS[name])
        seconds = 0.6 if name == "bare ball" else args.seconds
        for integrator in args.integrators:
            for per_second in args.dts:
                scene = case(base, integrator, 1.0 / per_second)
                start, highest, end, step, solves = run(scene, seconds)
                gain = (highest - start) / abs(start)
                print(f"| {name} | {integrator} | 1/{per_second} | {start:.2f} | {highest:.2f} "
                      f"| {end:.2f} | {gain:+.1%} | {1e3 * step:.2f} | {solves:.2f} |", flush=True)


if __name__ == "__main__":
    main()
