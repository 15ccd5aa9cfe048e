"""``memory_bytes()`` counts the picking trees, which at 512 x 512 hold tens of megabytes. The
trees are built on the first query that uses them; what they hold is counted from then on: at
least a node box (24 bytes) per particle for the particle tree and per triangle for the
triangle tree."""

from __future__ import annotations

from conftest import small_scene
from rustcloth import Simulation


def test_memory_bytes_counts_the_picking_trees():
    sim = Simulation(small_scene(cloth={"nx": 128, "ny": 128}))
    n = sim.num_particles
    sim.pick_strategy = "bvh"
    before = sim.memory_bytes()
    sim.pick([0.1, 1.0, 2.0], [0, 0, -1])
    with_particle_tree = sim.memory_bytes()
    sim.pick_triangle([0.1, 1.0, 2.0], [0, 0, -1])
    with_both = sim.memory_bytes()
    stats = sim.bvh_stats()
    assert stats["particle_builds"] == 1 and stats["triangle_builds"] == 1
    assert with_particle_tree - before >= 24 * n
    assert with_both - with_particle_tree >= 24 * len(sim.triangles)
