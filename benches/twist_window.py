"""The shipped ``twist`` (32 x 32, turned by ``TwistDriver``) in its wound window: CPU ms a
1/60 s frame, CG iterations a solve, the solver's setup and solve ms a frame, pairs held a solve,
over frames ``--start`` + 1 to ``--frames``; with ``--check`` also the largest spring stretch and
the crossings by the independent checker (``benches/peers/tri_check.py``) every 20 frames.

    RAYON_NUM_THREADS=1 python benches/twist_window.py [--frames 240] [--start 120] [--check]

Compare builds by running it with each build's package on ``PYTHONPATH``, alternated, in one
window: the wound rope is chaotic, so a change of rounding moves its trajectory; compare the
frame's cost, and stretch and crossings over the whole run, not positions.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import rustcloth
from rustcloth.drivers import TwistDriver

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import tri_check  # noqa: E402

FRAME = 1 / 60


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--start", type=int, default=120)
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    sim = rustcloth.Simulation(rustcloth.load_scene("twist"))
    driver = TwistDriver(sim)
    triangles = np.asarray(sim.triangles, dtype=np.int64)
    worst, crossings = 0.0, 0
    t0, s0 = time.process_time(), sim.solver_stats()
    for f in range(1, args.frames + 1):
        if f == args.start + 1:
            t0, s0 = time.process_time(), sim.solver_stats()
        while sim.time < f * FRAME - 1e-9:
            driver.before_step(sim)
            sim.step()
        if args.check and f % 20 == 0:
            worst = max(worst, float(sim.max_stretch()))
            crossings += tri_check.count(np.asarray(sim.positions, np.float64), triangles)
    cpu = time.process_time() - t0
    s1, n = sim.solver_stats(), args.frames - args.start
    solves = max(1, s1["solves"] - s0["solves"])
    iterations = (s1["iterations"] - s0["iterations"]) / solves
    print(f"{rustcloth.__file__}: frames {args.start + 1}-{args.frames}: "
          f"CPU {1e3 * cpu / n:.1f} ms a frame, CG {iterations:.1f} "
          f"iterations a solve (most {s1['most_iterations']}), setup "
          f"{1e3 * (s1['setup_seconds'] - s0['setup_seconds']) / n:.1f} and solve "
          f"{1e3 * (s1['solve_seconds'] - s0['solve_seconds']) / n:.1f} ms a frame, "
          f"{(s1['self_pairs'] - s0['self_pairs']) / solves:.0f} pairs held a solve")
    if args.check:
        print(f"largest stretch {worst:.3f} (every 20 frames), crossings {crossings}")


if __name__ == "__main__":
    main()
