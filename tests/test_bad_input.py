"""Bad input: every kind raises a clear exception that names the parameter and the value, and
leaves the simulation exactly as it was. No Rust panic reaches Python."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rustcloth
from conftest import full_digest, small_scene, state_differences
from rustcloth import Scene, Simulation, _core

BAD_SCENES = [
    # (changes, exception, text that must appear in the message)
    ({"dt": 0.0}, ValueError, "dt"),
    ({"dt": -0.001}, ValueError, "dt"),
    ({"dt": math.nan}, ValueError, "dt"),
    ({"dt": math.inf}, ValueError, "dt"),
    ({"dt": "fast"}, TypeError, "dt"),
    ({"substeps": 0}, ValueError, "substeps"),
    ({"substeps": -2}, ValueError, "substeps"),
    ({"substeps": 1.5}, TypeError, "substeps"),
    ({"gravity": [0, math.nan, 0]}, ValueError, "gravity[1]"),
    ({"gravity": [0, -9.81]}, ValueError, "gravity"),
    ({"air_drag": -1.0}, ValueError, "air_drag"),
    ({"integrator": "leapfrog"}, ValueError, "symplectic_euler"),
    ({"breeze": 3.0}, ValueError, "breeze"),
    ({"cloth": {"nx": 1}}, ValueError, "cloth.nx"),
    ({"cloth": {"ny": 0}}, ValueError, "cloth.ny"),
    ({"cloth": {"nx": -4}}, ValueError, "cloth.nx"),
    ({"cloth": {"nx": 100_000, "ny": 100_000}}, ValueError, "cloth.nx"),
    ({"cloth": {"size": [1.0, 0.0]}}, ValueError, "cloth.size[1]"),
    ({"cloth": {"particle_mass": 0.0}}, ValueError, "cloth.particle_mass"),
    ({"cloth": {"particle_mass": 0.1, "mass": 1.0}}, ValueError, "not both"),
    ({"cloth": {"mass": -1.0}}, ValueError, "cloth.mass"),
    ({"cloth": {"k_structural": -5.0}}, ValueError, "cloth.k_structural"),
    ({"cloth": {"k_shear": math.inf}}, ValueError, "cloth.k_shear"),
    ({"cloth": {"k_bend": math.nan}}, ValueError, "cloth.k_bend"),
    ({"cloth": {"damping": -0.1}}, ValueError, "cloth.damping"),
    ({"cloth": {"plane": "yz"}}, ValueError, "cloth.plane"),
    ({"cloth": {"pins": ["everywhere"]}}, ValueError, "cloth.pins[0]"),
    ({"cloth": {"pins": [[99, 0]]}}, ValueError, "cloth.pins[0]"),
    ({"cloth": {"colour": "red"}}, ValueError, "colour"),
    ({"cloth": {"center": [0, 1e39, 0]}}, ValueError, "cloth.center[1]"),
    ({"floor": {"friction": -0.3}}, ValueError, "floor.friction"),
    ({"floor": {"height": math.nan}}, ValueError, "floor.height"),
    ({"spheres": [{"radius": 0.0}]}, ValueError, "spheres[0].radius"),
    ({"spheres": [{"radius": 0.2}, {"radius": -1.0}]}, ValueError, "spheres[1].radius"),
    ({"spheres": [{"center": [0, 0]}]}, ValueError, "spheres[0].center"),
    ({"spheres": [{"radius": 0.2, "mass": 3}]}, ValueError, "mass"),
]


@pytest.mark.parametrize(("changes", "exception", "text"), BAD_SCENES)
def test_bad_scenes_raise_naming_the_parameter(changes, exception, text):
    with pytest.raises(exception) as info:
        small_scene(**changes)
    assert isinstance(info.value, rustcloth.RustclothError)
    assert text in str(info.value)


@pytest.mark.parametrize(("changes", "exception", "text"), BAD_SCENES)
def test_a_simulation_refuses_a_bad_scene_dict_as_the_scene_does(changes, exception, text):
    # Simulation(scene) hands the scene's dict to the core's Simulation, which validates it once,
    # as it builds the simulation, not also as it reads the dict (a second with a big mesh
    # collider). Handed a bad dict, the core's refusal is the Scene's, word for word.
    data = small_scene().to_dict()
    for key, value in changes.items():
        data[key] = {**data[key], **value} if key == "cloth" else value
    with pytest.raises(exception) as from_scene:
        Scene.from_dict(data)
    with pytest.raises(exception) as from_simulation:
        _core.Simulation(data)
    assert str(from_simulation.value) == str(from_scene.value)
    assert text in str(from_simulation.value)


def test_bad_toml_is_a_value_error():
    with pytest.raises(ValueError, match="TOML"):
        Scene.from_toml_str("dt = = 3")


@pytest.fixture
def stepped():
    # With state in every part a bad call could touch: a remainder in advance, a kinematic
    # pin, a grab, a non-default pick radius, the watchdog's memory.
    sim = Simulation(small_scene(watchdog={"max_stretch": 3.0}))
    sim.step(20)
    sim.advance(0.0004)
    sim.pin(10, target=[0.0, 1.0, -0.2])
    sim.grab(20)
    sim.pick_radius = 0.04
    return sim


def unchanged_after(sim, action, exception, text):
    # The whole get_state() (dt, substeps, integrator, masses, pins, targets, the advance
    # remainder, the clock, the watchdog's memory, the cache versions...), not only positions
    # and velocities: a bad call may change any of them.
    state, before = sim.get_state(), (full_digest(sim), sim.effects)
    with pytest.raises(exception) as info:
        action(sim)
    assert isinstance(info.value, rustcloth.RustclothError), repr(info.value)
    assert text in str(info.value), str(info.value)
    assert (full_digest(sim), sim.effects) == before, state_differences(state, sim.get_state())


BAD_CALLS = [
    (lambda s: s.set_positions(np.zeros((5, 3), np.float32)), ValueError, "positions"),
    (lambda s: s.set_positions(np.zeros((48, 2), np.float32)), ValueError, "(48, 3)"),
    (lambda s: s.set_positions(np.zeros((48, 3), np.int64)), TypeError, "float32 or float64"),
    (lambda s: s.set_positions([[0.0, 0.0, 0.0]] * 48), TypeError, "numpy array"),
    (lambda s: s.set_positions(np.full((48, 3), np.nan, np.float32)), ValueError, "not finite"),
    (lambda s: s.set_velocities(np.full((48, 3), np.inf)), ValueError, "velocities"),
    (lambda s: s.pin(48), IndexError, "index 48"),
    (lambda s: s.pin(-1), IndexError, "index -1"),
    (lambda s: s.pin(2**70), IndexError, "index"),
    (lambda s: s.pin(1.5), TypeError, "index"),
    (lambda s: s.pin(True), TypeError, "index"),
    (lambda s: s.pin(3, target=[0.0, math.nan, 0.0]), ValueError, "target"),
    (lambda s: s.pin(3, target=[0.0, 1.0]), ValueError, "target"),
    # pin_many checks every index and target before it pins any (the first ones are good).
    (lambda s: s.pin_many([1, 2, 48]), IndexError, "indices[2]: index 48"),
    (lambda s: s.pin_many([1, -1]), IndexError, "indices[1]: index -1"),
    (lambda s: s.pin_many(np.array([1, 2**63], np.uint64)), IndexError, "indices"),
    (lambda s: s.pin_many([1.0, 2.0]), TypeError, "indices"),
    (lambda s: s.pin_many([True]), TypeError, "indices"),
    (lambda s: s.pin_many([[1, 2]]), ValueError, "indices"),
    (lambda s: s.pin_many([1, 2], np.zeros((3, 3))), ValueError, "targets"),
    (lambda s: s.pin_many([1, 2], [[0, 0, 0], [0, math.inf, 0]]), ValueError, "targets[1]"),
    (lambda s: s.pin(3, target="up"), TypeError, "target"),
    (lambda s: s.unpin(10_000), IndexError, "index"),
    (lambda s: s.cut(-5), IndexError, "index"),
    (lambda s: s.step(-1), ValueError, "n"),
    (lambda s: s.step(2.5), TypeError, ""),
    (lambda s: s.advance(-0.1), ValueError, "seconds"),
    (lambda s: s.advance(math.nan), ValueError, "seconds"),
    (lambda s: setattr(s, "integrator", "rk5"), ValueError, "symplectic_euler"),
    (lambda s: setattr(s, "substeps", 0), ValueError, "substeps"),
    (lambda s: setattr(s, "dt", -1.0), ValueError, "dt"),
    (lambda s: setattr(s, "dt", math.inf), ValueError, "dt"),
    # Calls that would change state beyond positions and velocities: dt, substeps, the
    # integrator, masses, the advance remainder, pins, the grab, the pick settings.
    (lambda s: setattr(s, "dt", 1e-12), ValueError, "dt"),
    (lambda s: setattr(s, "dt", 5e-324), ValueError, "dt"),
    (lambda s: setattr(s, "substeps", 2**40), ValueError, "substeps"),
    (lambda s: setattr(s, "substeps", 10**7), ValueError, "substeps"),
    (lambda s: setattr(s, "integrator", 5), TypeError, "integrator"),
    (lambda s: s.set_masses(np.zeros(48)), ValueError, "masses"),
    (lambda s: s.set_masses(np.full(48, 1e-50)), ValueError, "masses"),
    (lambda s: s.set_masses(np.full(47, 0.002)), ValueError, "masses"),
    (lambda s: s.advance(1e300), ValueError, "seconds"),
    (lambda s: s.advance("0.1"), TypeError, "seconds"),
    (lambda s: s.step(2**63), ValueError, "n"),
    (lambda s: s.pin(3, target=b"abc"), TypeError, "target"),
    (lambda s: s.drag_to([math.nan, 0.0, 0.0]), ValueError, "target"),
    (lambda s: s.grab(48), IndexError, "index"),
    (lambda s: s.cut_stroke([([0.1, 1.0, 2.0], [0, 0, -1]), ([0, 0, 0], [0, 0, 0])]),
     ValueError, "rays[1].direction"),
    (lambda s: setattr(s, "pick_radius", math.nan), ValueError, "pick_radius"),
    (lambda s: setattr(s, "pick_strategy", "fast"), ValueError, "pick_strategy"),
    (lambda s: s.set_state({}), ValueError, "state"),
    (lambda s: s.set_state({**s.get_state(), "accumulator": -1.0}), ValueError, "accumulator"),
]


@pytest.mark.parametrize(("action", "exception", "text"), BAD_CALLS)
def test_bad_calls_raise_and_leave_the_simulation_unchanged(stepped, action, exception, text):
    unchanged_after(stepped, action, exception, text)


def test_pinning_a_cut_particle_is_refused(stepped):
    stepped.cut(5)
    unchanged_after(stepped, lambda s: s.pin(5), ValueError, "cut")
    unchanged_after(stepped, lambda s: s.pin_many([4, 5]), ValueError, "indices[1]")


def test_the_wrong_type_of_scene_is_a_type_error():
    with pytest.raises(TypeError, match="scene"):
        Simulation(42)
    with pytest.raises(TypeError, match="must be strings"):
        Simulation({1: 2})
