"""Time for a big mesh collider to become a Scene and then a Simulation.

    python benches/mesh_scene.py [--triangles 200000] [--repeat 3] [--against OTHER_CHECKOUT/python]

A closed torus of `--triangles` triangles (generated with numpy, nothing read from disk) is
added to a small cloth scene with ``Scene.with_mesh_collider``, and the scene is turned into a
``Simulation``. Printed, each the best of `--repeat` runs: the whole of each, and the stages of
the scene's construction (the arrays' checks, the scene's own copy, the nesting check, the
conversion to the core's types, the core's validation). With ``--against``, the same
measurement runs again in a child process on the package found at that path (another build),
one after the other, and the ratios are printed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

# The generated meshes the tests use.
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
import mesh_shapes  # noqa: E402


def torus(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed torus of about `triangles` triangles, 2.5 times as many segments as rings."""
    rings = max(3, round(math.sqrt(triangles / 2 / 2.5)))
    return mesh_shapes.torus(max(3, round(triangles / 2 / rings)), rings)


def best(run: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), result


def measure(triangles: int, repeat: int) -> dict[str, Any]:
    import rustcloth
    from rustcloth import _core
    from rustcloth import scene as scene_module

    vertices, faces = torus(triangles)
    base = rustcloth.Scene(cloth={"nx": 8, "ny": 8}, floor=None)
    keys = {"center": [0.0, 0.0, 0.0]}
    times: dict[str, float] = {}
    times["with_mesh_collider"], scene = best(
        lambda: base.with_mesh_collider(vertices, faces, **keys), repeat
    )
    # The stages of the same construction, one by one.
    times["  mesh arrays"], (v, f) = best(
        lambda: (scene_module._mesh_array(vertices, "v"), scene_module._mesh_array(faces, "t")),
        repeat,
    )
    collider = {**keys, "shape": "mesh", "vertices": v, "triangles": f}
    times["  to_dict"], data = best(base.to_dict, repeat)
    data["colliders"] = [collider]
    times["  check nesting"], _ = best(lambda: scene_module._check_nesting(data), repeat)
    times["  to core types"], plain = best(lambda: scene_module._plain(data), repeat)
    times["  core: validate"], _ = best(lambda: _core.normalize_scene(plain), repeat)
    times["scene.to_dict()"], _ = best(scene.to_dict, repeat)
    times["Simulation(scene)"], _ = best(lambda: rustcloth.Simulation(scene), repeat)
    return {"package": os.path.dirname(rustcloth.__file__), "triangles": len(faces),
            "times": times}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--against", help="a python/ folder holding another rustcloth build")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    ours = measure(args.triangles, args.repeat)
    if args.json:
        print(json.dumps(ours))
        return
    runs = [ours]
    if args.against:
        env = {**os.environ, "PYTHONPATH": args.against}
        command = [sys.executable, __file__, "--json", "--triangles", str(args.triangles),
                   "--repeat", str(args.repeat)]
        out = subprocess.run(command, env=env, check=True, capture_output=True, text=True)
        runs.append(json.loads(out.stdout.splitlines()[-1]))
    print(f"{ours['triangles']} triangles, best of {args.repeat}")
    header = "".join(f"{run['package'][-40:]:>42s}" for run in runs)
    print(f"{'stage':22s}{header}" + ("   ratio" if len(runs) == 2 else ""))
    for stage, seconds in ours["times"].items():
        row = "".join(f"{run['times'][stage]:41.3f}s" for run in runs)
        ratio = ""
        if len(runs) == 2:
            # Stages that now take no measurable time have no meaningful ratio.
            other = runs[1]["times"][stage]
            ratio = f"{other / seconds:8.1f}x" if seconds > 1e-3 else "      --"
        print(f"{stage:22s}{row}{ratio}")


if __name__ == "__main__":
    main()
