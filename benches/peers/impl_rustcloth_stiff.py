"""rustcloth on the stiff drape (stiff_scene.py): ``implicit_euler`` with a preconditioner and
tolerance, or ``projective_dynamics`` with an iteration count. Also runs against an older
rustcloth (the "before" of docs/stiff.md), passing only the keys given on the command line.

    python impl_rustcloth_stiff.py --n 128 --frames 120 --integrator implicit_euler \\
        --preconditioner multigrid --tolerance 1e-4

The rayon pool size is fixed per process: the runner sets ``RAYON_NUM_THREADS``.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import rustcloth  # noqa: E402
from stiff_scene import run, rustcloth_scene  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=128)
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--integrator", default="implicit_euler")
    p.add_argument("--preconditioner", default=None)
    p.add_argument("--tolerance", type=float, default=1e-4, help="implicit_euler: CG tolerance")
    p.add_argument("--max-iterations", type=int, default=5000)
    p.add_argument("--pd-iterations", type=int, default=None)
    p.add_argument("--pd-tolerance", type=float, default=None)
    p.add_argument("--substeps", default="1",
                   help="substeps per frame, or 'auto': the fewest the stability report "
                        "says the integrator needs")
    p.add_argument("--name", default="rustcloth")
    p.add_argument("--out", default=None, help="save the final positions (npz)")
    args = p.parse_args()
    solver = {"cg_tolerance": args.tolerance, "cg_max_iterations": args.max_iterations}
    for key, value in [("preconditioner", args.preconditioner),
                       ("pd_iterations", args.pd_iterations),
                       ("pd_tolerance", args.pd_tolerance)]:
        if value is not None:
            solver[key] = value
    scene = rustcloth.Scene.from_dict(rustcloth_scene(args.n, args.integrator, **solver))
    if args.substeps == "auto":
        needed = scene.stability_report(warn=False).substeps_needed()
        scene = scene.replace(substeps=needed or 1)
    else:
        scene = scene.replace(substeps=int(args.substeps))

    def stats(sim: rustcloth.Simulation) -> dict:
        s = sim.solver_stats() or {}
        solves = max(s.get("solves", 0), 1)
        return {
            "threads": int(os.environ.get("RAYON_NUM_THREADS", "0")),
            "iterations_mean": s.get("iterations", 0) / solves,
            "iterations_max": s.get("most_iterations"),
            "last_residual": s.get("last_residual"),
            "not_converged": s.get("not_converged"),
            "setup_ms_per_frame": 1e3 * s["setup_seconds"] / solves if "setup_seconds" in s
            else None,
            "solve_ms_per_frame": 1e3 * s["solve_seconds"] / solves if "solve_seconds" in s
            else None,
            "factorizations": s.get("factorizations"),
            "substeps": sim.substeps,
        }

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        run(args.name, args.n, args.frames, build=lambda: rustcloth.Simulation(scene),
            step=lambda sim: sim.step(1), positions=lambda sim: sim.positions, stats=stats,
            out=args.out)


if __name__ == "__main__":
    main()
