"""A mesh collider from a file: drop a cloth onto any triangle mesh trimesh reads (OBJ, STL,
PLY, glTF, ...). Without a file argument it writes a low-poly sphere to out/ball.obj first.

    pip install 'rustcloth[export]'
    python examples/mesh_collider_from_file.py [body.obj]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import rustcloth
import trimesh
from _quick import pick, size

if len(sys.argv) > 1:
    path = Path(sys.argv[1])
else:
    path = Path("out/ball.obj")
    path.parent.mkdir(exist_ok=True)
    trimesh.creation.icosphere(subdivisions=2, radius=0.3).export(path)

n = size(48, 16)
scene = (rustcloth.load_scene("drape")
         .replace(spheres=[], cloth={"nx": n, "ny": n})  # the built-in sphere out ...
         .with_mesh_collider(path=path, center=[0.0, 0.45, 0.0], friction=0.5,
                             thickness=0.01))           # ... the file's mesh in
sim = rustcloth.Simulation(scene)
sim.advance(pick(2.0, 0.4))

# The collider as the simulation holds it (its vertices in its own frame) and the cloth's
# nearest approach to the mesh's centre.
collider = sim.colliders()[-1]
vertices = np.asarray(collider["vertices"])
gap = np.linalg.norm(sim.positions - np.array([0.0, 0.45, 0.0]), axis=1).min()
print(f"{path}: {len(vertices)} vertices, {len(collider['triangles'])} triangles")
print(f"t = {sim.time:.2f} s: the cloth is {gap:.3f} m from the ball's centre at the closest "
      f"(radius 0.3 m + thickness 0.01 m); lowest point {sim.positions[:, 1].min():.3f} m")
