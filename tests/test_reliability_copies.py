"""Simulations and scenes cross process boundaries: a sweep sends both to its workers.

``pickle``, ``copy.copy`` and ``copy.deepcopy`` give an independent simulation that continues
bit for bit, whatever it holds: any integrator (Verlet's start-up history), cuts, kinematic
pins, a grab being dragged, the watchdog's held substeps, the ``advance`` remainder. A scene
copies and pickles too, and a ``multiprocessing.Pool`` takes it: a worker that died unpickling
one would leave the pool waiting for good."""

from __future__ import annotations

import copy
import multiprocessing
import pickle
import warnings

import numpy as np
import pytest
import rustcloth
from conftest import full_digest, small_scene, state_differences
from rustcloth import Scene, Simulation


def _quiet(scene: Scene) -> Simulation:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rustcloth.StabilityWarning)
        return Simulation(scene)


def rich(integrator: str) -> Simulation:
    """A simulation holding every kind of state: every optional pass, a cut, a kinematic pin, a
    grab being dragged, a time remainder in ``advance``, a non-default pick radius."""
    scene = small_scene(
        integrator=integrator,
        substeps=24 if integrator == "explicit_euler" else 2,
        cloth={"nx": 12, "ny": 10},
        floor={"height": 0.55, "friction": 0.4},
        spheres=[{"center": [0.1, 0.6, -0.2], "radius": 0.15}],
        strain_limit={"max_strain": 0.2},
        watchdog={"max_stretch": 2.0, "on_trouble": "substep", "hold_steps": 40},
    )
    sim = _quiet(scene)
    sim.step(10)
    sim.cut(20)
    p = sim.positions
    sim.pin(5, target=p[5] + [0.0, 0.01, 0.01])
    sim.grab(60)
    sim.drag_to(p[60] + [0.02, 0.0, 0.02])
    sim.pick_radius = 0.03
    sim.pick_strategy = "bvh"
    sim.step(15)
    sim.advance(0.0123)
    state = sim.get_state()
    # The pin, and the grip: the grabbed particle and the patch around it, each with a target.
    assert state["grab"] is not None and len(state["grip"]) > 1
    assert len(state["targets"]) == 1 + len(sim.gripped()) == 2 + len(state["grip"])
    assert 0 < state["accumulator"] < sim.dt
    assert not state["alive"][20]
    return sim


def held(integrator: str) -> Simulation:
    """Springs too stiff for the step, saved by the watchdog's retries, which now hold 4
    substeps for the next 100 steps."""
    sim = _quiet(
        small_scene(
            integrator=integrator,
            cloth={"k_structural": 2e4},
            watchdog={"max_stretch": 1.2, "on_trouble": "substep", "hold_steps": 100},
        )
    )
    sim.step(30)
    assert sim.get_state()["watchdog"]["hold"] is not None
    return sim


CASES = [pytest.param(rich, name, id=f"rich-{name}") for name in rustcloth.INTEGRATORS] + [
    pytest.param(held, name, id=f"held-{name}") for name in ("symplectic_euler", "verlet")
]

COPIES = {
    "pickle": lambda sim: pickle.loads(pickle.dumps(sim)),
    "copy": copy.copy,
    "deepcopy": copy.deepcopy,
    "from_state": lambda sim: Simulation.from_state(sim.get_state()),
    "state_pickle": lambda sim: Simulation.from_state(pickle.loads(pickle.dumps(sim.get_state()))),
}


def _go_on(sim: Simulation) -> None:
    sim.step(7)
    if sim.grabbed() is not None:
        sim.drag_to(sim.positions[60] + [0.0, 0.01, 0.0])
    sim.advance(0.0101)
    sim.cut(33)
    sim.step(5)


@pytest.mark.parametrize("how", list(COPIES))
@pytest.mark.parametrize(("make", "integrator"), CASES)
def test_a_copy_continues_bit_for_bit(make, integrator, how):
    sim = make(integrator)
    clone = COPIES[how](sim)
    assert type(clone) is Simulation
    assert full_digest(clone) == full_digest(sim), state_differences(
        sim.get_state(), clone.get_state()
    )
    _go_on(sim)
    _go_on(clone)
    assert full_digest(clone) == full_digest(sim), state_differences(
        sim.get_state(), clone.get_state()
    )
    assert clone.pick([0.1, 1.0, 2.0], [0, 0, -1]) == sim.pick([0.1, 1.0, 2.0], [0, 0, -1])


def test_a_copy_is_independent():
    sim = rich("verlet")
    clone = copy.deepcopy(sim)
    before = full_digest(clone)
    sim.step(10)
    sim.cut(40)
    sim.set_masses(np.full(sim.num_particles, 0.003))
    sim.dt = 0.0005
    assert full_digest(clone) == before
    clone.step(3)
    assert sim.dt == 0.0005 and clone.dt == 0.001 and clone.alive[40]


def test_scene_copies_are_equal_and_independent():
    scene = rustcloth.load_scene("drape").replace(strain_limit={}, watchdog={"max_stretch": 2.0})
    for clone in (pickle.loads(pickle.dumps(scene)), copy.copy(scene), copy.deepcopy(scene)):
        assert clone == scene and clone.to_dict() == scene.to_dict()
        assert hash(clone) == hash(scene)


def _continue_in_worker(sim: Simulation, scene: Scene) -> tuple[str, str, int]:
    sim.step(25)
    sim.advance(0.0077)
    fresh = Simulation(scene)
    fresh.step(10)
    return full_digest(sim), full_digest(fresh), scene.cloth["nx"]


def test_a_spawn_pool_takes_simulations_and_scenes():
    # The worker unpickles both (a fresh interpreter: nothing shared with this one), steps
    # them, and sends back digests equal to the parent's doing the same.
    sim = rich("rk4")
    scene = rustcloth.load_scene("curtain").replace(cloth={"nx": 20, "ny": 20})
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        remote = pool.apply_async(_continue_in_worker, (sim, scene)).get(timeout=120)
    assert remote == _continue_in_worker(copy.deepcopy(sim), scene)


def test_a_simulation_that_advanced_frame_times_can_be_copied():
    # Found writing these tests: 60 Hz frames at a 2 ms step, the ordinary game loop.
    sim = Simulation(small_scene(dt=0.002))
    for _ in range(3):
        sim.advance(1 / 60)
    assert sim.steps == 25
    clone = copy.deepcopy(sim)
    assert full_digest(clone) == full_digest(sim)
