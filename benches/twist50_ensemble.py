"""newton's 50 x 50 twist (``self_collision.py``'s ``twist50``, 2 steps a frame, ``solve_stiffness``
30) in its wound windows, as an ensemble: CPU ms a 1/60 s frame, cascade retries, pass runs and
CPU a pass run, CG iterations and solves a frame, vertices the cap stopped, from saved states at
``--windows`` seconds, each run once as saved and once with the scene's ``cg_tolerance`` moved
by ``-/+ --perturb`` (relative), so that each build is measured on several trajectories.

    python benches/twist50_ensemble.py --make-states DIR            # once, with the baseline
    RAYON_NUM_THREADS=1 python benches/twist50_ensemble.py --states DIR --packages A B

Why an ensemble: the wound rope is chaotic, and what a frame costs there is set mostly by the
watchdog's cascade retries (each one the step again at 2 or 4 times the substeps). Moving
``cg_tolerance`` by 0.3 % moved the retries in the 20 frames from 3.0 s from 6 to 11 and their
mean frame by 11 % on the same build (docs/notes/contact.md, "2026-12-07 (twistsolves)"), so a
change that is not bitwise cannot be judged from one window: compare the ensemble means, and
the CPU a pass run, which the retries move far less. ``--packages`` runs each package's
``python/`` folder (its ``PYTHONPATH``) in a process of its own, alternated, the states made
once for all of them. A saved state carries the watchdog's hold of the build that made it, so
for a change to the watchdog make states with each build and compare both ensembles.
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "peers"))


def make_states(folder: Path, windows: list[float]) -> None:
    """Steps ``twist50`` from rest to each window's start and pickles its state there."""
    import rustcloth

    import self_collision as bench

    folder.mkdir(parents=True, exist_ok=True)
    sim = rustcloth.Simulation(bench.twist50(2, 30.0))
    driver = bench.twist50_driver(sim)
    for start in sorted(windows):
        while sim.time < start - 1e-9:
            driver.before_step(sim)
            sim.step()
        (folder / f"{start:.2f}.pkl").write_bytes(pickle.dumps(sim.get_state()))
        print(f"state at {sim.time:.3f} s: {sim.watchdog_stats()}", flush=True)


def one(state_file: Path, frames: int, factor: float) -> dict[str, Any]:
    """``frames`` frames from the saved state, its ``cg_tolerance`` times ``factor``."""
    import rustcloth

    import self_collision as bench

    state = pickle.loads(state_file.read_bytes())
    state["scene"] = {**state["scene"], "cg_tolerance": state["scene"]["cg_tolerance"] * factor}
    # The driver turns the edges from where they were at t = 0: made from a restored wound
    # state it would turn them a second time.
    driver = bench.twist50_driver(rustcloth.Simulation(bench.twist50(2, 30.0)))
    sim = rustcloth.Simulation.from_state(state)
    w0, s0, v0 = sim.watchdog_stats() or {}, sim.self_collision_stats() or {}, sim.solver_stats()
    cpu = 0.0
    for _ in range(frames * round(bench.FRAME / sim.dt)):
        driver.before_step(sim)
        t = time.process_time()
        sim.step()
        cpu += time.process_time() - t
    w1, s1, v1 = sim.watchdog_stats() or {}, sim.self_collision_stats() or {}, sim.solver_stats()
    runs = s1["substeps"] - s0["substeps"]
    solves = v1["solves"] - v0["solves"]
    return {"ms_frame": 1e3 * cpu / frames, "retried": w1["retried"] - w0["retried"],
            "pass_runs": runs, "ms_run": 1e3 * cpu / max(runs, 1),
            "solves_frame": solves / frames,
            "its_frame": (v1["iterations"] - v0["iterations"]) / frames,
            "stopped": s1.get("stopped", 0) - s0.get("stopped", 0)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--make-states", type=Path)
    parser.add_argument("--states", type=Path)
    parser.add_argument("--packages", nargs="+", default=[])
    parser.add_argument("--windows", type=float, nargs="+", default=[2.0, 2.5, 3.0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--perturb", type=float, default=0.003)
    parser.add_argument("--one", nargs=2, metavar=("STATE", "FACTOR"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.make_states:
        make_states(args.make_states, args.windows)
        return
    if args.one:
        print(json.dumps(one(Path(args.one[0]), args.frames, float(args.one[1]))))
        return
    if not args.states or not args.packages:
        parser.error("give --make-states DIR, or --states DIR and --packages")
    rows: dict[str, list[dict[str, Any]]] = {p: [] for p in args.packages}
    for start in args.windows:
        for factor in (1.0, 1.0 - args.perturb, 1.0 + args.perturb):
            for package in args.packages:
                env = {**os.environ, "PYTHONPATH": package}
                state = args.states / f"{start:.2f}.pkl"
                out = subprocess.run(
                    [sys.executable, __file__, "--frames", str(args.frames), "--one", str(state),
                     repr(factor)], env=env, capture_output=True, text=True, check=True)
                run = json.loads(out.stdout.strip().splitlines()[-1])
                rows[package].append(run)
                print(f"{start:.2f} s x{factor}: {package}: "
                      + ", ".join(f"{k} {v:.1f}" for k, v in run.items()), flush=True)
    for package, runs in rows.items():
        means = {k: statistics.mean(r[k] for r in runs) for k in runs[0]}
        spread = statistics.stdev(r["ms_frame"] for r in runs)
        print(f"{package}: mean of {len(runs)} runs: "
              + ", ".join(f"{k} {v:.1f}" for k, v in means.items())
              + f" (ms_frame sd {spread:.1f})")


if __name__ == "__main__":
    main()
