"""The ``colliders`` scene key through Python: a box stops a falling cloth, the pass is listed
in ``effects`` and ``profile()``, bad values raise ``ValueError`` naming the parameter."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest
import rustcloth

BOX = {"shape": "box", "half_extents": [0.3, 0.1, 0.3], "center": [0.0, 0.0, 0.0]}


def _box_distance(points: np.ndarray, half: np.ndarray) -> np.ndarray:
    # Signed distance to an axis-aligned box at the origin (negative inside).
    d = np.abs(points) - half
    return np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)


def test_a_box_collider_stops_a_falling_cloth() -> None:
    scene = rustcloth.Scene(
        cloth={"nx": 16, "ny": 16, "size": [0.5, 0.5], "center": [0.0, 0.3, 0.0], "pins": []},
        colliders=[BOX],
    )
    sim = rustcloth.Simulation(scene)
    assert "colliders" in sim.effects
    half = np.array(BOX["half_extents"])
    for _ in range(40):
        sim.step(10)
        pos = sim.positions.astype(np.float64)
        assert np.isfinite(pos).all() and (np.abs(pos) < 10).all()
        assert _box_distance(pos, half).min() >= 0.002 - 1e-6
    # Resting on top, not fallen past.
    assert abs(pos[:, 1].max() - 0.102) < 1e-3
    assert "colliders" in sim.profile().passes


def test_the_scene_keeps_the_colliders() -> None:
    scene = rustcloth.Scene(colliders=[dict(BOX, velocity=[0.1, 0.0, 0.0])])
    (collider,) = scene.colliders
    assert collider["velocity"] == [0.1, 0.0, 0.0]
    assert collider["friction"] == 0.3
    assert "1 collider(s)" in repr(scene)
    assert rustcloth.Scene.from_toml_str(scene.to_toml()) == scene


@pytest.mark.parametrize(
    ("collider", "name"),
    [
        ({"shape": "box"}, "colliders[0].half_extents"),
        ({"shape": "sphere", "radius": -1.0}, "colliders[0].radius"),
        ({"shape": "capsule", "radius": 1.0}, "colliders[0].half_height"),
        ({"shape": "cylinder", "radius": 1.0, "half_height": 1.0, "friction": float("nan")},
         "colliders[0].friction"),
    ],
)
def test_bad_colliders_raise_naming_the_parameter(collider: dict[str, object], name: str) -> None:
    with pytest.raises(ValueError, match=name.replace("[", r"\[").replace("]", r"\]")):
        rustcloth.Scene(colliders=[collider])


def _box_mesh(half: list[float]) -> tuple[np.ndarray, np.ndarray]:
    # 8 corners (x from bit 0, y from bit 1, z from bit 2); 12 triangles counter-clockwise
    # seen from outside.
    corners = np.array([[(k >> b & 1) * 2 - 1 for b in range(3)] for k in range(8)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3]]
    triangles = np.array([t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])])
    return corners * np.array(half), triangles


def _falling(**keys: object) -> rustcloth.Scene:
    return rustcloth.Scene(
        cloth={"nx": 16, "ny": 16, "size": [0.5, 0.5], "center": [0.0, 0.3, 0.0], "pins": []},
        **keys,
    )


def test_a_plane_and_a_mesh_box_stop_the_cloth_where_the_box_does() -> None:
    half = np.array(BOX["half_extents"])
    vertices, triangles = _box_mesh(list(half))
    box = rustcloth.Simulation(_falling(colliders=[BOX]))
    mesh_scene = _falling().with_mesh_collider(vertices, triangles, center=[0, 0, 0])
    mesh = rustcloth.Simulation(mesh_scene)
    plane = rustcloth.Simulation(_falling(colliders=[{"shape": "plane", "center": [0, 0.1, 0]}]))
    for sim in (box, mesh, plane):
        sim.step(400)
        pos = sim.positions.astype(np.float64)
        assert np.isfinite(pos).all() and (np.abs(pos) < 10).all()
    assert _box_distance(mesh.positions.astype(np.float64), half).min() >= 0.002 - 1e-6
    middle = 8 * 16 + 8
    for sim in (mesh, plane):
        assert abs(sim.positions[middle, 1] - box.positions[middle, 1]) < 1e-5


def _write_box_obj(path: object, half: list[float]) -> None:
    vertices, triangles = _box_mesh(half)
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    with open(str(path), "w") as f:
        f.write("\n".join(lines) + "\n")


def test_a_mesh_file_gives_the_scene_its_arrays(tmp_path: object) -> None:
    pytest.importorskip("trimesh")
    obj = f"{tmp_path}/box.obj"
    _write_box_obj(obj, [0.3, 0.1, 0.3])
    vertices, triangles = _box_mesh([0.3, 0.1, 0.3])
    from_arrays = rustcloth.Scene().with_mesh_collider(vertices, triangles, friction=0.5)
    from_file = rustcloth.Scene().with_mesh_collider(path=obj, friction=0.5)
    assert from_file == from_arrays
    # A TOML scene names the file relative to itself.
    toml = f"{tmp_path}/scene.toml"
    with open(toml, "w") as f:
        f.write('[[colliders]]\nshape = "mesh"\npath = "box.obj"\nfriction = 0.5\n')
    assert rustcloth.Scene.from_toml(toml) == from_arrays


def _named(name: str) -> str:
    return name.replace("[", r"\[").replace("]", r"\]")


@pytest.mark.parametrize(
    ("change", "name"),
    [
        (lambda v, t: v.__setitem__((2, 1), np.nan), "colliders[0].vertices[2][1]"),
        (lambda v, t: v.__setitem__((0, 0), np.inf), "colliders[0].vertices[0][0]"),
        (lambda v, t: t.__setitem__((3, 2), 8), "colliders[0].triangles[3]"),
        (lambda v, t: t.__setitem__((5, 1), t[5, 0]), "colliders[0].triangles[5]"),
        (lambda v, t: t.__setitem__(slice(None), t[:, ::-1]), "colliders[0].triangles"),
    ],
)
def test_bad_meshes_raise_naming_the_parameter(change: Any, name: str) -> None:
    vertices, triangles = _box_mesh([0.3, 0.1, 0.3])
    change(vertices, triangles)
    with pytest.raises(ValueError, match=_named(name)):
        rustcloth.Scene().with_mesh_collider(vertices, triangles)


def test_empty_missing_and_malformed_meshes_raise_naming_the_parameter(tmp_path: object) -> None:
    pytest.importorskip("trimesh")
    with pytest.raises(ValueError, match=_named("colliders[0].triangles")):
        rustcloth.Scene(colliders=[{"shape": "mesh", "vertices": [[0, 0, 0]] * 3,
                                    "triangles": []}])
    with pytest.raises(ValueError, match=_named("colliders[0].path") + ": no such file"):
        rustcloth.Scene().with_mesh_collider(path=f"{tmp_path}/missing.obj")
    bad = f"{tmp_path}/bad.obj"
    with open(bad, "w") as f:
        f.write("this is not\nan OBJ file\n")
    with pytest.raises(ValueError, match=_named("colliders[0].path")):
        rustcloth.Scene().with_mesh_collider(path=bad)
    with pytest.raises(ValueError, match=_named("colliders[1].path")):
        rustcloth.Scene(colliders=[BOX, {"shape": "mesh", "path": bad}])


def _resting_on_a_box() -> rustcloth.Simulation:
    box = {"shape": "box", "half_extents": [1.0, 0.1, 1.0], "center": [0, 0, 0], "friction": 0.8}
    return rustcloth.Simulation(rustcloth.Scene(
        cloth={"nx": 12, "ny": 12, "size": [0.5, 0.5], "center": [0.0, 0.1021, 0.0],
               "pins": []},
        colliders=[box],
    ))


def test_a_box_posed_every_step_carries_the_cloth_at_its_speed() -> None:
    sim, v = _resting_on_a_box(), 0.5
    for _ in range(1000):
        sim.set_collider_pose(0, [v * (sim.time + sim.dt), 0, 0], [0, 0, 0, 1])
        sim.step()
    mean_vx = sim.velocities[:, 0].astype(np.float64).mean()
    assert abs(mean_vx - v) < 0.03 * v
    positions, rotations = sim.collider_poses()
    assert positions.shape == (1, 3) and rotations.shape == (1, 4)
    assert abs(positions[0, 0] - v * sim.time) < 1e-9
    assert np.allclose(rotations[0], [0, 0, 0, 1])
    (shape,) = sim.colliders()
    assert shape == {"shape": "box", "thickness": 0.002, "half_extents": [1.0, 0.1, 1.0]}
    # The pose survives a pickle: the copy continues bit for bit.
    copy = pickle.loads(pickle.dumps(sim))
    sim.step(5)
    copy.step(5)
    assert np.array_equal(sim.positions, copy.positions)


@pytest.mark.parametrize(
    ("index", "position", "rotation", "error", "name"),
    [
        (1, [0, 0, 0], [0, 0, 0, 1], IndexError, "index"),
        (-1, [0, 0, 0], [0, 0, 0, 1], IndexError, "index"),
        (0, [0, np.nan, 0], [0, 0, 0, 1], ValueError, "position"),
        (0, [0, 0, 0], [0, 0, 0, 2], ValueError, "rotation"),
        (0, [0, 0, 0], [np.nan, 0, 0, 1], ValueError, "rotation"),
        (0, [0, 0, 0], [0, 0, 1], ValueError, "rotation"),
        (0, [0, 0, 0], "abcd", TypeError, "rotation"),
    ],
)
def test_bad_poses_raise_naming_the_parameter_and_change_nothing(
    index: int, position: list[float], rotation: Any, error: type, name: str
) -> None:
    sim, reference = _resting_on_a_box(), _resting_on_a_box()
    with pytest.raises(error, match=name):
        sim.set_collider_pose(index, position, rotation)
    sim.step(50)
    reference.step(50)
    assert np.array_equal(sim.positions, reference.positions)
    assert np.array_equal(sim.collider_poses()[0], reference.collider_poses()[0])
