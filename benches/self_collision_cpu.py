"""CPU time per 1/60 s frame of newton's 50 x 50 twist (benches/peers/impl_rustcloth_twist.py),
for comparing two builds on a loaded machine, where wall times are not steady.

    RAYON_NUM_THREADS=1 PYTHONPATH=BUILD python benches/self_collision_cpu.py [--settle 2.0]
        [--frames 10]

Steps to ``--settle`` s, then times ``--frames`` frames by ``time.process_time()``. Prints
the state hash after them (equal for two builds whose pass gives the same result) and the CPU
and wall milliseconds per frame.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))

import impl_rustcloth_twist as peer  # noqa: E402
import rustcloth  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--settle", type=float, default=2.0)
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()
    sim = rustcloth.Simulation(peer.scene("implicit_euler", (1000.0, 250.0, 10.0)))
    driver = TwistDriver(sim, turns=peer.RATE_TURNS * peer.END, seconds=peer.END)
    while sim.time < args.settle - 0.5 * sim.dt:
        driver.before_step(sim)
        sim.step()
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(args.frames * peer.STEPS_PER_FRAME):
        driver.before_step(sim)
        sim.step()
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    digest = hashlib.sha1(sim.positions.tobytes()).hexdigest()[:12]
    print(f"state {digest} cpu {1e3 * cpu / args.frames:.1f} ms per frame "
          f"wall {1e3 * wall / args.frames:.1f} ms per frame")


if __name__ == "__main__":
    main()
