"""newton peer on mesh contact (issue 13): a 128 x 128 cloth draped on a closed 20480-triangle
mesh (the icosphere of ``benches/mesh_collider.py``, level 5, radius 0.5 m), with newton's soft
contacts of particles against a mesh shape, on the Warp CPU device.

The scene is rustcloth's mesh-collider bench's: a 1.6 m cloth of 128 x 128 particles of 0.4 g,
horizontal at 1.05 m, dropped onto the sphere mesh centred at (0, 0.5, 0), draped for 0.3 s,
then timed. newton's cloth: ``add_cloth_grid`` (FEM triangles ``tri_ke = tri_ka = 1e3``,
dihedral bending ``edge_ke = 1e-3``, newton's twist example's material), stepped by
``SolverVBD`` (``--iterations``) at ``--substeps`` substeps per 1/60 s frame. The mesh:
``newton.Mesh`` added with ``add_shape_mesh`` to the static world body (-1). Particle radius 2
mm (rustcloth's collider ``thickness``), soft-contact detection gap newton's default 1 cm.

Each substep is newton's cloth loop, ``CollisionPipeline.collide`` (for this scene: the soft
contacts, one ``create_soft_contacts`` launch over every particle-shape pair, a BVH query of the
mesh per particle) and then ``SolverVBD.step``; both are timed apart, each followed by
``wp.synchronize()``. Reported: ms per substep of each, best of three slices of ``--steps``
substeps (as rustcloth's bench takes the best of three), and the share of particles within 1 cm
of the sphere. ``--cold`` compiles every kernel (empty cache) and reports the set-up time.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from warp_cpu import start_warp_on_cpu  # noqa: E402

N = 128
SIZE = 1.6  # m
HEIGHT = 1.05  # m
PARTICLE_MASS = 4e-4  # kg
RADIUS = 0.5  # m
CENTER = (0.0, 0.5, 0.0)
LEVEL = 5  # 20480 triangles
DRAPE = 0.3  # s


def build(substeps: int, iterations: int):
    import newton  # noqa: PLC0415
    from mesh_collider import icosphere  # noqa: PLC0415  (benches/mesh_collider.py)

    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
    vertices, triangles = icosphere(LEVEL, RADIUS)
    mesh = newton.Mesh(vertices.astype(np.float32), triangles.astype(np.int32).ravel(),
                       compute_inertia=False)
    builder.add_shape_mesh(-1, xform=wp.transform(wp.vec3(*CENTER), wp.quat_identity()),
                           mesh=mesh)
    cell = SIZE / (N - 1)
    builder.add_cloth_grid(
        # Local x, y of the grid onto world x, -z: the cloth horizontal, centred over the mesh.
        pos=wp.vec3(-SIZE / 2, HEIGHT, SIZE / 2),
        rot=wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), -np.pi / 2),
        vel=wp.vec3(0.0, 0.0, 0.0),
        dim_x=N - 1, dim_y=N - 1, cell_x=cell, cell_y=cell, mass=PARTICLE_MASS,
        tri_ke=1.0e3, tri_ka=1.0e3, tri_kd=2.0e-4, edge_ke=1.0e-3, edge_kd=1.0e-2,
        particle_radius=0.002,
    )
    builder.color()
    model = builder.finalize(device="cpu")
    model.soft_contact_ke = 1.0e3
    model.soft_contact_kd = 1.0e-1
    model.soft_contact_mu = 0.3  # rustcloth's collider friction default
    solver = newton.solvers.SolverVBD(model, iterations=iterations)
    pipeline = newton.CollisionPipeline(model)
    return newton, model, solver, pipeline, len(triangles)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--substeps", type=int, default=10, help="per 1/60 s frame")
    p.add_argument("--iterations", type=int, default=5)
    p.add_argument("--steps", type=int, default=30, help="substeps per timed slice")
    p.add_argument("--cold", action="store_true", help="compile every kernel (empty cache)")
    args = p.parse_args()
    t0 = time.perf_counter()
    start_warp_on_cpu(args.cold)
    newton, model, solver, pipeline, mesh_triangles = build(args.substeps, args.iterations)
    state_0, state_1 = model.state(), model.state()
    control = model.control()
    contacts = pipeline.contacts()
    h = 1.0 / (60 * args.substeps)
    setup = time.perf_counter() - t0

    def substep(times: list[float] | None = None) -> None:
        nonlocal state_0, state_1
        c0 = time.perf_counter()
        state_0.clear_forces()
        pipeline.collide(state_0, contacts)
        wp.synchronize()
        c1 = time.perf_counter()
        solver.step(state_0, state_1, control, contacts, h)
        wp.synchronize()
        c2 = time.perf_counter()
        state_0, state_1 = state_1, state_0
        if times is not None:
            times[0] += c1 - c0
            times[1] += c2 - c1

    f0 = time.perf_counter()
    substep()  # the first pays for the solver's and collision kernels' compilation
    first = time.perf_counter() - f0
    while_draping = int(round(DRAPE / h)) - 1
    for _ in range(while_draping):
        substep()
    best_collide = best_solve = float("inf")
    for _ in range(3):
        times = [0.0, 0.0]
        for _ in range(args.steps):
            substep(times)
        best_collide = min(best_collide, 1e3 * times[0] / args.steps)
        best_solve = min(best_solve, 1e3 * times[1] / args.steps)
    x = state_0.particle_q.numpy().astype(np.float64)
    r = np.linalg.norm(x - CENTER, axis=1)
    with open("/proc/loadavg") as f:
        load = float(f.read().split()[0])
    result = {
        "peer": "newton",
        "solver": f"SolverVBD, CollisionPipeline soft contacts, {args.iterations} iterations",
        "version": f"newton {newton.__version__}, warp {wp.__version__}",
        "threads": 1,
        "cold": args.cold,
        "setup_s": setup,
        "first_substep_s": first,
        "particles": int(model.particle_count),
        "mesh_triangles": mesh_triangles,
        "substep_dt": h,
        "collide_ms_per_substep": best_collide,
        "solve_ms_per_substep": best_solve,
        "step_ms_per_substep": best_collide + best_solve,
        "soft_contacts": int(contacts.soft_contact_count.numpy()[0]),
        "soft_contact_pairs": int(pipeline.soft_contact_pair_count),
        "contact_share": float((r < RADIUS + 0.01).mean()),
        "min_r": float(r.min()),
        "finite": bool(np.isfinite(x).all()),
        "load": load,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    sys.stdout.flush()
    print("RESULT " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
