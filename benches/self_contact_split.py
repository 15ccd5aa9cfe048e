"""Where a frame of newton's 50 x 50 twist goes with implicit Euler and the self-contact term:
the implicit solve (its assembly and multigrid setup, its CG iterations, the rest of the step),
the in-solve pair search at each step's start, the pass after the solve (its search, repulsion,
cap and redo), and the rest, per 1/60 s frame.

    RAYON_NUM_THREADS=1 PYTHONPATH=python python benches/self_contact_split.py \
        [--settle 90] [--frames 60] [--steps-per-frame 2] [--solve-stiffness 30] [--n 50]

Steps ``--settle`` frames, then times ``--frames`` frames (the default window, frames 90-150,
is the wound rope, where the contacts are). Prints the state hash after them (equal for two
builds that step the same).

Every stage is timed inside the step by the wall clock (`sim.profile()`, `solver_stats()`,
`self_collision_stats()`); on one thread of an otherwise idle core that is its CPU time. The
frame's own CPU time (`time.process_time()`) is printed beside it.
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
from twist_common import sample  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--settle", type=int, default=90)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--steps-per-frame", type=int, default=2)
    parser.add_argument("--solve-stiffness", type=float, default=30.0)
    parser.add_argument("--n", type=int, default=peer.N)
    args = parser.parse_args()
    peer.N = args.n
    sim = rustcloth.Simulation(peer.scene("implicit_euler", (1000.0, 250.0, 10.0),
                                          args.steps_per_frame, args.solve_stiffness))
    driver = TwistDriver(sim, turns=peer.RATE_TURNS * peer.END, seconds=peer.END)
    sample(0, sim.positions, sim.triangles)  # the rest lengths
    for _ in range(args.settle * args.steps_per_frame):
        driver.before_step(sim)
        sim.step()
    before = (sim.profile(), sim.solver_stats() or {}, sim.self_collision_stats() or {})
    cpu = time.process_time()
    for _ in range(args.frames * args.steps_per_frame):
        driver.before_step(sim)
        sim.step()
    cpu = time.process_time() - cpu
    profile = sim.profile()
    solver = since(before[1], sim.solver_stats() or {})
    pas = since(before[2], sim.self_collision_stats() or {})
    per_frame = 1e3 / args.frames
    passes = {name: (p.seconds - before[0].passes[name].seconds) * per_frame
              for name, p in profile.passes.items()}
    contact = passes.pop("self_collision", 0.0)
    stages = {k: pas.get(f"{k}_seconds", 0.0) * per_frame
              for k in ("search", "repulsion", "cap", "redo")}
    # The integrator's own time holds the in-solve search, timed apart as the pass.
    in_solve = contact - sum(stages.values())
    integrator = passes.pop("implicit_euler", 0.0) - in_solve
    setup = solver.get("setup_seconds", 0.0) * per_frame
    cg = solver.get("solve_seconds", 0.0) * per_frame
    rows = [
        ("frame (CPU, process_time)", 1e3 * cpu / args.frames),
        ("frame (profile total)", (profile.total_seconds - before[0].total_seconds) * per_frame),
        ("implicit solve: assembly + multigrid setup", setup),
        ("implicit solve: CG", cg),
        ("implicit solve: rest (forces excluded)", integrator - setup - cg),
        ("in-solve pair search (step start)", in_solve),
        ("pass after the solve: search", stages["search"]),
        ("pass after the solve: repulsion", stages["repulsion"]),
        ("pass after the solve: cap", stages["cap"]),
        ("pass after the solve: redo", stages["redo"]),
    ]
    rows += [(f"other pass: {name}", ms) for name, ms in sorted(passes.items())]
    for name, ms in rows:
        print(f"{name:48s} {ms:8.2f} ms/frame")
    solves = max(solver.get("solves", 1), 1)
    substeps = max(pas.get("substeps", 1), 1)
    print(f"CG iterations per solve {solver.get('iterations', 0) / solves:.1f}, "
          f"solves per step {solves / (args.frames * args.steps_per_frame):.2f}, "
          f"held pairs per solve {solver.get('self_pairs', 0) / solves:.0f}")
    print(f"pass per substep: pairs {pas.get('pairs', 0) / substeps:.0f}, "
          f"candidates {pas.get('candidates', 0) / substeps:.0f}, "
          f"boxes {pas.get('boxes_tested', 0) / substeps:.0f}, "
          f"contacts {pas.get('contacts', 0) / substeps:.0f}, "
          f"capped {pas.get('capped', 0) / substeps:.0f}, "
          f"swept {pas.get('swept_substeps', 0) / substeps:.2f}, "
          f"redone {pas.get('redone', 0)}")
    taken = pas.get("pass_from_ahead", 0)
    searches = pas.get("ahead_searches", 0) + substeps - taken
    steps = args.frames * args.steps_per_frame
    print(f"searches a step {searches / steps:.2f}, "
          f"passes taking their pairs from the step's one search {taken / substeps:.2f}, "
          f"vertices outside their budget there {pas.get('pass_outside', 0) / max(taken, 1):.1f}, "
          f"solves given the pairs ahead again {pas.get('ahead_again', 0) / steps:.2f} a step")
    x = sim.positions
    end = sample(args.settle + args.frames, x, sim.triangles)
    print(f"state {hashlib.sha1(x.tobytes()).hexdigest()[:12]} at frame {end['frame']}: "
          f"largest stretch {end['max_stretch']:.2f}, crossings {end['intersections']}")


def since(before: dict[str, float], after: dict[str, float]) -> dict[str, float]:
    """The counters' growth between two readings."""
    return {k: v - before.get(k, 0.0) for k, v in after.items() if isinstance(v, (int, float))}


if __name__ == "__main__":
    main()
