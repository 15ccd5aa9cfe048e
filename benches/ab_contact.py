"""Two builds of rustcloth side by side on contact at display-frame steps: the implicit solvers'
solves per step, their time per step, and whether both builds end in the same state.

Each case runs in a fresh interpreter that imports the build from the folder given (a copy of
``python/`` holding that build's ``_core.abi3.so``); A and B alternate within every repeat, so
that both see the same load, and the medians' ratio B / A is reported. ``same`` says whether the
two builds ended every repeat bit for bit in the same positions and velocities: a refactor must
say yes; a change of the physics says no, and the energy columns show what it did.

    cp -r python /tmp/before                       # with the old build's _core.abi3.so in it
    python benches/ab_contact.py --a /tmp/before --b python          # about two minutes
    python benches/ab_contact.py --a /tmp/before --b python --cases "pd pile 10 cm" --repeats 5

Columns: solves and halved solves per step, linear-solver iterations per step (implicit Euler:
conjugate-gradient iterations; projective dynamics: local-global iterations), self-collision
reruns per step (substeps the pass ran beyond one per step), the highest total energy above the
start over the start, ms per step.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

# name: (builtin scene, integrator, the pile's square dropped edge first with its lower edge this
# far above the floor in m (tests/test_contact_energy.py's ``pile``; None: the scene as shipped),
# seconds)
CASES: dict[str, tuple[str, str, float | None, float]] = {
    "pd pile 10 cm": ("pile", "projective_dynamics", 0.1, 0.8),
    "ie pile 10 cm": ("pile", "implicit_euler", 0.1, 0.8),
    "pd pile 40 cm": ("pile", "projective_dynamics", 0.4, 0.8),
    "ie pile 40 cm": ("pile", "implicit_euler", 0.4, 0.8),
    "ie drape": ("drape", "implicit_euler", None, 2.0),
}


def run_case(name: str, dt: float) -> dict[str, object]:
    """One case in this interpreter: what the table reports, and a digest of the end state."""
    import rustcloth
    from contact_energy import drive  # puts tests/ on the path
    from test_contact_energy import pile

    scene_name, integrator, drop, seconds = CASES[name]
    scene = rustcloth.load_scene(scene_name) if drop is None else pile(drop)
    scene = scene.replace(integrator=integrator, dt=dt, substeps=1)
    sim = rustcloth.Simulation(scene)
    start = sim.energy().total
    steps = round(seconds / dt)
    highest, step = drive(sim, steps)
    solver = sim.solver_stats() or {}
    contact = sim.self_collision_stats() or {}
    digest = hashlib.sha256(sim.positions.tobytes() + sim.velocities.tobytes()).hexdigest()
    return {
        "ms": 1e3 * step,
        "solves": solver.get("solves", 0) / steps,
        "halved": solver.get("halved", 0) / steps,
        "iterations": solver.get("iterations", 0) / steps,
        "reruns": max(0, contact.get("substeps", steps) - steps) / steps,
        "gain": (highest - start) / abs(start),
        "digest": digest[:16],
        "module": rustcloth.__file__,
    }


def run_once(path: str, name: str, dt: float, threads: int) -> dict[str, object]:
    path = str(Path(path).resolve())
    env = dict(os.environ, PYTHONPATH=path, RAYON_NUM_THREADS=str(threads))
    args = [sys.executable, str(Path(__file__).resolve()), "--worker", name, "--dt", str(dt)]
    out = subprocess.run(args, env=env, cwd="/", capture_output=True, text=True, check=True)
    result: dict[str, object] = json.loads(out.stdout.strip().splitlines()[-1])
    if not str(result["module"]).startswith(path):
        raise SystemExit(f"{path}: imported {result['module']} instead")
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--a", help="folder holding build A's rustcloth package (the reference)")
    p.add_argument("--b", help="folder holding build B's rustcloth package")
    p.add_argument("--cases", nargs="+", default=["pd pile 10 cm", "ie drape"],
                   choices=list(CASES))
    p.add_argument("--dt", type=float, default=1 / 60, help="step, s (one substep)")
    p.add_argument("--threads", type=int, default=1, help="rayon threads")
    p.add_argument("--repeats", type=int, default=3, help="interleaved repeats per case")
    p.add_argument("--worker", choices=list(CASES), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        print(json.dumps(run_case(args.worker, args.dt)))
        return 0
    if not (args.a and args.b):
        p.error("--a and --b are required")
    print("| case | build | solves/step | halved/step | iterations/step | reruns/step | gain "
          "| ms/step | B / A | same |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.cases:
        runs: dict[str, list[dict[str, object]]] = {"a": [], "b": []}
        for k in range(args.repeats):
            for key in ("a", "b") if k % 2 == 0 else ("b", "a"):
                runs[key].append(run_once(getattr(args, key), name, args.dt, args.threads))
        ms = {key: statistics.median(float(str(r["ms"])) for r in rs) for key, rs in runs.items()}
        digests = {key: {r["digest"] for r in rs} for key, rs in runs.items()}
        same = "yes" if digests["a"] == digests["b"] and len(digests["a"]) == 1 else "no"
        for key in ("a", "b"):
            r = runs[key][0]
            ratio = f"{ms['b'] / ms['a']:.3f}" if key == "b" else ""
            print(f"| {name} | {key.upper()} | {r['solves']:.2f} | {r['halved']:.2f} "
                  f"| {r['iterations']:.1f} | {r['reruns']:.2f} | {float(str(r['gain'])):+.2e} "
                  f"| {ms[key]:.1f} | {ratio} "
                  f"| {same if key == 'b' else ''} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
