"""Drape a cloth over a sphere and write it out: the last frame as glTF binary, OBJ and PLY,
and the whole run as one time-sampled USD file for Blender, Houdini or usdview.

    pip install 'rustcloth[export,usd]'
    python examples/drape_and_export.py          # writes out/drape.glb, .obj, .ply, .usda
"""

from __future__ import annotations

from pathlib import Path

import rustcloth
from _quick import pick, size
from rustcloth import export

FPS = 30.0
out = Path("out")
out.mkdir(exist_ok=True)

n = size(48, 16)
scene = rustcloth.load_scene("drape").replace(cloth={"nx": n, "ny": n})
sim = rustcloth.Simulation(scene)
seconds = pick(2.0, 0.3)

try:
    recorder: export.Recorder | None = export.recorder(out / "drape.usda", fps=FPS)
except ImportError as err:  # the usd extra is missing: the message says which to install
    print(f"no USD file: {err}")
    recorder = None

frames = round(seconds * FPS)
for k in range(frames + 1):
    # Frame k at the step nearest k / FPS: the USD file puts it on time code k.
    sim.step(round(k / FPS / sim.dt) - sim.steps)
    if recorder is not None:
        recorder.add(sim)
if recorder is not None:
    recorder.close()
    print(f"wrote {out / 'drape.usda'}: {frames + 1} frames at {FPS:g} fps")

mesh = sim.to_mesh()  # numpy arrays: vertices, triangles, normals, uvs
print(f"t = {sim.time:.2f} s: {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles, "
      f"lowest point {mesh.vertices[:, 1].min():.3f} m")
for suffix in (".glb", ".obj", ".ply"):
    print("wrote", sim.export(out / f"drape{suffix}"))
