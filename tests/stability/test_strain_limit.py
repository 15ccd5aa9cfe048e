"""Provot strain limiting in the step (``strain_limit`` in a scene): a soft cloth keeps a stiff
cloth's shape, a cloth within the limit is untouched bit for bit, and the pass is only in the
pipeline when asked for."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth
from conftest import state_digest
from stability.checks import run_checked


def soft_hanging(**changes) -> rustcloth.Scene:
    """The built-in hanging cloth at a tenth of its stiffness: it sags far beyond 10 %."""
    scene = rustcloth.load_scene("hanging").replace(
        cloth={"nx": 24, "ny": 24, "k_structural": 80.0, "k_shear": 20.0, "k_bend": 2.0},
        air_drag=0.002,
    )
    return scene.replace(**changes)


def structural_and_shear_strain(sim: rustcloth.Simulation) -> float:
    """Worst strain over structural and shear springs (bending springs are not limited)."""
    x, nx, ny = sim.positions.astype(np.float64), sim.nx, sim.ny
    grid = x.reshape(ny, nx, 3)
    rest = sim.scene.cloth["size"][0] / (nx - 1)
    pairs = [(grid[:, 1:], grid[:, :-1], rest), (grid[1:], grid[:-1], rest),
             (grid[1:, 1:], grid[:-1, :-1], rest * np.sqrt(2)),
             (grid[1:, :-1], grid[:-1, 1:], rest * np.sqrt(2))]
    return max((np.linalg.norm(a - b, axis=-1) / length - 1).max() for a, b, length in pairs)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_a_soft_cloth_is_held_near_the_limit(integrator):
    free = rustcloth.Simulation(soft_hanging(integrator=integrator))
    held = rustcloth.Simulation(soft_hanging(integrator=integrator,
                                             strain_limit={"max_strain": 0.1, "iterations": 8}))
    assert "strain_limit" in held.effects and "strain_limit" not in free.effects
    free.step(1500)
    assert run_checked(held, 1500) is None
    assert structural_and_shear_strain(free) > 0.5
    # Jacobi sweeps carry a correction one particle per sweep: near, not at, the limit.
    assert structural_and_shear_strain(held) < 0.15
    assert held.profile().passes["strain_limit"].calls == 1500 * held.substeps


def test_a_cloth_within_the_limit_is_untouched_bit_for_bit():
    stiff = rustcloth.load_scene("hanging").replace(cloth={"nx": 16, "ny": 16})
    plain = rustcloth.Simulation(stiff)
    limited = rustcloth.Simulation(stiff.replace(strain_limit={"max_strain": 0.5}))
    plain.step(300)
    limited.step(300)
    assert limited.max_stretch() < 0.5
    assert state_digest(plain) == state_digest(limited)


def test_the_limit_follows_a_dragged_particle():
    # Pins run before the limit: the cloth is pulled after the dragged corner, which stays
    # exactly on its target.
    sim = rustcloth.Simulation(soft_hanging(strain_limit={"max_strain": 0.1}))
    corner = sim.nx * sim.ny - 1
    target = sim.positions[corner] + [0.3, 0.2, 0.0]
    sim.pin(corner, target)
    sim.step(200)
    np.testing.assert_array_equal(sim.positions[corner], target.astype(np.float32))


def test_strain_limit_settings_are_validated():
    with pytest.raises(rustcloth.ParameterError, match="strain_limit.max_strain"):
        rustcloth.Scene(strain_limit={"max_strain": -0.1})
    with pytest.raises(rustcloth.ParameterError, match="strain_limit.iterations"):
        rustcloth.Scene(strain_limit={"iterations": 0})
    with pytest.raises(rustcloth.ParameterError, match="dt / substeps"):
        rustcloth.Scene(dt=1e-12)
    sim = rustcloth.Simulation(rustcloth.Scene())
    with pytest.raises(rustcloth.ParameterError, match="substeps"):
        sim.substeps = 10**9
    assert sim.substeps == 1
