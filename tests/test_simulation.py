"""The Python API of Simulation: arrays, stepping, pins, caches, profile."""

from __future__ import annotations

import functools
import sys
import threading
import time

import numpy as np
import pytest
import rustcloth
from conftest import small_scene, state_digest
from rustcloth import Simulation


def test_arrays_have_the_documented_shapes_and_dtypes(sim):
    n = sim.nx * sim.ny
    assert sim.num_particles == n
    for array in (sim.positions, sim.velocities, sim.normals):
        assert array.shape == (n, 3) and array.dtype == np.float32
    tris = sim.triangles
    assert tris.dtype == np.uint32 and tris.shape == (2 * (sim.nx - 1) * (sim.ny - 1), 3)
    assert sim.pinned.dtype == bool and sim.pinned.sum() == 2
    assert sim.alive.all()
    np.testing.assert_allclose(np.linalg.norm(sim.normals, axis=1), 1.0, rtol=1e-6)


def test_particle_index_is_j_times_nx_plus_i(sim):
    pos = sim.positions
    nx = sim.nx
    # Along i: +x; along j: +y (plane "xy").
    assert pos[1, 0] > pos[0, 0] and pos[nx, 1] > pos[0, 1]
    assert sim.pinned[(sim.ny - 1) * nx] and sim.pinned[sim.ny * nx - 1]


def test_state_arrays_are_read_only_copies(sim):
    # Writing into a writable copy would look like moving the cloth and do nothing: reads are
    # read-only copies, so the write raises; a copy of the copy may be changed and given back
    # through set_positions.
    for array in (sim.positions, sim.velocities, sim.normals, sim.masses, sim.pinned,
                  sim.alive, sim.triangles, sim.spring_strain()):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0
    a = sim.positions.copy()
    a[:] = 42.0
    assert not np.any(sim.positions == 42.0)
    sim.set_positions(a)
    assert np.all(sim.positions == 42.0)


def test_step_advance_time_and_steps(sim):
    sim.step()
    sim.step(9)
    assert sim.steps == 10 and sim.time == pytest.approx(0.010)
    assert sim.advance(0.0155) == 15
    assert sim.advance(0.0005) == 1  # the carried 0.5 ms completes a step
    assert sim.steps == 26


def test_set_positions_and_velocities_round_trip(sim):
    pos = sim.positions + np.float32(0.01)
    sim.set_positions(pos)
    np.testing.assert_array_equal(sim.positions, pos)
    vel = np.ones_like(pos)
    sim.set_velocities(vel.astype(np.float64))
    v = sim.velocities
    assert np.all(v[~sim.pinned] == 1.0) and np.all(v[sim.pinned] == 0.0)


def test_pins_move_and_release(sim):
    p = 3
    sim.pin(p)
    before = sim.positions[p].copy()
    sim.step(50)
    np.testing.assert_array_equal(sim.positions[p], before)
    sim.pin(p, target=[0.0, 2.0, 0.0])
    assert "kinematic_pins" in sim.effects
    sim.step(2)
    np.testing.assert_array_equal(sim.positions[p], np.float32([0.0, 2.0, 0.0]))
    sim.unpin(p)
    sim.step(50)
    assert sim.positions[p, 1] < 2.0  # it falls once released
    assert "kinematic_pins" not in sim.effects


def test_pin_many_pins_as_pin_does_one_at_a_time(sim):
    indices = np.array([3, 7, 11])
    targets = sim.positions[indices] + np.float32([0.0, 0.1, 0.0])
    one_by_one = Simulation(sim.scene)
    for i, t in zip(indices, targets, strict=True):
        one_by_one.pin(int(i), tuple(float(c) for c in t))
    sim.pin_many(indices, targets)
    one_by_one.step(20)
    sim.step(20)
    np.testing.assert_array_equal(sim.positions, one_by_one.positions)
    np.testing.assert_array_equal(sim.positions[indices], targets)
    # Static pins (no targets), from a list; an empty call does nothing.
    sim.pin_many([0, 1])
    sim.pin_many([])
    assert sim.pinned[[0, 1, 3, 7, 11]].all()


def test_energy_is_reported_in_joules(sim):
    e = sim.energy()
    assert e.kinetic == 0.0 and e.elastic == pytest.approx(0.0, abs=1e-9)
    m = sim.masses.astype(float)
    expected = float(np.sum(m * 9.81 * sim.positions[:, 1].astype(float)))
    assert e.gravitational == pytest.approx(expected, rel=1e-6)
    sim.step(100)
    assert sim.energy().kinetic > 0 and sim.energy().total == pytest.approx(sum(sim.energy()))


def test_effects_and_profile():
    sim = Simulation(small_scene(air_drag=0.0, cloth={"k_bend": 0.0}))
    assert sim.effects == ["gravity", "structural_springs", "shear_springs", "symplectic_euler"]
    sim.step(20)
    profile = sim.profile()
    assert profile.steps == 20 and list(profile.passes) == sim.effects
    assert all(p.seconds >= 0 for p in profile.passes.values())
    assert sum(p.seconds for p in profile.passes.values()) <= profile.total_seconds * 1.05
    assert "ms/step" in str(profile)


def test_normals_and_triangles_are_cached_until_the_state_changes(sim):
    n1 = sim.normals
    assert np.array_equal(n1, sim.normals)
    sim.step(30)
    assert not np.array_equal(n1, sim.normals)
    version = sim.topology_version
    tris = sim.triangles
    sim.cut(0)
    assert sim.topology_version == version + 1
    assert len(sim.triangles) == len(tris) - 2  # both triangles of the corner cell


def test_runtime_settings_and_reset(sim):
    sim.integrator = "explicit_euler"
    sim.substeps = 3
    sim.dt = 0.0005
    sim.step(10)
    assert sim.scene.integrator == "explicit_euler" and sim.scene.substeps == 3
    version = sim.topology_version
    sim.reset()
    assert sim.steps == 0 and sim.integrator == "explicit_euler"
    # Versions only ever grow, reset included: a version set back could match a cache stamped
    # with an earlier one again.
    assert sim.topology_version > version
    np.testing.assert_array_equal(sim.positions, Simulation(small_scene()).positions)


def test_simulation_accepts_a_scene_a_dict_or_a_name():
    assert Simulation("hanging").nx == rustcloth.load_scene("hanging").cloth["nx"]
    assert Simulation(small_scene().to_dict()).nx == 8
    assert Simulation().nx == 32


def _increments_inside(call) -> tuple[int, float]:
    """Runs `call` while another thread timestamps a counter as fast as it can; returns how
    many increments fell in the middle 60 % of the call's interval, and the call's length.
    The margins keep out what the counter may do while this thread is between taking a
    timestamp and entering or leaving the call (a thread switch, at most a switch interval)."""
    stamps: list[float] = []
    done, started = threading.Event(), threading.Event()

    def count() -> None:
        started.set()
        while not done.is_set():
            stamps.append(time.perf_counter())

    t = threading.Thread(target=count)
    t.start()
    started.wait()
    t0 = time.perf_counter()
    call()
    t1 = time.perf_counter()
    done.set()
    t.join()
    span = t1 - t0
    lo, hi = t0 + 0.2 * span, t1 - 0.2 * span
    return sum(lo < s < hi for s in stamps), span


def test_stepping_releases_the_gil():
    # The increments must fall *during* the step, in its middle: counted from before the step
    # started, they would let a step that holds the GIL pass. A Python thread runs while
    # another thread steps.
    sim = Simulation(small_scene(cloth={"nx": 128, "ny": 128}))
    # The step must last long enough for the margins to mean anything, however fast the machine:
    # twice the steps until it does.
    steps = 400
    inside, span = _increments_inside(functools.partial(sim.step, steps))
    while span <= 20 * sys.getswitchinterval() and steps < 400 * 2**6:
        steps *= 2
        inside, span = _increments_inside(functools.partial(sim.step, steps))
    assert span > 20 * sys.getswitchinterval()
    assert inside >= 1000, (inside, span, steps)


def test_the_gil_test_fails_for_a_call_that_holds_the_gil():
    # The measurement itself can fail: a long C call that never releases the GIL (the sum of a
    # range, in the interpreter's C loop) lets no increment into its middle.
    inside, span = _increments_inside(lambda: sum(range(20_000_000)))
    assert span > 20 * sys.getswitchinterval()
    assert inside == 0, (inside, span)


def test_memory_per_particle_at_256_squared():
    sim = Simulation(small_scene(cloth={"nx": 256, "ny": 256}))
    per_particle = sim.memory_bytes() / sim.num_particles
    assert per_particle <= 200, per_particle


def test_same_scene_same_trajectory():
    a, b = Simulation(small_scene()), Simulation(small_scene())
    a.step(300)
    b.step(100)
    b.step(200)
    assert state_digest(a) == state_digest(b)
