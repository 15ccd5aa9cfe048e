"""rustcloth peer on the twist (issue 13): the built-in ``twist`` scene with ``[self_collision]``,
made as like newton's ``example_cloth_twist`` as the two models allow.

Changed from ``scenes/twist.toml`` to match newton's example (see docs/peers_contact.md for
every remaining difference):

- the cloth: 50 x 50 particles, 1.5 m along the turning axis by 1.0 m, 0.3 kg (newton's 0.2
  kg/m^2), so 1.2e-4 kg a particle;
- the turning: ``TwistDriver(turns=10/6, seconds=10)``, pi/3 rad/s each edge in opposite
  directions for 10 s, as newton's ``rot_angular_velocity`` and ``rot_end_time``;
- the time step: 1/600 s, ten steps per 1/60 s frame (newton's 10 substeps), each step one
  substep, the driver moving the pinned edges before each;
- self-collision ``thickness`` 2 mm (newton's ``particle_self_contact_margin``, the distance at
  which its pairs start to interact), friction 0.2 (newton's ``soft_contact_mu``);
- the springs: ``k_structural`` 1000 N/m (newton's ``tri_ke``), shear 250, bending 10 (the
  built-in scene's 20 : 5 : 1 for shear and bending), and, because symplectic Euler would need
  six substeps for that at 1/600 s, ``implicit_euler`` (one linearised backward-Euler solve a
  step, as newton's VBD is an implicit-Euler solver).

``--integrator``/``--k`` change the last two (e.g. the built-in scene's own symplectic Euler
with its springs scaled to the lighter cloth). The rayon pool size is fixed per process: the
runner sets ``RAYON_NUM_THREADS``. Prints one ``RESULT {json}`` line; the driver's own time
(Python, 100 ``pin`` calls a step) is reported apart from the simulation's.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402
from twist_common import emit, sample  # noqa: E402

N = 50
SIZE = (1.5, 1.0)  # m: along the turning axis, across
MASS = 0.3  # kg
STEPS_PER_FRAME = 10
RATE_TURNS = 1.0 / 6.0  # turns per second (pi/3 rad/s)
END = 10.0  # s
THICKNESS = 0.002  # m
FRICTION = 0.2


def scene(integrator: str, k: tuple[float, float, float], steps_per_frame: int,
          solve_stiffness: float = 0.0) -> rustcloth.Scene:
    base = rustcloth.load_scene("twist")
    return base.replace(
        integrator=integrator,
        dt=1.0 / (60 * steps_per_frame),
        substeps=1,
        cloth={"nx": N, "ny": N, "size": list(SIZE), "particle_mass": MASS / (N * N),
               "k_structural": k[0], "k_shear": k[1], "k_bend": k[2]},
        self_collision={**base.self_collision, "thickness": THICKNESS, "friction": FRICTION,
                        "solve_stiffness": solve_stiffness},
    )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=180)
    p.add_argument("--every", type=int, default=30)
    p.add_argument("--integrator", default="implicit_euler")
    p.add_argument("--k", type=float, nargs=3, default=(1000.0, 250.0, 10.0),
                   help="structural, shear, bending (N/m)")
    p.add_argument("--steps-per-frame", type=int, default=STEPS_PER_FRAME,
                   help="steps per 1/60 s frame (default 10, newton's substeps)")
    p.add_argument("--solve-stiffness", type=float, default=0.0,
                   help="self_collision.solve_stiffness: implicit Euler holds the pairs ahead "
                        "of its step apart inside its solve (default 0: off)")
    args = p.parse_args()
    t0 = time.perf_counter()
    s = scene(args.integrator, tuple(args.k), args.steps_per_frame, args.solve_stiffness)
    sim = rustcloth.Simulation(s)
    driver = TwistDriver(sim, turns=RATE_TURNS * END, seconds=END)
    setup = time.perf_counter() - t0
    triangles = sim.triangles
    walls, steps, drives, cpus = [], [], [], []
    samples = [sample(0, sim.positions, triangles)]
    for frame in range(1, args.frames + 1):
        stepping = driving = 0.0
        w0, c0 = time.perf_counter(), time.process_time()
        for _ in range(args.steps_per_frame):
            d0 = time.perf_counter()
            driver.before_step(sim)
            d1 = time.perf_counter()
            sim.step()
            d2 = time.perf_counter()
            driving += d1 - d0
            stepping += d2 - d1
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
        steps.append(stepping)
        drives.append(driving)
        if frame % args.every == 0 or frame == args.frames:
            samples.append(sample(frame, sim.positions, triangles))
    x = sim.positions
    stats = sim.self_collision_stats() or {}
    profile = sim.profile()
    frames = max(profile.steps / args.steps_per_frame, 1)
    min_distance = stats.get("min_distance")
    substeps = max(stats.get("substeps", 1), 1)
    emit({
        "peer": "rustcloth",
        "solver": f"{args.integrator}, [self_collision]",
        "version": f"rustcloth {getattr(rustcloth, '__version__', '?')}",
        "threads": rustcloth._core.thread_count(),
        "setup_s": setup,
        "first_frame_s": walls[0],
        "walls": walls,
        # The process's CPU time (every thread's), steadier than the wall time on a shared
        # machine; with RAYON_NUM_THREADS=1 it is the frame's cost on one core.
        "cpu_ms_per_frame": 1e3 * float(np.mean(cpus[1:] or cpus)),
        "step_ms_per_frame": 1e3 * float(np.mean(steps[1:] or steps)),
        "driver_ms_per_frame": 1e3 * float(np.mean(drives[1:] or drives)),
        "samples": samples,
        "particles": sim.num_particles,
        "triangles": len(triangles),
        "substeps": args.steps_per_frame,
        "integrator": args.integrator,
        "k": list(args.k),
        "solve_stiffness": args.solve_stiffness,
        "pairs_per_substep": stats.get("pairs", 0) / substeps,
        "contacts_per_substep": stats.get("contacts", 0) / substeps,
        "capped_per_substep": stats.get("capped", 0) / substeps,
        "stopped_per_substep": stats.get("stopped", 0) / substeps,
        "swept_share": stats.get("swept_substeps", 0) / substeps,
        "min_distance": min_distance if min_distance is not None
        and np.isfinite(min_distance) else None,
        # Per pass, ms per frame over the whole run (the first frame included).
        "profile_ms_per_frame": {name: 1e3 * p.seconds / frames
                                 for name, p in profile.passes.items()},
        "solver_stats": sim.solver_stats(),
        "extent": (x.max(0) - x.min(0)).tolist(),
        "finite": bool(np.isfinite(x).all()),
    })


if __name__ == "__main__":
    main()
