"""``Simulation.self_collision`` read and set at run time (the demo's C key): the settings
dict or None, True for the defaults, False or None for off; the state carries over bit for bit
and bad settings change nothing. The stepping itself is checked in tests/self_collision_toggle.rs
against simulations built with and without ``[self_collision]``."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import rustcloth
from conftest import at_1ms
from rustcloth import Simulation
from rustcloth.errors import ParameterError


def test_off_and_on_again_continues_bit_for_bit_and_survives_pickling():
    sim, untouched = Simulation(at_1ms("pile")), Simulation(at_1ms("pile"))
    for s in (sim, untouched):
        s.advance(0.3)
    own = sim.self_collision
    assert own == {"thickness": 0.003, "friction": 0.3, "iterations": 4, "solve_stiffness": 0.0}
    sim.self_collision = None
    assert sim.self_collision is None and "self_collision" not in sim.effects
    assert sim.scene.self_collision is None
    copy = pickle.loads(pickle.dumps(sim))
    assert copy.self_collision is None
    sim.self_collision = own
    for s in (sim, untouched):
        s.advance(0.3)
    assert np.array_equal(sim.positions, untouched.positions)
    assert sim.self_collision_stats() is not None


def test_true_takes_the_defaults_and_false_turns_it_off():
    sim = Simulation("hanging")
    assert sim.self_collision is None
    sim.self_collision = True
    defaults = rustcloth.Scene(self_collision={}).self_collision
    assert sim.self_collision == defaults and "self_collision" in sim.effects
    sim.self_collision = {"friction": 0.0}
    assert sim.self_collision == {**defaults, "friction": 0.0}
    sim.self_collision = False
    assert sim.self_collision is None and sim.self_collision_stats() is None


@pytest.mark.parametrize(
    ("bad", "error", "name"),
    [
        ({"thickness": 0.5}, ParameterError, "self_collision.thickness"),
        ({"thickness": float("nan")}, ParameterError, "self_collision.thickness"),
        ({"iterations": 0}, ParameterError, "self_collision.iterations"),
        ({"stiffness": 1.0}, ParameterError, "self_collision.stiffness"),
        ({"friction": "high"}, TypeError, "self_collision.friction"),
        (1, TypeError, "self_collision"),
        ("on", TypeError, "self_collision"),
    ],
)
def test_bad_settings_are_refused_by_name_changing_nothing(bad, error, name):
    sim = Simulation(at_1ms("pile"))
    sim.advance(0.1)
    before = (sim.positions.copy(), sim.velocities.copy(), sim.self_collision, sim.steps)
    with pytest.raises(error, match=name):
        sim.self_collision = bad
    assert np.array_equal(sim.positions, before[0]) and np.array_equal(sim.velocities, before[1])
    assert (sim.self_collision, sim.steps) == before[2:]
