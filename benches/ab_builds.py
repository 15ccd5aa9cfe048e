"""Two builds of rustcloth side by side: the peer harness's rustcloth measurement
(benches/peers/impl_rustcloth.py: the hanging N x N cloth, k = 50 N/m, m = 1 g, dt = 1 ms) run
by two interpreters, each importing its own build, interleaved within every repeat, medians
and their ratio reported. This is how a change of the core (a refactor, an optimisation) shows
it did not slow the step: in one run, on one machine, under the same load.

    python benches/ab_builds.py --a /tmp/venv-before/bin/python --b .venv/bin/python \\
        --sizes 128 256 512 --threads 1 2 --repeats 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
IMPL = HERE / "peers" / "impl_rustcloth.py"


def run_once(python: str, n: int, threads: int, colliders: bool) -> dict[str, float]:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    # From outside the repository, so each interpreter imports the build installed in it.
    args = [python, str(IMPL), "--n", str(n), "--threads", str(threads)]
    if colliders:
        args.append("--colliders")
    out = subprocess.run(args, env=env, cwd="/", capture_output=True, text=True, check=True)
    line = next(x for x in out.stdout.splitlines() if x.startswith("RESULT "))
    result: dict[str, float] = json.loads(line[len("RESULT "):])
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--a", required=True, help="interpreter with build A (the reference)")
    p.add_argument("--b", required=True, help="interpreter with build B")
    p.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512], help="N of N x N")
    p.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="rayon threads")
    p.add_argument("--colliders", action="store_true", help="with the floor and a sphere")
    p.add_argument("--repeats", type=int, default=5, help="interleaved repeats per case")
    args = p.parse_args(argv)
    print(f"{'case':>16} {'A ms/step':>10} {'B ms/step':>10} {'B / A':>7}  (medians of "
          f"{args.repeats}, interleaved)")
    for n in args.sizes:
        for threads in args.threads:
            times: dict[str, list[float]] = {"a": [], "b": []}
            states: dict[str, set[float]] = {"a": set(), "b": set()}
            for k in range(args.repeats):
                for key in ("a", "b") if k % 2 == 0 else ("b", "a"):
                    r = run_once(getattr(args, key), n, threads, args.colliders)
                    times[key].append(r["ms_per_step"])
                    states[key].add(r["min_y"])
            a, b = statistics.median(times["a"]), statistics.median(times["b"])
            same = "same state" if states["a"] == states["b"] else f"STATES DIFFER {states}"
            print(f"{n:>5} x {n:<4} {threads}t {a:10.4f} {b:10.4f} {b / a:7.3f}  {same}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
