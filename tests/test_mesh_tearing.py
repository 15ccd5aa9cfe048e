"""Tearing and cuts on a mesh cloth from Python: the scene's ``[tearing]`` and the cut calls
accepted, a stroke across giving two pieces of which the lower falls, and the severed springs
surviving ``get_state``/``set_state`` and pickling bitwise. The physics is tested in
tests/meshtear.rs; this checks the binding."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import rustcloth
from rustcloth.errors import ParameterError
from test_mesh_cloth import jittered_square


def held_by_its_top(n: int = 12) -> rustcloth.Scene:
    vertices, triangles = jittered_square(n)
    return rustcloth.Scene(dt=0.0005).with_cloth_mesh(vertices, triangles, pins=[{"top": 1e-9}])


def across(y: float) -> list[tuple[np.ndarray, np.ndarray]]:
    return [(np.array([x, y, 2.0]), np.array([0.0, 0.0, -1.0])) for x in np.linspace(-1, 1, 11)]


def test_a_stroke_across_a_mesh_cloth_gives_two_pieces_and_the_lower_falls() -> None:
    sim = rustcloth.Simulation(held_by_its_top())
    sim.step(10)
    version = sim.topology_version
    triangles = len(sim.triangles)
    assert sim.sever_stroke(across(1.02)) > 0
    assert sim.topology_version == version + 1
    assert sim.pieces() == 2
    assert len(sim.triangles) < triangles
    labels = sim.piece_labels()
    lower = labels == labels[np.argmin(sim.positions[:, 1])]
    assert not sim.pinned[lower].any()
    y0, v0 = sim.positions[lower, 1].mean(), sim.velocities[lower, 1].mean()
    sim.step(200)
    t = 200 * sim.dt
    drop = y0 + v0 * t - sim.positions[lower, 1].mean()
    # The lower piece's vertices have unequal masses: the plain mean is not its centre of mass,
    # so the free fall holds to a few per cent here (exactly in tests/meshtear.rs).
    assert drop == pytest.approx(9.81 * t * t / 2, rel=0.05)
    # The drawn mesh has no triangle across the cut.
    for tri in sim.triangles:
        assert len(set(labels[tri])) == 1


def test_a_mesh_cuts_drawn_mesh_has_its_cut_vertices_in_every_array(tmp_path) -> None:
    # The drawn mesh of a cut mesh cloth has cut vertices past the particles: its positions,
    # normals, texture coordinates and sources all have them, and the frame and export use them.
    sim = rustcloth.Simulation(held_by_its_top())
    assert sim.sever_stroke(across(1.02)) > 0
    tris, uvs, sources = sim.render_topology()
    positions, normals = sim.render_positions()
    assert len(positions) > sim.num_particles
    assert len(uvs) == len(normals) == len(sources) == len(positions)
    assert tris.max() == len(positions) - 1
    cut = positions[sim.num_particles:]
    assert np.abs(cut[:, 1] - 1.02).max() < 1e-5  # on the stroke: the sheet is still flat
    mesh = sim.to_mesh()
    assert len(mesh.vertices) == len(positions) and np.isfinite(mesh.uvs).all()
    assert ((0 <= mesh.uvs) & (mesh.uvs <= 1)).all()


def test_a_torn_mesh_cloth_restores_and_unpickles_bitwise() -> None:
    sim = rustcloth.Simulation(held_by_its_top(10).replace(tearing={"max_strain": 0.2}))
    pos = sim.positions.copy()
    pos[:, 0] *= 1.3
    sim.set_positions(pos)
    sim.step(1)
    state = sim.get_state()
    assert not state["mesh_springs"].all()
    copy = pickle.loads(pickle.dumps(sim))
    assert np.array_equal(copy.get_state()["mesh_springs"], state["mesh_springs"])
    assert np.array_equal(copy.triangles, sim.triangles)
    sim.step(100)
    copy.step(100)
    assert np.array_equal(copy.positions, sim.positions)
    sim.set_state(state)
    sim.step(100)
    assert np.array_equal(copy.positions, sim.positions)


def test_a_state_with_the_wrong_mesh_springs_is_refused_by_name() -> None:
    sim = rustcloth.Simulation(held_by_its_top(6))
    state = sim.get_state()
    state["mesh_springs"] = state["mesh_springs"][:-1]
    with pytest.raises(ParameterError, match="mesh_springs"):
        sim.set_state(state)
