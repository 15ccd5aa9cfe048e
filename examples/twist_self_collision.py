"""Self-collision: the built-in `twist` scene, its pinned edges turned in opposite directions by
`rustcloth.drivers.TwistDriver` until the cloth winds into a rope on itself, never passing
through itself; the pass's counters and the frame time printed as it goes.

    python examples/twist_self_collision.py     # 48 x 48 for 2.5 s: about a minute on 2 cores

`[self_collision]` in a scene turns the pass on (absent, it costs nothing); `thickness` is the
gap it keeps between layers, and `solve_stiffness` holds the pairs ahead inside implicit
Euler's solve, so a 1/60 s frame needs a few steps, not dozens (docs/contact.md).
"""

from __future__ import annotations

import time

import rustcloth
from _quick import pick, size
from rustcloth.drivers import TwistDriver

n = size(48, 24)
scene = rustcloth.load_scene("twist").replace(cloth={"nx": n, "ny": n})
print(f"twist at {n} x {n}: {scene.integrator}, dt {scene.dt:g} s, "
      f"self_collision {scene.self_collision}")
sim = rustcloth.Simulation(scene)
driver = TwistDriver(sim)
steps_per_frame = max(1, round(1 / 60 / sim.dt))

seconds = pick(2.5, 0.5)
for frame in range(round(seconds * 60)):
    start = time.perf_counter()
    for _ in range(steps_per_frame):
        driver.before_step(sim)  # the edges' pins move to this step's angle
        sim.step(1)
    ms = (time.perf_counter() - start) * 1e3
    if (frame + 1) % 30 == 0 or frame + 1 == round(seconds * 60):
        stats = sim.self_collision_stats()
        print(f"t = {sim.time:.2f} s: {ms:6.1f} ms this frame, {stats['contacts']:>7} contacts "
              f"repelled so far, closest layers {stats['min_distance'] * 1e3:.2f} mm apart "
              f"(thickness {scene.self_collision['thickness'] * 1e3:.1f} mm), largest stretch "
              f"{sim.max_stretch():.3f}")
