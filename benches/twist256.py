"""The shipped twist at 256 x 256, turned by its driver to frame 60: whether the watchdog's
cascade hold keeps the wound cloth whole, from the shipped start or a perturbed one.

    python benches/twist256.py                      # the shipped start
    python benches/twist256.py --seed 1 --eps 1e-6  # every free particle moved up to 1 um

The scene as ``benches/self_collision.py``'s ``shipped`` sets it (its ``thickness`` limited to
0.4 of the grid spacing), ``rustcloth.drivers.TwistDriver``. Every 5 frames it prints the
largest stretch of a grid edge against the start's spacing (``l / h - 1``) and the watchdog's
counters; at frame 60, the crossings the independent checker finds
(``benches/peers/tri_check.py``). The twist is chaotic once wound, so a perturbation far below
the contact distance (3 mm, 1.57 mm at this size) gives another trajectory from about frame 40,
where the cascades start: one trajectory says little about a threshold such as
``CASCADE_LARGE``. About 25 minutes a run on one core of the 2-core Xeon; the result does not
depend on the thread count (the step is bitwise the same on any).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import rustcloth  # noqa: E402
import tri_check  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402

from self_collision import shipped  # noqa: E402

N = 256


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbation")
    parser.add_argument("--eps", type=float, default=0.0,
                        help="each free particle moved by up to this much on each axis (m)")
    parser.add_argument("--frames", type=int, default=60)
    args = parser.parse_args()
    sim = rustcloth.Simulation(shipped("twist", N))
    start = np.array(sim.positions).reshape(N, N, 3)
    spacing = np.linalg.norm(start[0, 1] - start[0, 0])
    if args.eps > 0:
        x = start.reshape(-1, 3).copy()
        free = ~np.asarray(sim.pinned, dtype=bool)
        rng = np.random.default_rng(args.seed)
        x[free] += rng.uniform(-args.eps, args.eps, (int(free.sum()), 3))
        sim.set_positions(x)
    driver = TwistDriver(sim)
    steps_per_frame = max(1, round(1 / 60 / sim.dt))

    def stretch() -> float:
        x = np.asarray(sim.positions).reshape(N, N, 3)
        across = np.linalg.norm(x[:, 1:] - x[:, :-1], axis=2).max()
        along = np.linalg.norm(x[1:] - x[:-1], axis=2).max()
        return float(max(across, along) / spacing - 1)

    print(f"seed {args.seed}, eps {args.eps} m", flush=True)
    began = time.perf_counter()
    for frame in range(1, args.frames + 1):
        for _ in range(steps_per_frame):
            driver.before_step(sim)
            sim.step(1)
        if frame % 5 == 0:
            print(f"frame {frame}: largest stretch {stretch():.3f}, "
                  f"watchdog {sim.watchdog_stats()}, {time.perf_counter() - began:.0f} s",
                  flush=True)
    positions = np.asarray(sim.positions, dtype=np.float64)
    print("crossings", tri_check.count(positions, np.asarray(sim.triangles)), flush=True)


if __name__ == "__main__":
    main()
