"""A big mesh collider stays numpy arrays from the caller to the core and back: the scene
keeps read-only float64 and int64 arrays (its own copy, shared by every ``to_dict``), never
Python lists of lists, whose millions of objects would make a big mesh slow to become a
simulation. The arrays' checks are the lists' checks: a NaN deep in a big array is named by
its index, too deep an array is refused, and TOML still writes plain numbers."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import rustcloth
from mesh_shapes import torus
from rustcloth import _core


@pytest.fixture(scope="module")
def big() -> tuple[np.ndarray, np.ndarray]:
    return torus(500, 200)  # 200,000 triangles


def test_big_mesh_is_kept_as_read_only_arrays(big: tuple[np.ndarray, np.ndarray]) -> None:
    vertices, triangles = big
    scene = rustcloth.Scene().with_mesh_collider(vertices, triangles)
    for collider in (scene.colliders[0], scene.to_dict()["colliders"][0]):
        v, t = collider["vertices"], collider["triangles"]
        assert isinstance(v, np.ndarray) and v.dtype == np.float64 and v.shape == vertices.shape
        assert isinstance(t, np.ndarray) and t.dtype == np.int64 and t.shape == triangles.shape
        assert not v.flags.writeable and not t.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            v[0, 0] = 1.0
        np.testing.assert_array_equal(v, vertices)
        np.testing.assert_array_equal(t, triangles)


def test_changing_the_callers_arrays_leaves_the_scene_as_built() -> None:
    vertices, triangles = torus(20, 10)
    scene = rustcloth.Scene().with_mesh_collider(vertices.copy(), triangles.copy())
    given_v, given_t = vertices.copy(), triangles.copy()
    twin = rustcloth.Scene().with_mesh_collider(given_v, given_t)
    given_v[:] = 7.0
    given_t[:] = 0
    assert twin == scene
    np.testing.assert_array_equal(twin.colliders[0]["vertices"], vertices)
    np.testing.assert_array_equal(twin.colliders[0]["triangles"], triangles)


def test_nan_deep_in_a_big_array_is_named_by_its_index(
    big: tuple[np.ndarray, np.ndarray],
) -> None:
    vertices = big[0].copy()
    vertices[87_654, 1] = np.nan
    with pytest.raises(rustcloth.ParameterError, match=r"colliders\[0\]\.vertices\[87654\]"):
        rustcloth.Scene().with_mesh_collider(vertices, big[1])
    # The core's own reader of arrays, without the Python layer in front of it.
    data = rustcloth.Scene().to_dict()
    data["colliders"] = [{"shape": "mesh", "vertices": vertices, "triangles": big[1]}]
    with pytest.raises(ValueError, match=r"colliders\[0\]\.vertices\[87654\]\[1\]"):
        _core.normalize_scene(data)


@pytest.mark.parametrize(
    ("vertices", "error", "name"),
    [
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, True]], dtype=object), TypeError,
         r"colliders\[0\]\.vertices\[2\]\[2\]"),
        (np.ones((3, 3), dtype=bool), TypeError, r"colliders\[0\]\.vertices\[0\]\[0\]"),
        (np.ones((3, 3), dtype=complex), TypeError, r"colliders\[0\]\.vertices\[0\]\[0\]"),
        (np.ones((3,) + (1,) * 30), ValueError, r"colliders\[0\]\.vertices.*nest at most"),
    ],
)
def test_arrays_the_core_reads_are_checked_as_lists_are(
    vertices: np.ndarray, error: type[Exception], name: str
) -> None:
    data = rustcloth.Scene().to_dict()
    data["colliders"] = [{"shape": "mesh", "vertices": vertices, "triangles": [[0, 1, 2]]}]
    with pytest.raises(error, match=name):
        rustcloth.Scene.from_dict(data)
    with pytest.raises(error, match=name):
        _core.normalize_scene(data)


def test_array_scene_round_trips() -> None:
    vertices, triangles = torus(20, 10)
    scene = rustcloth.Scene().with_mesh_collider(vertices, triangles, friction=0.3)
    assert pickle.loads(pickle.dumps(scene)) == scene
    assert rustcloth.Scene.from_dict(scene.to_dict()) == scene
    text = scene.to_toml()
    assert "array" not in text and "vertices = [[" in text.replace("\n", "")
    assert rustcloth.Scene.from_toml_str(text) == scene
    lists = rustcloth.Scene().with_mesh_collider(vertices.tolist(), triangles.tolist(),
                                                 friction=0.3)
    assert lists == scene and hash(lists) == hash(scene)
    assert scene != rustcloth.Scene().with_mesh_collider(vertices[:, ::-1], triangles[:, ::-1],
                                                         friction=0.3)
    sim = rustcloth.Simulation(scene)
    assert sim.scene == scene
