"""A cloth from a triangle mesh file: a flag with a round hole, its hoist marked as a vertex group
in the file, pinned by that group's name and flown in a gusty wind; then exported as OBJ and read
back to show that the file's vertex order and UVs came through.

    pip install 'rustcloth[export]'
    python examples/flag_from_mesh.py

The OBJ is written here by hand (a modelling tool writes the same thing): ``v`` and ``vt``
lines, a ``g hoist`` group over the faces along the pole, and the rest under ``g field``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rustcloth
import trimesh
from _quick import pick, size

OUT = Path("out")
OUT.mkdir(exist_ok=True)

# A 1.2 m x 0.8 m flag in the x-y plane, its hoist (x = 0) on the pole, as a grid of points
# whose squares inside a hole of radius 0.15 m are left out.
nx, ny = size(49, 17), size(33, 12)
width, height, top = 1.2, 0.8, 2.0
u, v = np.meshgrid(np.linspace(0.0, 1.0, nx), np.linspace(0.0, 1.0, ny))
points = np.stack([u.ravel() * width, top - height + v.ravel() * height, np.zeros(u.size)], 1)
hole_centre, hole_radius = np.array([0.75, top - height / 2]), 0.15

hoist, field = [], []
for j in range(ny - 1):
    for i in range(nx - 1):
        a = j * nx + i
        b, c, d = a + 1, a + nx, a + nx + 1
        middle = points[[a, d], :2].mean(0)
        if np.linalg.norm(middle - hole_centre) < hole_radius:
            continue
        (hoist if i == 0 else field).extend([(a, b, d), (a, d, c)])

# Vertices no face uses (inside the hole) are left out of the file: the cloth refuses them.
used = np.unique(np.array(hoist + field))
number = {old: new for new, old in enumerate(used.tolist())}
path = OUT / "flag_hole.obj"
with open(path, "w", encoding="utf-8") as obj:
    obj.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in points[used])
    obj.writelines(f"vt {s:.6f} {t:.6f}\n" for s, t in zip(u.ravel()[used], v.ravel()[used],
                                                           strict=True))
    for name, faces in (("hoist", hoist), ("field", field)):
        obj.write(f"g {name}\n")
        obj.writelines("f " + " ".join(f"{number[k] + 1}/{number[k] + 1}" for k in face) + "\n"
                       for face in faces)

# The cloth: the file's mesh, a light polyester, the hoist's vertices pinned to the pole, and
# a 5 m/s wind with gusts. Implicit Euler steps it at 1/120 s.
scene = (rustcloth.Scene(integrator="implicit_euler", dt=1 / 120, floor=None)
         .with_cloth_mesh(path=path, pin_group="hoist", density=0.15, stretch=800.0,
                          bend=20.0, damping=0.05)
         .replace(wind={"velocity": [5.0, 0.0, 0.5], "gust": 0.3, "turbulence": 1.0,
                        "seed": 7}))
sim = rustcloth.Simulation(scene)
start = sim.positions.copy()
sim.advance(pick(3.0, 0.3))

moved = np.linalg.norm(sim.positions - start, axis=1)
print(f"{path}: {len(used)} vertices, {len(hoist) + len(field)} triangles, "
      f"{int(sim.pinned.sum())} vertices pinned by the group 'hoist' (its faces' two columns)")
print(f"t = {sim.time:.2f} s in a 5 m/s wind: the cloth moved up to {moved.max():.3f} m, the "
      f"largest stretch is {sim.max_stretch():.3f}, the cloth is in {sim.pieces()} piece(s)")

# Export keeps the file's vertex order and UVs: read back, vertex k is still particle k.
out = OUT / "flag_hole_flown.obj"
sim.export(out)
back = trimesh.load(out, process=False)
assert np.allclose(back.vertices, sim.positions, atol=1e-5)
assert np.allclose(back.visual.uv, np.stack([u.ravel()[used], v.ravel()[used]], 1), atol=1e-5)
print(f"wrote {out}: {len(back.vertices)} vertices read back in the file's order, UVs kept")
