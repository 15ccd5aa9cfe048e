"""The twist scene's driver (rustcloth.drivers): the edges it pins follow the rotation it
prescribes, the demo's stepper runs it before every step, and the twist it makes is a real
self-contact case."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rustcloth
from conftest import at_1ms
from rustcloth.drivers import TwistDriver, driver_for


def _twist(n: int = 12) -> rustcloth.Simulation:
    scene = at_1ms("twist").replace(cloth={"nx": n, "ny": n})
    return rustcloth.Simulation(scene)


def test_the_edges_follow_the_prescribed_turn():
    sim = _twist()
    driver = TwistDriver(sim, turns=1.0, seconds=1.0)
    start = sim.positions.copy()
    for _ in range(250):
        driver.before_step(sim)
        sim.step()
    # A quarter turn: the left edge's offsets from the centre rotated by +90 degrees about x,
    # the right edge's by -90 degrees.
    assert math.isclose(sim.time, 0.25, rel_tol=1e-9)
    center = np.asarray(sim.scene.cloth["center"])
    for side, sign in ((driver.left, 1.0), (driver.right, -1.0)):
        r = start[side] - center
        expected = center + np.stack([r[:, 0], -sign * r[:, 2], sign * r[:, 1]], axis=1)
        np.testing.assert_allclose(sim.positions[side], expected, atol=1e-5)
    # Held after its time: the targets stop at the last angle.
    np.testing.assert_array_equal(
        driver.targets(1.0)[int(driver.left[0])], driver.targets(5.0)[int(driver.left[0])]
    )


def test_only_the_twist_has_a_driver_and_the_demo_runs_it_every_step():
    pytest.importorskip("moderngl")  # the viewer package, whose stepper this is
    from rustcloth.viewer.physics import Stepper

    sim = _twist()
    assert driver_for("hanging", sim) is None
    driver = driver_for("twist", sim)
    assert isinstance(driver, TwistDriver)
    stepper = Stepper(sim, driver)
    stepper.run(0.1, None)
    assert sim.steps == 100
    left = int(driver.left[-1])
    np.testing.assert_allclose(sim.positions[left], driver.targets(sim.time)[left], atol=1e-5)


def test_the_driven_twist_brings_the_cloth_into_contact_with_itself():
    sim = _twist(16)
    driver = TwistDriver(sim)
    for _ in range(2000):
        driver.before_step(sim)
        sim.step()
    stats = sim.self_collision_stats()
    assert stats is not None and stats["contacts"] > 100
    assert np.isfinite(sim.positions).all() and (np.abs(sim.positions) < 3.0).all()
