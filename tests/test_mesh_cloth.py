"""A cloth from a triangle mesh through the Python API: ``Scene.with_cloth_mesh``, a mesh file
named by a scene (``mesh = "flag.obj"``, relative to the scene file), errors that name the
offending element, stepping with pins and a floor, snapshots, pickling and export."""

from __future__ import annotations

import pickle
import re

import numpy as np
import pytest
import rustcloth
from rustcloth.errors import ParameterError


def jittered_square(n: int, seed: int = 0, jitter: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """An ``n`` x ``n`` grid of points on a 1 m square (x, y), centred at (0, 1, 0), the interior
    ones jittered, each quad split along its shorter diagonal, counter-clockwise from +z."""
    rng = np.random.default_rng(seed)
    h = 1.0 / (n - 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    x = i * h - 0.5 + np.where((i > 0) & (i < n - 1), rng.uniform(-jitter, jitter, i.shape) * h, 0)
    y = j * h - 0.5 + np.where((j > 0) & (j < n - 1), rng.uniform(-jitter, jitter, j.shape) * h, 0)
    vertices = np.stack([x.ravel(), y.ravel() + 1.0, np.zeros(n * n)], axis=1)
    triangles = []
    for jj in range(n - 1):
        for ii in range(n - 1):
            a = jj * n + ii
            b, c, d = a + 1, a + n, a + n + 1
            if np.sum((vertices[a] - vertices[d]) ** 2) <= np.sum((vertices[b] - vertices[c]) ** 2):
                triangles += [[a, b, d], [a, d, c]]
            else:
                triangles += [[a, b, c], [b, d, c]]
    return vertices, np.array(triangles, dtype=np.int64)


def corner_pins() -> list[object]:
    return [{"box": [[-0.51, 1.44, -0.1], [-0.44, 1.51, 0.1]]},
            {"box": [[0.44, 1.44, -0.1], [0.51, 1.51, 0.1]]}]


def hanging(n: int = 10, **keys: object) -> rustcloth.Scene:
    vertices, triangles = jittered_square(n)
    scene = rustcloth.Scene(dt=0.0005).with_cloth_mesh(
        vertices, triangles, pins=corner_pins(), **keys
    )
    return scene


def test_a_mesh_cloth_hangs_from_its_pinned_vertices_and_keeps_its_mass() -> None:
    scene = hanging()
    sim = rustcloth.Simulation(scene)
    assert sim.num_particles == 100
    assert "mesh_springs" in sim.effects
    # Lumped from the areas: the whole square's density.
    assert sim.masses.sum() == pytest.approx(0.2, rel=1e-6)
    pinned = np.flatnonzero(sim.pinned)
    start = sim.positions[pinned].copy()
    sim.advance(0.5)
    x = sim.positions
    assert np.isfinite(x).all() and (np.abs(x) < 3).all()
    assert np.array_equal(x[pinned], start)
    assert x[:, 1].min() < 0.5 - 1e-3  # it fell and hangs


def test_bad_meshes_name_the_element() -> None:
    vertices, triangles = jittered_square(4)
    bad = vertices.copy()
    bad[5, 0] = np.nan
    last = len(triangles)
    flipped = triangles[:1, ::-1]  # the first triangle again, wound the other way
    cases = [
        (bad, triangles, "cloth.mesh.vertices[5]"),
        (vertices, np.vstack([triangles, [[0, 1, 99]]]), f"cloth.mesh.triangles[{last}]"),
        (vertices, np.vstack([triangles, flipped]), f"cloth.mesh.triangles[{last}]"),
        (vertices, triangles[1:], "cloth.mesh.vertices[0]"),
    ]
    for v, t, name in cases:
        with pytest.raises(ParameterError, match=r"^" + re.escape(name)):
            rustcloth.Scene().with_cloth_mesh(v, t)
    with pytest.raises(ParameterError, match=r"cloth.mesh.vertices: must have shape"):
        rustcloth.Scene().with_cloth_mesh(vertices[:, :2], triangles)
    with pytest.raises(ParameterError, match=r"^cloth.pins\[0\]"):
        rustcloth.Scene().with_cloth_mesh(vertices, triangles, pins=["top_corners"])


def test_tearing_and_cuts_once_refused_on_a_mesh_cloth_now_run() -> None:
    # Both were refused on a mesh cloth while only the grid's stencil could be cut.
    sim = rustcloth.Simulation(hanging(4).replace(tearing={}))
    assert "tearing" in sim.effects
    sim.step(10)
    sim.cut(0)
    assert not sim.alive[0]
    assert sim.pieces() == 1


def _goes_on_alike_restored_and_unpickled(sim: rustcloth.Simulation, before: int,
                                          after: int) -> None:
    # A state saved after `before` steps, pickled and set back, steps `after` more bitwise as
    # the run that saved it.
    sim.step(before)
    state = sim.get_state()
    copy = pickle.loads(pickle.dumps(sim))
    sim.step(after)
    copy.step(after)
    assert np.array_equal(copy.positions, sim.positions)
    assert np.array_equal(copy.velocities, sim.velocities)
    sim.set_state(state)
    sim.step(after)
    assert np.array_equal(copy.positions, sim.positions)
    assert np.array_equal(copy.velocities, sim.velocities)


def test_a_mesh_cloth_restores_and_unpickles_bitwise() -> None:
    sim = rustcloth.Simulation(hanging(8).replace(floor={"height": 0.8}))
    _goes_on_alike_restored_and_unpickled(sim, 100, 200)
    assert (sim.positions[:, 1] >= 0.8).all()


def test_a_stiff_implicit_mesh_cloth_reusing_its_solves_unpickles_bitwise() -> None:
    # Implicit Euler's mesh solve reuses earlier steps' work (the multigrid's coarse operators
    # for several steps, the last step's dv as CG's start), which a pickle does not hold: a run
    # pickled and restored mid-way must still go on exactly as the original.
    scene = hanging(16, stretch=3000.0, bend=300.0).replace(
        dt=1 / 60, integrator="implicit_euler", preconditioner="multigrid"
    )
    sim = rustcloth.Simulation(scene)
    _goes_on_alike_restored_and_unpickled(sim, 11, 13)
    x = sim.positions
    assert np.isfinite(x).all() and (np.abs(x) < 3).all()


def test_a_mesh_file_named_by_a_scene_is_read_beside_it(tmp_path) -> None:
    pytest.importorskip("trimesh")
    vertices, triangles = jittered_square(5)
    uvs = (vertices[:, :2] - vertices[:, :2].min(axis=0))
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += [f"vt {u} {v}" for u, v in uvs]
    lines += ["f " + " ".join(f"{k + 1}/{k + 1}" for k in t) for t in triangles]
    (tmp_path / "flag.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "flag.toml").write_text(
        '[cloth]\nmesh = "flag.obj"\npins = [0, 4]\n'
    )
    scene = rustcloth.Scene.from_toml(tmp_path / "flag.toml")
    sim = rustcloth.Simulation(scene)
    assert np.allclose(sim.positions, vertices.astype(np.float32))
    mesh = sim.to_mesh()
    assert np.array_equal(mesh.triangles, triangles)
    assert np.allclose(mesh.uvs, uvs, atol=1e-6)
    # Export keeps the vertex order and triangles.
    sim.step(10)
    sim.export(tmp_path / "out.obj")
    import trimesh

    back = trimesh.load(tmp_path / "out.obj", force="mesh", process=False, maintain_order=True)
    assert np.array_equal(np.asarray(back.faces), triangles)
    assert np.allclose(np.asarray(back.vertices), sim.positions, atol=1e-5)


def test_a_mesh_cloth_without_uvs_is_drawn_with_planar_ones() -> None:
    sim = rustcloth.Simulation(hanging(4))
    uvs = sim.to_mesh().uvs
    assert uvs.shape == (16, 2) and uvs.min() == 0.0 and uvs.max() == 1.0


def test_a_mesh_cloths_settings_have_the_typed_keys() -> None:
    from rustcloth import settings

    scene = hanging(4, density=0.3)
    # A mesh's masses come from its density: no `particle_mass`.
    assert set(scene.cloth) | {"particle_mass"} == set(settings.ClothSettings.__annotations__)
    # `uvs`, `seams` and `panels` (NotRequired) only when given.
    assert set(scene.cloth["mesh"]) | {"uvs", "seams", "panels"} == set(
        settings.MeshSettings.__annotations__)
    assert scene.cloth["mesh"]["density"] == 0.3


def test_the_triangle_membrane_runs_from_python_and_its_keys_are_checked() -> None:
    # The hanging sheet falls and stays bounded; the membrane's pass is in the profile (the
    # physics is tested in tests/mesh_membrane.rs).
    sim = rustcloth.Simulation(hanging(8, membrane="triangle", stretch=60.0))
    y0 = sim.positions[:, 1].mean()
    sim.advance(0.5)
    assert np.isfinite(sim.positions).all() and (np.abs(sim.positions) < 3).all()
    assert 0 < y0 - sim.positions[:, 1].mean() < 0.5
    assert "mesh_membrane" in sim.profile().passes
    bad = [({"membrane": "bogus"}, "cloth.mesh.membrane"),
           ({"membrane": "triangle", "poisson": 1.0}, "cloth.mesh.poisson"),
           ({"poisson": 0.2}, "cloth.mesh.poisson"),
           ({"membrane": "triangle", "integrator": "projective_dynamics"}, "cloth.mesh.membrane")]
    for keys, name in bad:
        integrator = keys.pop("integrator", None)
        scene = rustcloth.Scene(integrator=integrator) if integrator else rustcloth.Scene()
        with pytest.raises(ParameterError, match=r"^" + re.escape(name)):
            vertices, triangles = jittered_square(4)
            scene.with_cloth_mesh(vertices, triangles, **keys)
    sim = rustcloth.Simulation(hanging(4, membrane="triangle"))
    with pytest.raises(ParameterError, match=r"^cloth\.mesh\.membrane"):
        sim.integrator = "projective_dynamics"
    assert sim.integrator == "symplectic_euler"


def test_isometric_bending_runs_from_python_and_its_keys_are_checked() -> None:
    # The physics is tested in tests/mesh_bending.rs; here the keys reach it, survive a
    # round trip through the scene's dict, and bad ones are named.
    scene = hanging(8, bending="isometric", bend_modulus=1e-4, stretch=60.0)
    assert scene.cloth["mesh"]["bending"] == "isometric"
    assert scene.cloth["mesh"]["bend_modulus"] == 1e-4
    assert rustcloth.Scene.from_dict(scene.to_dict()).to_dict() == scene.to_dict()
    for integrator in ("symplectic_euler", "implicit_euler"):
        sim = rustcloth.Simulation(scene.replace(integrator=integrator, dt=0.0005))
        y0 = sim.positions[:, 1].mean()
        sim.advance(0.25)
        assert np.isfinite(sim.positions).all()
        assert 0 < y0 - sim.positions[:, 1].mean() < 0.5
    # A flat sheet at rest stores nothing (round-off of its float32 positions aside).
    assert rustcloth.Simulation(scene).energy().elastic == pytest.approx(0.0, abs=1e-9)
    vertices, triangles = jittered_square(4)
    curved = vertices.copy()
    curved[:, 2] = 0.3 * (curved[:, 0] ** 2)
    bad = [((vertices, {"bending": "bogus"}), "cloth.mesh.bending"),
           ((vertices, {"bend_modulus": 1e-4}), "cloth.mesh.bend_modulus"),
           ((vertices, {"bending": "isometric", "bend_modulus": -1.0}), "cloth.mesh.bend_modulus"),
           ((curved, {"bending": "isometric"}), "cloth.mesh.bending")]
    for (points, keys), name in bad:
        with pytest.raises(ParameterError, match=r"^" + re.escape(name)):
            rustcloth.Scene().with_cloth_mesh(points, triangles, **keys)


def test_the_demos_mouse_drags_a_mesh_cloth_and_cuts_it() -> None:
    pytest.importorskip("moderngl")  # rustcloth.viewer needs the viewer extra
    from rustcloth.viewer.interaction import Interaction

    sim = rustcloth.Simulation(hanging(6))
    before = sim.positions.copy()
    mouse = Interaction(sim)
    ray = (np.array([0.0, 1.0, 2.0]), np.array([0.0, 0.0, -1.0]))
    # A stroke sample alone sweeps nothing; the next one cuts from it.
    assert mouse.cut([(ray[0] + [0.0, 0.3, 0], ray[1])]) == 0
    assert mouse.cut([(ray[0] + [0.3, 0.3, 0], ray[1])]) > 0
    mouse.end_stroke()
    assert np.array_equal(sim.positions, before)
    assert mouse.grab(ray) is True
    held = sim.grabbed()
    assert held is not None and np.linalg.norm(before[held] - [0.0, 1.0, 0.0]) < 0.2
    sim.drag_to(before[held] + [0.0, 0.0, 0.1])
    sim.advance(sim.drag_time)  # the grip glides there over the drag time
    sim.step(1)
    assert np.allclose(sim.positions[held], before[held] + [0.0, 0.0, 0.1], atol=1e-6)


def test_a_mesh_cloth_is_pinned_by_its_boundary_or_its_top_row() -> None:
    n = 6
    scene = hanging(n).replace(cloth={"pins": [{"top": 1e-9}]})
    sim = rustcloth.Simulation(scene)
    assert np.array_equal(np.flatnonzero(sim.pinned), np.arange(n * n - n, n * n))
    scene = hanging(n).replace(cloth={"pins": [{"boundary": True}]})
    sim = rustcloth.Simulation(scene)
    i, j = np.arange(n * n) % n, np.arange(n * n) // n
    ring = (i == 0) | (j == 0) | (i == n - 1) | (j == n - 1)
    assert np.array_equal(sim.pinned, ring)
    with pytest.raises(ParameterError, match=r"^cloth.pins\[0\]: .*selects nothing"):
        hanging(n).replace(cloth={"pins": [{"boundary": False}]})


def write_grouped_square(path, n: int = 6) -> tuple[np.ndarray, set[int], set[int]]:
    """An OBJ of ``jittered_square(n)`` laid flat (its y as -z, at 1 m) whose top row of cells
    is group ``hem`` and whose left column is group ``side`` (the other triangles in neither);
    returns the vertices and each group's vertices, from the triangles written under it."""
    square, triangles = jittered_square(n)
    vertices = np.stack([square[:, 0], np.ones(len(square)), 1.0 - square[:, 1]], axis=1)
    row = (triangles // n).min(axis=1)  # the cell row of each triangle
    column = (triangles % n).min(axis=1)
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    groups: dict[str, set[int]] = {"hem": set(), "side": set()}
    for name, chosen in (("hem", row == n - 2), ("side", (column == 0) & (row < n - 2)),
                         ("", (column > 0) & (row < n - 2))):
        lines.append(f"g {name}".rstrip())
        for t in triangles[chosen]:
            lines.append("f " + " ".join(str(k + 1) for k in t))
            if name:
                groups[name].update(t.tolist())
    path.write_text("\n".join(lines) + "\n")
    return vertices, groups["hem"], groups["side"]


def test_a_mesh_cloth_hangs_from_its_files_vertex_group(tmp_path) -> None:
    pytest.importorskip("trimesh")
    vertices, hem, side = write_grouped_square(tmp_path / "flag.obj")
    assert hem == set(range(24, 36))  # the two top rows of the 6 x 6 square
    (tmp_path / "flag.toml").write_text('[cloth]\nmesh = "flag.obj"\npin_group = "hem"\n')
    sim = rustcloth.Simulation(rustcloth.Scene.from_toml(tmp_path / "flag.toml").replace(dt=5e-4))
    assert np.allclose(sim.positions, vertices.astype(np.float32))
    assert set(np.flatnonzero(sim.pinned).tolist()) == hem
    start = sim.positions.copy()
    sim.advance(0.3)
    x = sim.positions
    pinned = sim.pinned
    assert np.isfinite(x).all() and (np.abs(x) < 3).all()
    assert np.array_equal(x[pinned], start[pinned])
    # The hem holds while the rest swings down: every other vertex fell, the far edge most.
    assert (x[~pinned, 1] < start[~pinned, 1] - 1e-3).all()
    assert x[:, 1].min() < 0.8
    # Several groups, and the indices given beside them, pin their union.
    both = rustcloth.Scene().with_cloth_mesh(
        path=tmp_path / "flag.obj", pin_group=["hem", "side"], pins=[1]
    )
    assert set(rustcloth.Simulation(both).pinned.nonzero()[0].tolist()) == hem | side | {1}


def test_a_pin_group_the_file_lacks_is_named_with_the_files_groups(tmp_path) -> None:
    trimesh = pytest.importorskip("trimesh")
    write_grouped_square(tmp_path / "flag.obj")
    scene = rustcloth.Scene()
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: .*flag\.obj' has no group "
                                             r"'hemline'; its groups: 'hem', 'side'$"):
        scene.with_cloth_mesh(path=tmp_path / "flag.obj", pin_group="hemline")
    plain = tmp_path / "plain.obj"
    vertices, triangles = jittered_square(3)
    plain.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in vertices.tolist())
                     + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in triangles))
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: .*plain\.obj' has no vertex"):
        scene.with_cloth_mesh(path=plain, pin_group="hem")
    stl = tmp_path / "flag.stl"
    trimesh.Trimesh(*jittered_square(3), process=False).export(stl)
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: .*flag\.stl' has no vertex"):
        scene.with_cloth_mesh(path=stl, pin_group="hem")
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: names vertex groups"):
        scene.with_cloth_mesh(*jittered_square(3), pin_group="hem")
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: names vertex groups"):
        rustcloth.Scene.from_toml_str('[cloth]\nnx = 4\nny = 4\npin_group = "hem"\n')
    with pytest.raises(rustcloth.ParameterTypeError, match=r"^cloth\.pin_group: must be"):
        scene.with_cloth_mesh(path=tmp_path / "flag.obj", pin_group=[])


def write_two_part_gltf(path, hem_node: str = "hem") -> tuple[np.ndarray, set[int]]:
    """A cloth of two named parts, as a modelling tool writes a glTF: the body (a 6 x 6
    jittered 1 m square, its mesh named "cloth") and a separate strip above it, placed by its
    node (moved 0.2 m up) named ``hem_node``, its mesh named "strip". Returns the placed
    vertices in the order trimesh concatenates the parts, and the strip's."""
    trimesh = pytest.importorskip("trimesh")
    body = trimesh.Trimesh(*jittered_square(6), process=False)
    strip = trimesh.Trimesh(vertices=[[0, 1.5, 0], [1, 1.5, 0], [1, 1.7, 0], [0, 1.7, 0]],
                            faces=[[0, 1, 2], [0, 2, 3]], process=False)
    scene = trimesh.Scene()
    scene.add_geometry(body, node_name="body", geom_name="cloth")
    scene.add_geometry(strip, node_name=hem_node, geom_name="strip",
                       transform=trimesh.transformations.translation_matrix([0, 0.2, 0]))
    scene.export(path)
    parts = trimesh.load_scene(path, process=False).dump()
    placed = np.concatenate([p.vertices for p in parts])
    start = sum(len(p.vertices) for p in parts[:[p.metadata["node"] for p in parts].index(
        hem_node)])
    return placed, set(range(start, start + 4))


def test_a_mesh_cloth_pins_a_named_part_of_a_gltf_file(tmp_path) -> None:
    placed, hem = write_two_part_gltf(tmp_path / "flag.glb")
    for group in ("hem", "strip"):  # the node's name and the mesh's
        scene = rustcloth.Scene().with_cloth_mesh(path=tmp_path / "flag.glb", pin_group=group)
        sim = rustcloth.Simulation(scene.replace(dt=5e-4))
        assert np.allclose(sim.positions, placed.astype(np.float32))
        assert set(np.flatnonzero(sim.pinned).tolist()) == hem
        assert np.allclose(sim.positions[sim.pinned][:, 1], [1.7, 1.7, 1.9, 1.9])
    with pytest.raises(ParameterError, match=r"^cloth\.pin_group: .*flag\.glb' has no group "
                                             r"'hemline'; its groups: 'body', 'cloth', 'hem', "
                                             r"'strip'$"):
        rustcloth.Scene().with_cloth_mesh(path=tmp_path / "flag.glb", pin_group="hemline")


def test_implicit_euler_on_a_mesh_builds_the_multigrid_of_each_step_once():
    # An energy-judged step split into halves and back alternates two steps: each step's
    # hierarchy is kept and found again, not rebuilt at every change (as a garment held by
    # friction at rest did, twice a step).
    vertices, triangles = jittered_square(12)
    scene = rustcloth.Scene(integrator="implicit_euler", dt=1 / 120,
                            preconditioner="multigrid").with_cloth_mesh(
        vertices, triangles, pins=[{"top": 0.001}])
    sim = rustcloth.Simulation(scene)
    for k in range(8):
        sim.dt = 1 / 120 if k % 2 == 0 else 1 / 240
        sim.step(1)
    assert sim.solver_stats()["factorizations"] == 2
