"""No Rust panic reaches Python, on any grid shape at any thread count.

A panic reaches Python as pyo3's ``PanicException``, a ``BaseException`` that ``except
Exception`` misses, and the chunking of the force pass depends on the thread count, so a shape
that steps on 2 cores can fail on 16. These tests step very wide and very tall grids on both
sides of the 2,048-particle chunk and a seeded sample at 1, 2, 7 and 16 threads (in
subprocesses: rayon's pool is global), and drive both panic guards, which turn any panic into
``InternalError`` with the state put back, through the test hooks ``_inject_panic`` (the next
force evaluation panics on a rayon worker) and ``_panic_now`` (a panic under the binding's
lock)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rustcloth
from conftest import full_digest, small_scene, state_differences, worker_run
from reliability_worker import SHAPES, every_pass_scene, shape_scene
from rustcloth import RustclothError, Simulation
from rustcloth.errors import InternalError

THREAD_COUNTS = (1, 2, 7, 16)


@pytest.mark.parametrize(("nx", "ny"), [(1025, 2), (2049, 2), (2, 2049), (4097, 2)])
def test_wide_cloths_step_and_stay_bounded(nx, ny):
    # Rows longer than a chunk of the force pass (1025 x 2, nx >= 2049) step, finite and
    # bounded.
    sim = Simulation(shape_scene(nx, ny))
    sim.step(20)
    x = sim.positions
    assert np.isfinite(x).all() and (np.abs(x) < 10).all()
    assert sim.steps == 20


# The worker's runs are cached per process: in one group, pytest-xdist runs them once.
@pytest.mark.xdist_group("reliability_worker")
def test_grid_shapes_step_alike_at_every_thread_count():
    # Every shape of the worker's list (wide and tall grids on both sides of the
    # 2,048-particle chunk, 1500 x 64, and a seeded sample)
    # steps at 1, 2, 7 and 16 threads to the bitwise same state: nothing depends on how the
    # pool splits the work.
    runs = {t: worker_run(t) for t in THREAD_COUNTS}
    assert "1500x64" in runs[16]["shapes"] and len(runs[16]["shapes"]) == len(SHAPES)
    for shape, digest in runs[1]["shapes"].items():
        assert {t: runs[t]["shapes"][shape] for t in THREAD_COUNTS} == dict.fromkeys(
            THREAD_COUNTS, digest
        ), shape
    for name, digest in runs[1]["integrators"].items():
        assert all(runs[t]["integrators"][name] == digest for t in THREAD_COUNTS), name


@pytest.mark.xdist_group("reliability_worker")
def test_in_process_pool_agrees_with_the_subprocesses():
    # The worker's results are not an artefact of the subprocess: this process's pool (of
    # whatever size) gets the same bits for the reported shape.
    sim = Simulation(shape_scene(1500, 64))
    sim.step(3)
    assert full_digest(sim) == worker_run(16)["shapes"]["1500x64"]


STIFF = {"k_structural": 2e4}  # 100 times too stiff for symplectic Euler at 1 ms

def _scenes(marks_for: dict[str, pytest.MarkDecorator]) -> list[object]:
    cases = [
        ("one_substep", small_scene(), 7),
        ("three_substeps", small_scene(substeps=3), 7),
        ("every_pass_verlet", every_pass_scene("verlet", 24, 24), 7),
        ("every_pass_rk4", every_pass_scene("rk4", 24, 24), 7),
        # Retries happen every few steps; step 8 is not held.
        (
            "watchdog_retries",
            small_scene(
                cloth=STIFF, watchdog={"max_stretch": 1.2, "on_trouble": "substep", "hold_steps": 3}
            ),
            7,
        ),
        # One retry early on, then 100 held steps: the panicking step is a held one.
        (
            "watchdog_hold",
            small_scene(
                cloth=STIFF,
                watchdog={"max_stretch": 1.2, "on_trouble": "substep", "hold_steps": 100},
            ),
            30,
        ),
    ]
    return [
        pytest.param(scene, before, id=label, marks=marks_for.get(label, ()))
        for label, scene, before in cases
    ]


def _make(scene: rustcloth.Scene) -> Simulation:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rustcloth.StabilityWarning)
        return Simulation(scene)


def _panicking_step(sim: Simulation) -> None:
    sim._core._inject_panic()
    with pytest.raises(Exception) as info:  # noqa: PT011 - that `except Exception` catches it
        sim.step(5)
    err = info.value
    assert type(err) is InternalError
    assert isinstance(err, RustclothError) and isinstance(err, RuntimeError)
    assert "bug in rustcloth" in str(err)


@pytest.mark.parametrize(
    ("scene", "before"),
    _scenes(
        {}
    ),
)
def test_a_panic_in_a_step_leaves_the_state_exactly_as_it_was(scene, before):
    # A panic on a rayon worker inside the force pass: caught, the step rolled back, reported
    # as InternalError, an ordinary Exception; get_state() is bit for bit what it was (the two
    # cache-version counters aside: they count up so that caches rebuild).
    sim = _make(scene)
    sim.step(before)
    state = sim.get_state()
    digest = full_digest(sim, versions=False)
    _panicking_step(sim)
    assert sim.steps == before
    np.testing.assert_array_equal(sim.positions, state["positions"])
    np.testing.assert_array_equal(sim.velocities, state["velocities"])
    assert full_digest(sim, versions=False) == digest, state_differences(state, sim.get_state())


@pytest.mark.parametrize(
    ("scene", "before"), _scenes({})
)
def test_after_a_panic_it_steps_like_a_twin_that_never_panicked(scene, before):
    # With one substep, several, every optional pass and the watchdog's substep retries: after
    # the InternalError the simulation goes on bit for bit as a twin that never panicked.
    sim, twin = _make(scene), _make(scene)
    sim.step(before)
    twin.step(before)
    _panicking_step(sim)
    for _ in range(3):
        sim.step(10)
        twin.step(10)
        assert full_digest(sim, versions=False) == full_digest(twin, versions=False), (
            state_differences(twin.get_state(), sim.get_state())
        )
    if scene.cloth["k_structural"] == STIFF["k_structural"]:
        assert twin.watchdog_stats()["retried"] >= 1  # the retry path did run


def test_a_panic_during_advance_keeps_the_time_owed():
    sim, twin = Simulation(small_scene()), Simulation(small_scene())
    sim.advance(0.0105)
    twin.advance(0.0105)
    sim._core._inject_panic()
    with pytest.raises(InternalError):
        sim.advance(0.004)
    sim.advance(0.0)  # the 4 ms not simulated stay owed, like after a failed step
    twin.advance(0.004)
    assert full_digest(sim, versions=False) == full_digest(twin, versions=False)


def test_the_last_resort_guard_under_the_lock():
    # A panic anywhere under the binding's lock (not in a step) is InternalError too, and the
    # simulation stays usable and keeps its state.
    sim, twin = Simulation(small_scene()), Simulation(small_scene())
    sim.step(5)
    twin.step(5)
    before = full_digest(sim, versions=False)
    with pytest.raises(InternalError, match="bug in rustcloth"):
        sim._core._panic_now()
    assert full_digest(sim, versions=False) == before
    assert sim.pick([0.1, 1.0, 2.0], [0, 0, -1]) == twin.pick([0.1, 1.0, 2.0], [0, 0, -1])
    np.testing.assert_array_equal(sim.normals, twin.normals)
    sim.step(10)
    twin.step(10)
    assert full_digest(sim, versions=False) == full_digest(twin, versions=False)
