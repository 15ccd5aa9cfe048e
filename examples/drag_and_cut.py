"""Drag and cut from a script, as the demo's mouse does: pick the particle under a ray, drag it
along a path, then cut the cloth along a stroke of rays and count the pieces.

    python examples/drag_and_cut.py
"""

from __future__ import annotations

import numpy as np
import rustcloth
from _quick import pick, size

n = size(32, 12)
sim = rustcloth.Simulation(rustcloth.load_scene("hanging").replace(cloth={"nx": n, "ny": n}))
sim.advance(pick(1.0, 0.2))  # let it settle

# A camera in front of the settled cloth, 3 m out along its mean normal.
centre = sim.positions.mean(axis=0)
normal = sim.normals.mean(axis=0)
normal /= np.linalg.norm(normal)
eye = centre + 3.0 * normal

# Grab the particle under a ray through the cloth's lower-left quarter, and drag it out.
corner = sim.positions[0] * 0.5 + centre * 0.5
hit = sim.pick(eye, corner - eye)
assert hit is not None, "the ray missed the cloth"
index, distance = hit
print(f"grabbed particle {index} at {distance:.2f} m from the eye")
sim.grab(index)
start = sim.positions[index].copy()
for s in np.linspace(0.0, 1.0, 20):
    sim.drag_to(start + s * 0.4 * normal)  # pull it towards the camera
    sim.step(10)
sim.release()

# Cut along a stroke: a fan of rays from the eye sweeping across the cloth's middle, as a
# mouse drag would cast them. Severed springs never come back; no particle is removed.
left, right = sim.positions[:, 0].min(), sim.positions[:, 0].max()
rays = [(eye, np.array([x, centre[1], centre[2]]) - eye)
        for x in np.linspace(left - 0.1, right + 0.1, 24)]
severed = sim.sever_stroke(rays)
sim.advance(pick(1.0, 0.2))
print(f"severed {severed} springs; the cloth is in {sim.pieces()} pieces, "
      f"lowest point {sim.positions[:, 1].min():.2f} m")
