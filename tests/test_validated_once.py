"""A scene is validated once on its way into a simulation, whichever way it comes: with a big
mesh collider each validation checks every vertex and builds the closedness test's edge map
(about a second at a million triangles). The core counts the validations each thread makes
(``_core._scene_validations``), so the tests count them rather than time them.

``set_state`` and unpickling used to validate a state's scene twice: once as the binding read
it, for the particle count its arrays are checked against, and again as the simulation was
built from it. Now the simulation is built first, and the arrays are checked against it."""

from __future__ import annotations

import pickle
from collections.abc import Callable

import numpy as np
import pytest
import rustcloth
from conftest import full_digest
from rustcloth import _core


def _validations(call: Callable[[], object]) -> int:
    before = _core._scene_validations()
    call()
    return _core._scene_validations() - before


def _stepped() -> rustcloth.Simulation:
    sim = rustcloth.Simulation("hanging")
    sim.grab(5)
    sim.drag_to((0.1, 0.2, 0.3))
    sim.step(4)
    return sim


def test_set_state_validates_the_scene_once():
    sim = _stepped()
    state = sim.get_state()
    other = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4}))
    assert _validations(lambda: other.set_state(state)) == 1
    assert full_digest(other) == full_digest(sim)


def test_unpickling_and_from_state_validate_the_scene_once():
    sim = _stepped()
    assert _validations(lambda: pickle.loads(pickle.dumps(sim))) == 1
    state = sim.get_state()
    twin = None

    def restore() -> None:
        nonlocal twin
        twin = rustcloth.Simulation.from_state(state)

    assert _validations(restore) == 1
    assert twin is not None and full_digest(twin) == full_digest(sim)


def test_a_simulation_validates_its_scene_once():
    scene = rustcloth.load_scene("hanging")
    assert _validations(lambda: rustcloth.Simulation(scene)) == 1
    assert _validations(lambda: _core.Simulation(scene.to_dict())) == 1


def test_a_state_is_checked_against_its_own_scene():
    # The arrays are checked against the particles of the state's scene, not the simulation's
    # it replaces: a state of a 4 x 4 cloth with a 5 x 5 cloth's positions is refused by name,
    # and a bad scene is refused before any array is looked at.
    small = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4})).get_state()
    big = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 5, "ny": 5}))
    before = full_digest(big)
    shape = r"state\.positions: must have shape \(16, 3\)"
    with pytest.raises(rustcloth.ParameterError, match=shape):
        big.set_state({**small, "positions": np.zeros((25, 3), np.float32)})
    bad_scene = {**small["scene"], "dt": -1.0}
    with pytest.raises(rustcloth.ParameterError, match="dt") as info:
        big.set_state({**small, "scene": bad_scene, "positions": None})
    assert info.value.parameter == "dt"
    assert full_digest(big) == before
