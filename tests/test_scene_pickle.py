"""Scenes cross process boundaries: pickle, copy and multiprocessing round-trip them."""

from __future__ import annotations

import copy
import multiprocessing
import pickle

import rustcloth
from rustcloth import Scene


def _nx(scene: Scene) -> int:
    return int(scene.cloth["nx"])


def test_a_scene_survives_pickle_and_copy():
    # pickle and copy rebuild a Scene before its `_data` is set, so Scene.__getattr__ must not
    # answer `_data` from `_data` (a RecursionError, and a multiprocessing.Pool whose worker
    # died unpickling the scene would wait for good).
    scene = rustcloth.load_scene("drape").replace(dt=0.0005)
    for clone in (pickle.loads(pickle.dumps(scene)), copy.copy(scene), copy.deepcopy(scene)):
        assert clone == scene
        assert clone.to_dict() == scene.to_dict()


def test_scene_goes_through_a_process_pool():
    scene = rustcloth.load_scene("hanging")
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        result = pool.apply_async(_nx, (scene,)).get(timeout=60)
    assert result == scene.cloth["nx"]


def test_private_names_are_attribute_errors_not_scene_keys():
    scene = Scene()
    assert not hasattr(scene, "_missing")
    assert not hasattr(scene, "__wrapped__")


def test_load_scene_takes_a_toml_path(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(rustcloth.load_scene("curtain").to_toml())
    assert rustcloth.load_scene(str(path)) == rustcloth.load_scene("curtain")
    assert rustcloth.load_scene(path) == rustcloth.load_scene("curtain")
