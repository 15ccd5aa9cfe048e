"""Hidden state: what a caller cannot see must not change what happens next.

A cut particle is absent from every computation: one sent to 1e30 m leaves the live cloth
bitwise as in a twin whose dead particle stayed put, for every integrator with every optional
pass. Evaluating and masking its springs instead would let a far-away dead particle make the
live cloth diverge, or change it silently under implicit Euler.

A refused step leaves no trace: the simulation continues bitwise like a twin that never tried
the step, for every integrator (Verlet's start-up flag included), so two simulations that look
identical stay identical after the same calls."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rustcloth
from conftest import state_differences
from hypothesis import given, settings
from hypothesis import strategies as st
from rustcloth import Scene, Simulation, SimulationDiverged

CUT = (200, 201, 26, 0)  # inside the cloth, next to the first, on an edge, a corner


def every_pass(integrator: str, **watchdog) -> Scene:
    """A 24 x 24 cloth over a sphere on a floor, with air drag, strain limiting and the
    watchdog on; explicit Euler with the substeps and damping it needs."""
    scene = rustcloth.load_scene("drape").replace(
        integrator=integrator,
        air_drag=0.001,
        cloth={"nx": 24, "ny": 24, "pins": ["corners"]},
        strain_limit={"max_strain": 0.1, "iterations": 4},
        watchdog=watchdog or {"max_stretch": 3.0, "on_trouble": "substep"},
    )
    if integrator == "explicit_euler":
        scene = scene.replace(substeps=16, cloth={"damping": 0.05})
    return scene


def _quiet(scene: Scene) -> Simulation:
    with warnings.catch_warnings():
        warnings.simplefilter("error", rustcloth.StabilityWarning)
        return Simulation(scene)


def _masked(sim: Simulation, rows) -> dict:
    """The state with the given rows of every position array set to 0 (the dead particles'
    positions are the one thing allowed to differ)."""
    state = sim.get_state()
    state["positions"] = state["positions"].copy()
    state["positions"][list(rows)] = 0.0
    previous = state["watchdog"]["previous"]
    if previous is not None:
        positions = previous[0].copy()
        positions[list(rows)] = 0.0
        state["watchdog"]["previous"] = (positions, *previous[1:])
    return state


@pytest.mark.parametrize("far", [1e30, -1e30])
@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
def test_a_dead_particle_far_away_changes_nothing(integrator, far):
    sims = [_quiet(every_pass(integrator)) for _ in range(2)]
    for sim in sims:
        sim.step(150)  # on the sphere, in contact, strain limit active
        for p in CUT:
            sim.cut(p)
        sim.pin(23, target=sim.positions[23] + [0.0, 0.05, 0.0])  # the kinematic pins pass
        sim.step(5)
    moved, twin = sims
    assert "kinematic_pins" in moved.effects and "spheres" in moved.effects
    x = moved.positions.copy()
    x[list(CUT)] = far
    moved.set_positions(x)
    twin.set_positions(twin.positions)  # the same call, with the dead particles left in place
    for _ in range(4):
        moved.step(25)
        twin.step(25)
        np.testing.assert_array_equal(moved.positions[list(CUT)], np.float32(far))
        a, b = _masked(moved, CUT), _masked(twin, CUT)
        assert state_differences(a, b) == []
    assert np.array_equal(moved.normals[moved.alive], twin.normals[twin.alive])
    assert moved.max_stretch() == twin.max_stretch()
    e_moved, e_twin = moved.energy(), twin.energy()
    assert e_moved == e_twin
    ray = ([0.0, 3.0, 0.0], [0.0, -1.0, 0.0])
    assert moved.pick(*ray) == twin.pick(*ray)


def _refusing(integrator: str, on_trouble: str = "raise") -> Scene:
    # Any spring past 1.5 times its rest length is refused and the step raised; with
    # "substep", after retries with 2 and 4 times the substeps, which cannot help here.
    return every_pass(integrator, max_stretch=1.5, on_trouble=on_trouble, max_substeps=4)


GRABBED = 24 * 12 + 12  # the middle of the cloth

# What a refused step may leave behind: the watchdog's statistics (a record of what it caught
# and the retries it tried: that is what they are for) and the cache versions (they only count
# up).
RECORDS = ("state.watchdog.stats.", "state.state_version", "state.topology_version")


def _hidden_differences(sim: Simulation, twin: Simulation) -> list[str]:
    diffs = state_differences(twin.get_state(), sim.get_state())
    return [d for d in diffs if not d.startswith(RECORDS)]





@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
def test_a_refused_step_leaves_no_trace(integrator, n):
    _refused_step_leaves_no_trace(integrator, n, "raise")


@pytest.mark.parametrize(
    "integrator",
    [pytest.param(name, marks=[])
     for name in rustcloth.INTEGRATORS],
)
def test_a_step_refused_after_its_retries_leaves_no_trace(integrator):
    _refused_step_leaves_no_trace(integrator, 1, "substep")


def _refused_step_leaves_no_trace(integrator: str, n: int, on_trouble: str) -> None:
    scene = _refusing(integrator, on_trouble)
    sim, twin = _quiet(scene), _quiet(scene)
    for s in (sim, twin):
        s.step(40)  # Verlet is primed, the watchdog remembers a previous state
        s.grab(GRABBED)
        s.drag_time = 0.0  # a drag lands in the next step instead of gliding there
    start = sim.positions[GRABBED].copy()
    # Dragged 2 m in one step: the next step overstretches and is refused.
    sim.drag_to(start + [0.0, 2.0, 0.0])
    with pytest.raises(SimulationDiverged) as info:
        sim.step(n)
    assert info.value.reason == "overstretched"
    assert sim.steps == 40
    # Dragged back: the grab's target is where it was, and nothing else differs but the
    # record of the refusal (watchdog_stats()["caught"]) and the cache versions.
    sim.drag_to(start)
    assert _hidden_differences(sim, twin) == []
    for _ in range(3):
        sim.step(10)
        twin.step(10)
        assert _hidden_differences(sim, twin) == []
    assert sim.watchdog_stats()["caught"] == twin.watchdog_stats()["caught"] + 1


@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
def test_a_refused_advance_owes_its_time(integrator):
    # The same through advance: the refused call's time stays owed; dragged back, the next
    # advance(0) takes exactly the steps the twin's advance takes.
    sim, twin = _quiet(_refusing(integrator)), _quiet(_refusing(integrator))
    for s in (sim, twin):
        s.step(40)
        s.grab(GRABBED)
        s.drag_time = 0.0  # a drag lands in the next step instead of gliding there
    start = sim.positions[GRABBED].copy()
    sim.drag_to(start + [0.0, 2.0, 0.0])
    with pytest.raises(SimulationDiverged):
        sim.advance(0.0105)
    sim.drag_to(start)
    assert sim.advance(0.0) == twin.advance(0.0105) == 10
    assert _hidden_differences(sim, twin) == []


@settings(derandomize=True, max_examples=40, database=None, deadline=None)
@given(
    integrator=st.sampled_from(rustcloth.INTEGRATORS),
    cut=st.lists(st.integers(0, 24 * 24 - 1), min_size=1, max_size=6, unique=True),
    far=st.floats(1e3, 1e37) | st.floats(-1e37, -1e3),
    axis=st.sampled_from([0, 1, 2, None]),
)
def test_dead_particles_anywhere_change_nothing(integrator, cut, far, axis):
    # Any set of cut particles, sent anywhere along one axis or all three: the live cloth
    # evolves bitwise as in a twin whose dead particles stayed where they were.
    sims = [_quiet(every_pass(integrator)) for _ in range(2)]
    for sim in sims:
        sim.step(60)
        for p in cut:
            sim.cut(p)
    moved, twin = sims
    x = moved.positions.copy()
    if axis is None:
        x[cut] = far
    else:
        x[cut, axis] = far
    moved.set_positions(x)
    twin.set_positions(twin.positions)
    moved.step(30)
    twin.step(30)
    assert state_differences(_masked(moved, cut), _masked(twin, cut)) == []
