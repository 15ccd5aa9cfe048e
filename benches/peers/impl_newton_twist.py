"""newton peer on the twist (issue 13): newton's own ``example_cloth_twist``, unchanged, headless
on the Warp CPU device.

The example's ``Example`` class is imported from the installed newton package and driven as
``python -m newton.examples cloth_twist --viewer null --device cpu`` would drive it: a
``ViewerNull`` (no rendering), one ``step()`` per 1/60 s frame (its captured graph of one
collision-pipeline pass, one BVH rebuild and 10 substeps of VBD with 4 iterations, the edge
rotation kernel before each). Its cloth: warp's ``square_cloth.usd`` (50 x 50 vertices,
1.5 m x 1.0 m, 4802 triangles, 0.3 kg), FEM triangles (``tri_ke = tri_ka = 1e3``), dihedral
bending ``edge_ke = 1e-3``, no gravity, the two short edges turned in opposite directions about
the long axis at pi/3 rad/s for 10 s, self-contact at 2 mm (margin) with 1.5 mm of extra
detection reach (gap). Reading the USD file needs ``usd-core`` (``pxr``).

Every ``--every`` frames the positions are handed to ``tri_check`` (outside the timing).
Prints one ``RESULT {json}`` line. ``--cold`` points Warp's kernel cache at an empty folder, so
that the set-up and first frame include compiling every kernel.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from twist_common import emit, sample  # noqa: E402
from warp_cpu import start_warp_on_cpu  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=180)
    p.add_argument("--every", type=int, default=30)
    p.add_argument("--cold", action="store_true", help="compile every kernel (empty cache)")
    args = p.parse_args()
    t0 = time.perf_counter()
    start_warp_on_cpu(args.cold)
    import newton  # noqa: PLC0415
    import newton.viewer  # noqa: PLC0415
    from newton.examples.cloth.example_cloth_twist import Example  # noqa: PLC0415

    example = Example(newton.viewer.ViewerNull(), None)
    wp.synchronize()
    setup = time.perf_counter() - t0
    triangles = example.model.tri_indices.numpy()
    walls, cpus = [], []
    samples = [sample(0, example.state_0.particle_q.numpy(), triangles)]
    for frame in range(1, args.frames + 1):
        w0, c0 = time.perf_counter(), time.process_time()
        example.step()
        wp.synchronize()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
        if frame % args.every == 0 or frame == args.frames:
            samples.append(sample(frame, example.state_0.particle_q.numpy(), triangles))
    x = example.state_0.particle_q.numpy()
    emit({
        "peer": "newton",
        "solver": "SolverVBD (example_cloth_twist)",
        "version": f"newton {newton.__version__}, warp {wp.__version__}",
        "threads": 1,
        "cold": args.cold,
        "setup_s": setup,
        "first_frame_s": walls[0],
        "walls": walls,
        # The process's CPU time, steadier than the wall time on a shared machine (as
        # impl_rustcloth_twist.py reports it).
        "cpu_ms_per_frame": 1e3 * float(np.mean(cpus[1:] or cpus)),
        "samples": samples,
        "particles": len(x),
        "triangles": len(triangles),
        "substeps": example.sim_substeps,
        "iterations": example.iterations,
        "graph": example.graph is not None,
        "extent": (x.max(0) - x.min(0)).tolist(),
        "finite": bool(np.isfinite(x).all()),
    })


if __name__ == "__main__":
    main()
