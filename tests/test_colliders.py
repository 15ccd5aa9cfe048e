"""The ``colliders`` scene key through Python: a box stops a falling cloth, the pass is listed
in ``effects`` and ``profile()``, bad values raise ``ValueError`` naming the parameter."""

from __future__ import annotations

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
