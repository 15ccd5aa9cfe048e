"""What one call on a tiny Simulation costs, for two builds side by side: the binding's
per-call overhead (argument reading, locking, conversion), not the physics. Each build is
imported by its own interpreter from its package folder (``--a``, ``--b``: folders that hold
``rustcloth/``), the two interleaved within every repeat; ``sim.time``, a getter that reads
no argument, is the reference that both builds share.

    python benches/call_overhead.py --a /tmp/before/python --b python --repeats 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import timeit

# Each a statement on `sim` (a 4 x 4 cloth, particle 5 grabbed) and `np`.
CALLS = {
    "sim.time": "sim.time",
    "sim.positions": "sim.positions",
    "sim.step(1)": "sim.step(1)",
    "sim.drag_to(target)": "sim.drag_to((0.1, 0.2, -0.3))",
    "sim.pick(o, d)": "sim.pick((0.5, 0.5, 2.0), (0.0, 0.0, -1.0))",
    "sim.pin(3, target)": "sim.pin(3, (0.0, 0.1, 0.0))",
    "sim.set_positions(a)": "sim.set_positions(p)",
}


def measure(number: int) -> dict[str, float]:
    """Microseconds per call of each of CALLS, best of 5 rounds of ``number`` calls."""
    import numpy as np
    import rustcloth

    sim = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4}))
    sim.grab(5)
    p = sim.positions.copy()
    space = {"sim": sim, "np": np, "p": p}
    return {
        name: 1e6 * min(timeit.repeat(stmt, globals=space, number=number, repeat=5)) / number
        for name, stmt in CALLS.items()
    }


def run_once(package: str, number: int) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(package), RAYON_NUM_THREADS="1")
    args = [sys.executable, os.path.abspath(__file__), "--measure", str(number)]
    out = subprocess.run(args, env=env, cwd="/", capture_output=True, text=True, check=True)
    result: dict[str, float] = json.loads(out.stdout.splitlines()[-1])
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--a", help="package folder of build A (the reference)")
    p.add_argument("--b", help="package folder of build B")
    p.add_argument("--repeats", type=int, default=3, help="interleaved repeats")
    p.add_argument("--number", type=int, default=20000, help="calls per timing round")
    p.add_argument("--measure", type=int, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.measure:
        print(json.dumps(measure(args.measure)))
        return 0
    if not (args.a and args.b):
        p.error("--a and --b are required")
    times: dict[str, list[dict[str, float]]] = {"a": [], "b": []}
    for k in range(args.repeats):
        for key in ("a", "b") if k % 2 == 0 else ("b", "a"):
            times[key].append(run_once(getattr(args, key), args.number))
    print(f"{'call':>22} {'A us':>8} {'B us':>8} {'B - A':>8} {'A/time':>7} {'B/time':>7}"
          f"  (medians of {args.repeats}, interleaved)")
    median = {key: {name: statistics.median(t[name] for t in runs) for name in CALLS}
              for key, runs in times.items()}
    a, b = median["a"], median["b"]
    for name in CALLS:
        print(f"{name:>22} {a[name]:8.3f} {b[name]:8.3f} {b[name] - a[name]:+8.3f} "
              f"{a[name] / a['sim.time']:7.1f} {b[name] / b['sim.time']:7.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
