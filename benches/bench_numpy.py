"""rustcloth against a vectorised numpy implementation of the same model, in one run.

    python benches/bench_numpy.py [--sizes 64 128 256] [--seconds 3]

Both step the same scene (symplectic Euler, the 12-neighbour springs, gravity, damping, two
pinned corners) on the same machine, interleaved, so the ratio holds even on a noisy machine.
numpy is rustcloth's reference model (``rustcloth.reference``) in float32, vectorised by grid
slicing: no Python loop over particles or springs. Also reports rustcloth's memory per particle
and the cost of each optional effect.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle BLAS threads would steal the cores

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
from rustcloth.reference import ReferenceCloth  # noqa: E402


def scene(n: int, **changes) -> rustcloth.Scene:
    return rustcloth.Scene(
        dt=0.001,
        cloth={"nx": n, "ny": n, "size": [0.01 * (n - 1)] * 2, "plane": "xy",
               "center": [0.0, 1.0, 0.0], "particle_mass": 1e-3, "k_structural": 50.0,
               "k_shear": 50.0, "k_bend": 50.0, "damping": 0.01, "pins": ["top_corners"]},
    ).replace(**changes)


def steps_per_second(step, budget: float) -> float:
    """Median rate over repeated timed batches that fill `budget` seconds."""
    step(2)
    t = time.perf_counter()
    step(5)
    per = max((time.perf_counter() - t) / 5, 1e-7)
    batch = max(1, int(0.2 / per))
    rates = []
    end = time.perf_counter() + budget
    while time.perf_counter() < end or len(rates) < 3:
        t = time.perf_counter()
        step(batch)
        rates.append(batch / (time.perf_counter() - t))
    return statistics.median(rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256])
    parser.add_argument("--seconds", type=float, default=3.0, help="timing budget per run")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"numpy {np.__version__}, rustcloth {rustcloth.__version__}")
    print(f"{'size':>9} {'rustcloth steps/s':>18} {'numpy steps/s':>14} {'ratio':>7} "
          f"{'ms/step':>8} {'B/particle':>11}")
    for n in args.sizes:
        sc = scene(n)
        sim = rustcloth.Simulation(sc)
        ref = ReferenceCloth(sc.to_dict(), dtype=np.float32)
        ours = steps_per_second(sim.step, args.seconds)
        theirs = steps_per_second(ref.step, args.seconds)
        # Same model: both trajectories agree after the timed runs are replayed from rest.
        a, b = rustcloth.Simulation(sc), ReferenceCloth(sc.to_dict(), dtype=np.float32)
        a.step(100)
        b.step(100)
        gap = float(np.abs(a.positions - b.positions).max())
        print(f"{n:>4}x{n:<4} {ours:>18,.0f} {theirs:>14,.0f} {ours / theirs:>6.1f}x "
              f"{1e3 / ours:>8.3f} {sim.memory_bytes() / sim.num_particles:>11.0f}"
              f"   (max position gap after 100 steps {gap:.1e} m)")
    print("\neffects at 128x128 (each removed in turn from a scene with all of them):")
    full = dict(air_drag=0.001, floor={"height": 0.0}, spheres=[{"center": [0, 0.3, 0.5]}])
    variants = {
        "all effects": {},
        "no bending springs": {"cloth": {"k_bend": 0.0}},
        "no shear springs": {"cloth": {"k_shear": 0.0}},
        "no air drag": {"air_drag": 0.0},
        "no gravity": {"gravity": [0.0, 0.0, 0.0]},
        "no floor": {"floor": None},
        "no spheres": {"spheres": []},
    }
    base = scene(128, **full)
    rates = {name: steps_per_second(rustcloth.Simulation(base.replace(**ch)).step,
                                    args.seconds / 2) for name, ch in variants.items()}
    for name, rate in rates.items():
        print(f"  {name:<20} {1e3 / rate:7.4f} ms/step  "
              f"(saves {1 - rates['all effects'] / rate:.0%} of the full scene's time)")


if __name__ == "__main__":
    main()
