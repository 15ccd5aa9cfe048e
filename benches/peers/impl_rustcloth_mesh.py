"""rustcloth peer on mesh contact (issue 13): ``benches/mesh_collider.py``'s own measurement,
for the 20480-triangle icosphere (level 5) only.

The scene, the draping and the timing are that bench's (imported, not copied, so the two stay
one measurement): a 1.6 m cloth of 128 x 128 particles dropped on the icosphere of radius 0.5 m,
draped for 0.3 s (300 steps of 1 ms, 2 substeps each), then the best of three slices of
``--steps`` steps, the collider pass read from ``Simulation.profile()``'s ``colliders``. The
rayon pool size is fixed per process: the runner sets ``RAYON_NUM_THREADS``. Prints one
``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import rustcloth  # noqa: E402
from mesh_collider import base_scene, icosphere, measure  # noqa: E402

LEVEL = 5


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=200)
    args = p.parse_args()
    t0 = time.perf_counter()
    scene = base_scene()
    vertices, triangles = icosphere(LEVEL, 0.5)
    mesh = scene.with_mesh_collider(vertices, triangles, center=[0, 0.5, 0])
    setup = time.perf_counter() - t0
    collider, step, contact = measure(mesh, args.steps)
    with open("/proc/loadavg") as f:
        load = float(f.read().split()[0])
    print("RESULT " + json.dumps({
        "peer": "rustcloth",
        "solver": f"{scene.integrator}, mesh collider",
        "version": f"rustcloth {getattr(rustcloth, '__version__', '?')}",
        "threads": rustcloth._core.thread_count(),
        "setup_s": setup,
        "particles": scene.cloth["nx"] * scene.cloth["ny"],
        "mesh_triangles": len(triangles),
        "substep_dt": scene.dt / scene.substeps,
        "collide_ms_per_substep": collider,
        "step_ms_per_substep": step,
        "solve_ms_per_substep": step - collider,
        "contact_share": contact,
        "load": load,
    }), flush=True)


if __name__ == "__main__":
    main()
