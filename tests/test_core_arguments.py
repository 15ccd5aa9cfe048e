"""The compiled ``_core`` takes typed arguments; ``rustcloth._args`` reads them first.

The strict readers (bools, bytes and complex numbers refused, the parameter named) moved from
Rust to Python. Two things could break with that move and are checked here: the private core,
called directly with anything, must still raise an ordinary Python exception and change
nothing (never crash or panic); and the two ways a stroke reaches the core (a list of rays,
read in Python, and an ``(M, 2, 3)`` array, read by the core in one pass) must cut the same.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import rustcloth
from rustcloth import _args

JUNK = [None, "x", b"ab", 1.5, -1, 2**70, True, [1, 2], (1.0, 2.0, 3.0, 4.0), np.zeros(3),
        np.zeros((5, 4)), np.zeros((2, 3, 3)), np.zeros((2, 2, 3), ">f8"),
        np.zeros((3, 2), np.int64), np.zeros(4, np.float16), object(), {"a": 1},
        [[0, 0, 0], [0, 0, 1]], np.array([[1]]), np.zeros((16, 3)), np.zeros(16)]

METHODS = ["step", "advance", "set_positions", "set_velocities", "set_masses", "pin",
           "pin_many", "unpin", "cut", "set_state", "pick", "pick_triangle", "cut_ray", "grab",
           "drag_to", "cut_stroke", "sever_stroke", "sever_live_stroke", "set_collider_pose",
           "set_self_collision"]

SETTERS = ["dt", "substeps", "integrator", "pick_radius", "pick_strategy"]


def _digest(sim: rustcloth.Simulation) -> tuple[bytes, ...]:
    core = sim._core
    return (core.positions.tobytes(), core.velocities.tobytes(), core.pinned.tobytes(),
            core.alive.tobytes(), repr((core.dt, core.substeps, core.integrator,
                                        core.pick_radius, core.pick_strategy, core.grabbed(),
                                        core.steps)).encode())


@pytest.mark.parametrize("method", METHODS)
def test_bad_input_to_the_private_core_raises_an_exception_and_changes_nothing(method):
    sim = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4}))
    sim.step(2)
    for value in JUNK:
        for args in ([value], [value, value], [0, value, value]):
            before = _digest(sim)
            try:
                getattr(sim._core, method)(*args)
            except Exception:  # noqa: BLE001 - any ordinary exception is the point
                # pyo3's PanicException derives from BaseException: it would not be caught.
                assert _digest(sim) == before, f"{method}{tuple(args)!r} changed the state"
                continue
            # What the core takes as typed input is valid input: the simulation still steps.
            sim.step(1)
            assert np.isfinite(sim.positions).all()


@pytest.mark.parametrize("setter", SETTERS)
def test_bad_values_for_the_private_core_setters_raise_and_change_nothing(setter):
    for value in JUNK:
        sim = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4}))
        before = _digest(sim)
        try:
            setattr(sim._core, setter, value)
        except Exception:  # noqa: BLE001 - any ordinary exception is the point
            assert _digest(sim) == before, f"{setter} = {value!r} changed the state"


def test_a_stroke_as_a_list_cuts_as_the_same_stroke_as_an_array():
    # A list of rays is read in Python (each direction scaled to unit length in float64) and
    # an (M, 2, 3) array by the core as it is; with unit directions both are the same rays.
    scene = rustcloth.Scene(cloth={"nx": 12, "ny": 12})
    cut = [rustcloth.Simulation(scene) for _ in range(4)]
    # Across the flat cloth through its middle, from one side of it along its normal.
    positions, normal = cut[0].positions.astype(np.float64), cut[0].normals[0]
    low, high = positions.min(axis=0), positions.max(axis=0)
    middle, across = (low + high) / 2, np.argmax(high - low)
    start = np.array(middle, dtype=np.float64)
    start[across] = low[across] - 0.1
    end = start.copy()
    end[across] = high[across] + 0.1
    rays = [(tuple((start + t * (end - start) + normal).tolist()), tuple((-normal).tolist()))
            for t in np.linspace(0.0, 1.0, 9)]
    severed = [cut[0].sever_stroke(rays), cut[1].sever_stroke(np.array(rays))]
    removed = [cut[2].cut_stroke(rays), cut[3].cut_stroke(np.array(rays, np.float32))]
    assert severed[0] == severed[1] > 0
    assert removed[0] == removed[1] and removed[0]
    for a, b in ((cut[0], cut[1]), (cut[2], cut[3])):
        assert a.topology_version == b.topology_version
        assert np.array_equal(a.render_mesh().triangles, b.render_mesh().triangles)


@pytest.mark.parametrize(
    "vector",
    [(0.0, 0.0, 1e-300), (3.0, 4.0, 0.0), (1e-200, -1e-200, 1e-200), (1e30, 2e30, -3e30),
     (0.1, 0.2, 0.3), (-7.0, 0.0, 0.0)],
)
def test_a_direction_is_scaled_to_unit_length_in_float64(vector):
    # Against the exact unit vector: each component within float64 rounding of it.
    length = math.hypot(*vector)
    exact = [c / length for c in vector]
    got = _args.direction(vector, "direction")
    assert all(abs(g - e) <= 4 * math.ulp(1.0) for g, e in zip(got, exact, strict=True))
    assert abs(math.fsum(c * c for c in got) - 1.0) < 1e-15


@pytest.mark.parametrize("vector", [(0.0, 0.0, 0.0), (1e39, 0.0, 0.0), (math.nan, 1.0, 0.0),
                                    (math.inf, 0.0, 1.0)])
def test_a_direction_zero_or_not_finite_in_float32_goes_to_the_core_as_given(vector):
    assert _args.direction(vector, "direction") == vector
    sim = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4}))
    with pytest.raises(rustcloth.ParameterError, match="direction"):
        sim.pick((0.5, 0.5, 2.0), vector)
