"""A garment sewn from flat panels onto a body: a straight skirt of two panels wrapped round
the mannequin's hips, its side seams drawn closed, the cloth kept off the body and off itself;
then exported as glTF binary.

    pip install 'rustcloth[export]'
    python examples/sew_a_garment.py

Each panel is a flat outline in metres with named edges; a seam joins two named edges
(``"front.right"`` to ``"back.left"``). The scene meshes each panel at ``edge_length`` and sews
the seams' matching points together over ``sew_time`` seconds (docs/garments.md).
"""

from __future__ import annotations

from pathlib import Path

import rustcloth
from _quick import pick
from rustcloth import garment

OUT = Path("out")
OUT.mkdir(exist_ok=True)

# The outline (u across, v up, m): 50 cm long, its waist (v = 0) cut 7 % smaller round than
# the hips, so that it grips them. Edges name outline points, walking forward.
length = 0.5
outline = [[-0.26, -length], [0.26, -length], [0.245, 0.0], [-0.245, 0.0]]
edges = {"right": [1, 2], "left": [3, 0]}
radius = 0.172  # wrapped on a cylinder just outside the mannequin's hips
waist = [0.0, 1.25, 0.0]
front = garment.panel("front", outline, edges=edges, origin=[waist[0], waist[1], radius],
                      wrap_radius=radius)
back = garment.panel("back", outline, edges=edges, origin=[waist[0], waist[1], -radius],
                     x_axis=[-1, 0, 0], wrap_radius=radius)
seams = [garment.seam("front.right", "back.left"), garment.seam("front.left", "back.right")]

# The body: the built-in mannequin (a floor and its colliders) with the garments' stepping and
# self-collision; the cloth: a light cotton.
body = rustcloth.load_scene("mannequin").replace(**garment.STEPPING,
                                                 self_collision=garment.SELF_COLLISION)
scene = garment.scene([front, back], seams, body=body, edge_length=pick(0.03, 0.06),
                      sew_time=0.2, seam_damping=garment.SEAM_DAMPING, **garment.COTTON)
sim = rustcloth.Simulation(scene)
print(f"{len(sim.positions)} vertices, {len(sim.triangles)} triangles; "
      f"seams {sim.seam_gap() * 100:.1f} cm open at the start")
for seconds in (0.3, pick(1.5, 0.6)):
    sim.advance(seconds - sim.time)
    y = sim.positions[:, 1]
    print(f"t = {sim.time:.2f} s: seams {sim.seam_gap() * 1000:.1f} mm open, waist at "
          f"{y.max():.3f} m, hem at {y.min():.3f} m, largest stretch {sim.max_stretch():.3f}")

out = OUT / "skirt.glb"
sim.export(out)
print(f"wrote {out}")
