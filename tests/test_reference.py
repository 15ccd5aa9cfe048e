"""The numpy reference model (rustcloth.reference) checked on its own, before anything is
tested against it: its spring forces are central and vanish at rest, pins hold, and its float32
stepping (the benchmark's numpy peer) follows its float64 stepping."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth
from rustcloth.reference import ReferenceCloth, pin_indices


def scene(**cloth):
    return rustcloth.Scene(
        dt=1e-3, substeps=2, gravity=[0.0, 0.0, 0.0], air_drag=0.0,
        cloth={"nx": 7, "ny": 5, "size": [0.6, 0.4], "plane": "xz", "particle_mass": 0.002,
               "k_structural": 30.0, "k_shear": 20.0, "k_bend": 10.0, "damping": 0.05,
               "pins": [], **cloth},
    ).to_dict()


def test_spring_forces_conserve_momentum_and_angular_momentum():
    cloth = ReferenceCloth(scene())
    rng = np.random.default_rng(1)
    cloth.set_positions(cloth.positions + rng.normal(scale=0.02, size=(35, 3)))
    cloth.set_velocities(rng.normal(scale=0.5, size=(35, 3)))
    x, v = cloth.positions, cloth.velocities
    f = cloth.force_rows(x, v)
    scale = np.abs(f).max()
    assert scale > 0.1
    assert np.abs(f.sum(axis=0)).max() < 1e-12 * scale * len(f)
    assert np.abs(np.cross(x, f).sum(axis=0)).max() < 1e-12 * scale * len(f)


@pytest.mark.parametrize("plane", ["xz", "xy"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_cloth_at_rest_feels_no_spring_force(plane, dtype):
    cloth = ReferenceCloth(scene(nx=2, ny=2, plane=plane, center=[1.0, 2.0, 3.0]), dtype=dtype)
    assert sum(s.rest.size for s in cloth.springs) == 6  # 4 structural, 2 shear, no bend at 2x2
    f = cloth.force_rows(cloth.positions, cloth.velocities)
    assert f.dtype == dtype and np.all(f == 0.0)


def test_pins_hold_and_the_rest_falls():
    hanging = scene(pins=["top_corners", [3, 0]])
    cloth = ReferenceCloth({**hanging, "gravity": [0.0, -9.81, 0.0]})
    before = cloth.positions
    cloth.step(50)
    pinned = pin_indices(["top_corners", [3, 0]], 7, 5)
    assert pinned == [3, 28, 34]
    np.testing.assert_array_equal(cloth.positions[pinned], before[pinned])
    assert cloth.positions[:, 1].min() < before[:, 1].min() - 1e-3


def test_float32_steps_follow_float64_steps():
    hanging = {**scene(pins=["top_corners"]), "gravity": [0.0, -9.81, 0.0], "air_drag": 1e-3}
    fast, exact = ReferenceCloth(hanging, dtype=np.float32), ReferenceCloth(hanging)
    fast.step(30)
    exact.step(30)
    assert fast.positions.dtype == np.float32
    assert np.abs(fast.positions - exact.positions).max() < 1e-5


def test_effects_it_does_not_model_are_refused():
    with pytest.raises(ValueError, match="sets floor"):
        ReferenceCloth({**scene(), "floor": {"height": 0.0}})
