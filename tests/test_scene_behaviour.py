"""The showcase scenes do what their names say, checked from the API as the demo runs them:
``fold`` folds over its bar and stays, ``pile`` piles (``flag`` flies: tests/wind.rs)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import rustcloth


def footprint(positions: npt.NDArray[np.float32], triangles: npt.NDArray[np.uint32],
              cell: float = 0.01) -> float:
    """Area (m^2) the cloth covers seen from above: the union of its triangles projected on the
    floor, on a raster of ``cell``-sized squares (a square counts when its centre is covered)."""
    xz = positions[:, [0, 2]].astype(np.float64)
    lo = xz.min(axis=0)
    covered = np.zeros(tuple(np.ceil((xz.max(axis=0) - lo) / cell).astype(int) + 1), bool)
    for tri in xz[triangles]:
        a, b, c = tri
        i0, k0 = np.floor((tri.min(axis=0) - lo) / cell).astype(int)
        i1, k1 = np.ceil((tri.max(axis=0) - lo) / cell).astype(int)
        gi, gk = np.meshgrid(np.arange(i0, i1 + 1), np.arange(k0, k1 + 1), indexing="ij")
        px = lo[0] + (gi + 0.5) * cell
        pz = lo[1] + (gk + 0.5) * cell
        # Which side of each edge the square's centre is on.
        d = np.stack([(q[0] - p[0]) * (pz - p[1]) - (q[1] - p[1]) * (px - p[0])
                      for p, q in ((a, b), (b, c), (c, a))])
        inside = (d >= 0).all(axis=0) | (d <= 0).all(axis=0)
        gi, gk = gi[inside], gk[inside]
        ok = (gi < covered.shape[0]) & (gk < covered.shape[1])
        covered[gi[ok], gk[ok]] = True
    return float(covered.sum()) * cell * cell


def test_footprint_of_a_flat_square_is_its_area():
    sim = rustcloth.Simulation(rustcloth.load_scene("freefall"))
    area = footprint(sim.positions, sim.triangles)
    assert abs(area - 1.0) < 0.03, area


def test_fold_folds_over_its_bar_and_is_still_there_after_five_seconds():
    sim = rustcloth.Simulation(rustcloth.load_scene("fold"))
    sim.advance(5.0)
    p = sim.positions
    # Folded over a bar 0.6 m up: both halves hang below it and none of the cloth lies on the
    # floor; the particles that landed on the bar are still on it.
    assert p[:, 1].max() < 0.65 and p[:, 1].min() > 0.05, (p[:, 1].min(), p[:, 1].max())
    on_bar = np.abs(p[:, 1] - 0.6) < 0.05
    assert on_bar.sum() >= 20, on_bar.sum()
    halves = p[:, 2] > 0
    assert 0.3 < halves.mean() < 0.7, halves.mean()



def pile_shape(sim: rustcloth.Simulation) -> tuple[float, float]:
    """The cloth's footprint (m^2, seen from above) and height (m, highest minus lowest)."""
    p = sim.positions
    return footprint(p, sim.triangles), float(p[:, 1].max() - p[:, 1].min())


def test_pile_piles_into_a_footprint_under_a_third_of_its_area_and_several_layers_high():
    sim = rustcloth.Simulation(rustcloth.load_scene("pile"))
    width, depth = sim.scene.cloth["size"]
    gap = sim.scene.self_collision["thickness"]
    sim.advance(3.0)
    assert np.isfinite(sim.positions).all() and (abs(sim.positions) < 10).all()
    area, height = pile_shape(sim)
    # Several layers: ten self-collision gaps at the least (it lies about 0.15 m high). A square
    # dropped edge first lands as a band of folds as wide as itself, a third of its area; this
    # one is lowered held by its centre, so its width gathers too (benches/pile_footprint.py).
    assert height > 10 * gap, height
    assert area < width * depth / 3, area
    # Settled, not still falling or jittering: it lands at up to 3 m/s.
    speed = float(np.linalg.norm(sim.velocities, axis=1).max())
    assert speed < 0.5, speed


def test_the_built_in_pile_comes_to_rest_and_never_gains_energy_once_it_has_landed():
    sim = rustcloth.Simulation(rustcloth.load_scene("pile"))
    # The ball that lowers it has sunk through the floor by 2.8 s; after that nothing does work
    # on the cloth, so its energy (kinetic + gravity + springs) may only fall.
    sim.advance(3.0)
    before = sum(sim.energy())
    worst = 0.0
    for _ in range(120):
        sim.advance(1 / 60)
        now = sum(sim.energy())
        worst = max(worst, now - before)
        before = now
    # The pass after the solve still pushes the pairs the in-solve penalty leaves a little inside
    # `thickness` back out to it: about a millijoule a frame at most (of about 1 J), where the
    # solve holding none of the pairs its springs close gave up to 27 mJ
    # (docs/notes/contact.md, "Why the pile shivered").
    assert worst < 2.5e-3, worst
    speed = np.linalg.norm(sim.velocities, axis=1)
    # At rest by 5 s: a handful of particles above 0.1 m/s at most (20-90 and up to 0.45 m/s
    # while it shivered).
    assert speed.max() < 0.25 and (speed > 0.1).sum() <= 5, (speed.max(), (speed > 0.1).sum())


def test_every_scene_with_self_collision_opens_and_steps_with_the_pass_active():
    # The demo opens a scene as it ships: one that has [self_collision] must run the pass from
    # its first step (docs/contact.md, "Self-collision in the scenes").
    names = [n for n in rustcloth.scenes() if rustcloth.load_scene(n).self_collision is not None]
    assert {"freefall", "fold", "pile", "twist"} <= set(names), names
    for name in names:
        sim = rustcloth.Simulation(name)
        assert "self_collision" in sim.effects, name
        sim.step(3)
        stats = sim.self_collision_stats()
        assert stats is not None and stats["substeps"] == 3 * sim.scene.substeps, (name, stats)
        assert np.isfinite(sim.positions).all(), name
