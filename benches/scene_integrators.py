"""The self-collision scenes as built in (implicit Euler at display-frame steps with
self-contact held inside its solve, ``solve_stiffness``) against symplectic Euler at 1 ms steps
(what they all used before, with the pile's damping of then): CPU time per frame on one
thread, crossings by the independent ``tri_check`` every 30 frames, and what the scene must do
(``tests/test_scene_behaviour.py``: fold over its bar, pile; the twist's largest stretch).

    RAYON_NUM_THREADS=1 PYTHONPATH=python python benches/scene_integrators.py \
        [--scenes twist pile fold] [--runs builtin 1ms implicit] [--repeats 1] \
        [--steps-per-frame 2] [--stiffness 30] [--damping D] [--seconds S]

``builtin`` is the scene file, ``1ms`` symplectic Euler at 1 ms steps with no in-solve term and
damping 0.01 (the scenes as tuned), ``implicit`` implicit Euler at ``--steps-per-frame``,
``--stiffness`` and (if given) ``--damping``; ``--trace`` prints the twist's stretch every 0.5 s
and stops a run past a stretch of 4. ``twist`` is turned by ``TwistDriver`` (2 turns in
4 s) for 4 s, ``pile`` runs 3 s, ``fold`` 5 s (``--seconds`` overrides). With ``--repeats`` the
runs alternate (builtin, 1ms, builtin, 1ms, ...) so that a shared machine's drift falls on both.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

here = Path(__file__).resolve().parent
sys.path.insert(0, str(here / "peers"))
sys.path.insert(0, str(here.parent / "tests"))

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
import tri_check  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402
from test_scene_behaviour import pile_shape  # noqa: E402

SECONDS = {"twist": 4.0, "pile": 3.0, "fold": 5.0}
# The twist's largest stretch along its axis past which ``--trace`` calls it torn and stops.
TORN = 4.0
# Symplectic Euler's substeps per 1 ms step in each scene.
SUBSTEPS = {"twist": 1, "pile": 2, "fold": 1}


def variant(name: str, run: str, args: argparse.Namespace) -> tuple[rustcloth.Scene, str]:
    """The scene for ``run`` and a label saying how it steps."""
    base = rustcloth.load_scene(name)
    if run == "builtin":
        scene = base
    elif run == "1ms":
        scene = base.replace(integrator="symplectic_euler", dt=0.001, substeps=SUBSTEPS[name],
                             cloth={"damping": 0.01},
                             self_collision={**base.self_collision, "solve_stiffness": 0.0})
    else:
        cloth = {} if args.damping is None else {"damping": args.damping}
        scene = base.replace(integrator="implicit_euler", dt=1.0 / (60 * args.steps_per_frame),
                             substeps=1, cloth=cloth,
                             self_collision={**base.self_collision,
                                             "solve_stiffness": args.stiffness})
    steps = 1.0 / 60 / scene.dt
    label = (f"{run}: {scene.integrator}, " + (f"{steps:.0f} steps a frame" if steps < 10 else
             f"dt {scene.dt * 1e3:g} ms x {scene.substeps}") +
             f", K {scene.self_collision['solve_stiffness']:g}, damping {scene.cloth['damping']:g}")
    return scene, label


def stretch(sim: rustcloth.Simulation) -> float:
    """The largest ``l / L - 1`` of the edges along the twist's axis."""
    p = sim.positions
    edges = np.linalg.norm(np.diff(p.reshape(sim.ny, sim.nx, 3), axis=1), axis=2)
    return float(edges.max() / (sim.scene.cloth["size"][0] / (sim.nx - 1)) - 1)


def behaviour(name: str, sim: rustcloth.Simulation) -> str:
    """What the scene's test checks, measured."""
    p = sim.positions
    if name == "fold":
        on_bar = int((np.abs(p[:, 1] - 0.6) < 0.05).sum())
        return (f"y {p[:, 1].min():.3f}..{p[:, 1].max():.3f} (test: > 0.05, < 0.65), "
                f"on bar {on_bar} (>= 20), halves {(p[:, 2] > 0).mean():.2f} (0.3-0.7)")
    if name == "pile":
        area, height = pile_shape(sim)
        speed = float(np.linalg.norm(sim.velocities, axis=1).max())
        return (f"footprint {area:.3f} m^2 (< 0.333), height {height:.3f} m (> 0.03), "
                f"fastest {speed:.2f} m/s (< 0.5)")
    return f"largest stretch along the axis {stretch(sim):.2f}"


def run(name: str, kind: str, args: argparse.Namespace) -> None:
    scene, label = variant(name, kind, args)
    sim = rustcloth.Simulation(scene)
    driver = TwistDriver(sim) if name == "twist" else None
    frames = round((args.seconds or SECONDS[name]) * 60)
    per_frame = round(1.0 / 60 / sim.dt)
    cpu, crossings, trace = 0.0, [], []
    for frame in range(1, frames + 1):
        c0 = time.process_time()
        for _ in range(per_frame):
            if driver is not None:
                driver.before_step(sim)
            sim.step()
        cpu += time.process_time() - c0
        if frame % 30 == 0:
            crossings.append(tri_check.count(sim.positions.astype(np.float64), sim.triangles))
            if args.trace and name == "twist":
                trace.append(f"{stretch(sim):.2f}")
                if stretch(sim) > TORN:
                    trace.append(f"torn, stopped at {sim.time:.2f} s")
                    frames = frame
                    break
    print(f"{name:6s} {label:72s} {1e3 * cpu / frames:8.2f} CPU ms/frame, crossings at "
          f"{len(crossings)} checks: {max(crossings)} at most; {behaviour(name, sim)}"
          + (f"; every 0.5 s: {' '.join(trace)}" if trace else ""), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["twist", "pile", "fold"])
    parser.add_argument("--runs", nargs="+", default=["builtin", "1ms"],
                        choices=["builtin", "1ms", "implicit"])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--stiffness", type=float, default=30.0,
                        help="solve_stiffness of the implicit run")
    parser.add_argument("--steps-per-frame", type=int, default=2,
                        help="implicit steps per 1/60 s frame of the implicit run")
    parser.add_argument("--damping", type=float, default=None,
                        help="the implicit run's spring damping, N s/m (default: the scene's)")
    parser.add_argument("--seconds", type=float, default=None, help="simulated time")
    parser.add_argument("--trace", action="store_true",
                        help="the twist's stretch every 0.5 s; stop a run once it is torn")
    args = parser.parse_args()
    for name in args.scenes:
        for _ in range(args.repeats):
            for kind in args.runs:
                run(name, kind, args)


if __name__ == "__main__":
    main()
