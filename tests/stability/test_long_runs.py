"""Long runs stay stable: a damped hanging cloth loses energy window after window and comes
to rest."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth


@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet", "rk4", "implicit_euler"])
def test_a_damped_hanging_cloth_settles_over_100k_steps(integrator):
    # Air drag damps the swing itself (spring damping only damps stretching): 2 mN s/m.
    scene = rustcloth.load_scene("hanging").replace(integrator=integrator, substeps=1,
                                                    dt=0.0005, air_drag=0.002,
                                                    cloth={"nx": 16, "ny": 16})
    sim = rustcloth.Simulation(scene)
    windows = []
    for _ in range(100):
        energies = []
        for _ in range(10):
            sim.step(100)
            energies.append(sim.energy().total)
        windows.append(np.mean(energies))
        x = sim.positions
        assert np.isfinite(x).all() and (np.abs(x) < 10).all()
    # Mean total energy over windows of 1,000 steps never grows (beyond float32 noise).
    growth = np.diff(windows)
    scale = abs(windows[0]) + 1e-9
    assert (growth <= 1e-6 * scale).all(), growth.max()
    # At rest at the end: kinetic energy is a vanishing fraction of what the swing had.
    assert sim.energy().kinetic < 1e-6 * scale
