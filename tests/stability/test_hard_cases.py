"""Hard cases stay numerically stable. Every case runs every integrator it applies to
and checks every step (``run_checked``): finite, bounded, outside the colliders, pins bitwise
put. Where an integrator cannot hold a case, the failure must be the watchdog's report with the
state rolled back, never a NaN. The impacts, the 10 m drag, cutting everything and the cloth
10 km from the origin are in ``tests/stability.rs``; ``docs/stability.md`` lists them all."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rustcloth
from rustcloth import StabilityWarning
from stability.checks import ALL, EXPLICIT, IMPLICIT, check_state, hanging, run_checked, stable


def make(scene: rustcloth.Scene) -> rustcloth.Simulation:
    """A simulation of a scene that is meant to be past its explicit stability limit."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        return rustcloth.Simulation(scene)


# ----- very stiff springs: k dt^2 / m = 100 ---------------------------------------------------

STIFF = {"k_structural": 1e5}


@pytest.mark.parametrize("integrator", IMPLICIT)
def test_very_stiff_springs_hold_with_the_implicit_solvers(integrator):
    sim = make(hanging(integrator=integrator, cloth=STIFF,
                       watchdog={"max_stretch": 1.2}))
    assert run_checked(sim, 200) is None
    assert sim.watchdog_stats()["caught"] == 0
    assert sim.max_stretch() < 0.01


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_very_stiff_springs_are_caught_before_any_nan(integrator):
    sim = make(hanging(integrator=integrator, cloth=STIFF, watchdog={"max_stretch": 1.2}))
    e = run_checked(sim, 200)
    assert e is not None and e.reason == "overstretched", e
    assert sim.watchdog_stats()["caught"] == 1


@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet", "rk4"])
def test_very_stiff_springs_are_saved_by_substep_retries(integrator):
    sim = make(hanging(integrator=integrator, cloth=STIFF,
                       watchdog={"max_stretch": 1.2, "on_trouble": "substep"}))
    assert run_checked(sim, 200) is None
    stats = sim.watchdog_stats()
    needed = sim.scene.stability_report(warn=False).substeps_needed()
    # The held substeps reach what the linear stability estimate asks for, within a doubling.
    assert needed <= 2 * stats["max_substeps_used"], (stats, needed)
    assert stats["retried"] >= 1 and stats["held_steps"] > 100, stats


def test_explicit_euler_past_max_substeps_is_reported():
    # Explicit Euler would need thousands of substeps: the retries give up and report.
    sim = make(hanging(integrator="explicit_euler", cloth=STIFF,
                       watchdog={"max_stretch": 1.2, "on_trouble": "substep"}))
    e = run_checked(sim, 200)
    assert e is not None and e.substeps == 64, e


# ----- large steps: 1/30 s and 1/15 s -----------------------------------------------------------

@pytest.mark.parametrize("dt", [1 / 30, 1 / 15])
@pytest.mark.parametrize("integrator", IMPLICIT)
def test_large_steps_hold_with_the_implicit_solvers(integrator, dt):
    sim = make(hanging(integrator=integrator, dt=dt, substeps=1, air_drag=0.001))
    assert run_checked(sim, 60) is None


@pytest.mark.parametrize("dt", [1 / 30, 1 / 15])
@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet", "rk4"])
def test_large_steps_with_two_substeps_are_saved_by_retries(integrator, dt):
    sim = make(hanging(integrator=integrator, dt=dt, substeps=2,
                       watchdog={"max_stretch": 1.3, "on_trouble": "substep"}))
    assert run_checked(sim, 30) is None
    assert sim.watchdog_stats()["retried"] >= 1


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_large_steps_without_retries_are_reported(integrator):
    sim = make(hanging(integrator=integrator, dt=1 / 30, substeps=2,
                       watchdog={"max_stretch": 1.3}))
    assert run_checked(sim, 30) is not None


# ----- masses ---------------------------------------------------------------------------------

@pytest.mark.parametrize("integrator", ALL)
def test_mass_ratio_of_1000_to_1_across_the_cloth(integrator):
    # A checkerboard of 1 g and 1 kg particles: every spring joins a 1000:1 pair.
    scene = hanging(16, integrator=integrator, air_drag=0.01, floor={"height": 0.0},
                    cloth={"k_structural": 2000.0, "damping": 0.05})
    # The lightest particle sets the stable step: the scene's uniform 1 g does.
    sim = rustcloth.Simulation(stable(scene))
    i, j = np.meshgrid(np.arange(16), np.arange(16))
    masses = np.where((i + j).ravel() % 2 == 0, 1e-3, 1.0)
    sim.set_masses(masses)
    np.testing.assert_array_equal(sim.masses, masses.astype(np.float32))
    steps = 120 if integrator in IMPLICIT else 400
    assert run_checked(sim, steps) is None


@pytest.mark.parametrize("integrator", ALL)
def test_very_light_particles(integrator):
    # 1 mg cloth, 1e-6 kg per particle: omega = 3.2e4 rad/s at the default stiffness.
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator,
                                              cloth={"particle_mass": 1e-6})))
    assert run_checked(sim, 300) is None


# ----- degenerate starts ------------------------------------------------------------------------

@pytest.mark.parametrize("integrator", ALL)
def test_a_cloth_collapsed_into_one_point_stays_finite(integrator):
    # Every spring has zero length and so no direction: no spring force, nothing to divide by.
    # It is an unstable equilibrium (a spring of rest length L at length ~0 pushes with k L as
    # soon as rounding gives it a direction), so it stays a point only where every particle's
    # arithmetic is the same: the explicit integrators, and implicit Euler with the Jacobi
    # preconditioner. Solvers that couple the particles (the multigrid preconditioner,
    # projective dynamics' factorisation) round differently at the edges; they must stay finite.
    scene = stable(hanging(integrator=integrator, cloth={"pins": []}))
    exact = integrator in EXPLICIT or integrator == "implicit_euler"
    if integrator == "implicit_euler":
        scene = scene.replace(preconditioner="jacobi")
    sim = rustcloth.Simulation(scene)
    sim.set_positions(np.tile([0.3, 1.0, -0.2], (sim.num_particles, 1)))
    assert run_checked(sim, 200) is None
    x = sim.positions
    if exact:
        assert np.ptp(x, axis=0).max() == 0.0, "a point cloth with only gravity stays one"


@pytest.mark.parametrize("integrator", ALL)
def test_coincident_particle_pairs_recover(integrator):
    # Each odd column sits on the even column to its left: a quarter of the springs start at
    # zero length, the structural springs across pairs at twice their rest length.
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator, air_drag=0.002,
                                              cloth={"damping": 0.05})))
    x = sim.positions.copy()
    nx = sim.nx
    odd = np.arange(sim.num_particles) % nx % 2 == 1
    x[odd] = x[np.flatnonzero(odd) - 1]
    sim.set_positions(x)
    start = sim.max_stretch()
    assert run_checked(sim, 1500) is None
    assert sim.max_stretch() < 0.2 * start, (start, sim.max_stretch())


@pytest.mark.parametrize("integrator", ALL)
def test_a_scrambled_start_recovers_or_is_reported(integrator):
    # Positions drawn at random in a 1 m cube: springs up to ~15 times their rest length, far
    # from where the linear stability estimate holds. A watchdog limit at twice the start's
    # worst stretch accepts the start and reports a cloth that flies apart instead.
    rng = np.random.default_rng(6)
    scene = stable(hanging(integrator=integrator, air_drag=0.002, cloth={"damping": 0.05}))
    x = rng.uniform(-0.5, 0.5, (scene.cloth["nx"] * scene.cloth["ny"], 3)) + [0, 1.5, 0]
    probe = rustcloth.Simulation(scene)
    probe.set_positions(x)
    start = probe.max_stretch()
    sim = rustcloth.Simulation(scene.replace(watchdog={"max_stretch": 2 * (1 + start)}))
    sim.set_positions(x)
    e = run_checked(sim, 1500, bound=1e3)
    if e is None:
        assert sim.max_stretch() < 0.5 * start, (start, sim.max_stretch())
    else:
        # Only explicit Euler, unstable for every undamped motion, may fail here.
        assert integrator == "explicit_euler" and e.reason == "overstretched", e


def test_a_scrambled_start_beyond_the_stretch_limit_is_refused():
    # The watchdog judges the state a step starts from; the user's state is not a step's fault,
    # so nothing is undone: the step is refused and the state kept as given.
    rng = np.random.default_rng(6)
    sim = rustcloth.Simulation(hanging(watchdog={"max_stretch": 2.0, "on_trouble": "substep"}))
    x = rng.uniform(-0.5, 0.5, (sim.num_particles, 3))
    sim.set_positions(x)
    with pytest.raises(rustcloth.SimulationDiverged) as e:
        sim.step(1)
    assert e.value.reason == "overstretched" and e.value.step == 1 and sim.steps == 0
    np.testing.assert_array_equal(sim.positions, x.astype(np.float32))


# ----- cutting ----------------------------------------------------------------------------------

@pytest.mark.parametrize("integrator", ALL)
def test_cutting_a_stretched_cloth(integrator):
    # Drag the bottom middle particle 0.5 m down, cut the cloth across while it is stretched,
    # let go: the pieces snap back and fall without trouble.
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator, air_drag=0.002,
                                              floor={"height": 0.0})))
    nx = sim.nx
    grabbed = nx // 2
    target = sim.positions[grabbed] - [0, 0.5, 0]
    sim.pin(grabbed, target)
    assert run_checked(sim, 100, dragged={grabbed}) is None
    assert sim.max_stretch() > 0.05, "the cloth should be stretched when cut"
    row = sim.ny // 2
    for i in range(nx):
        sim.cut(row * nx + i)
    assert run_checked(sim, 100, dragged={grabbed}) is None
    sim.unpin(grabbed)
    assert run_checked(sim, 300) is None


@pytest.mark.parametrize("integrator", ALL)
def test_cutting_every_other_particle(integrator):
    sim = rustcloth.Simulation(stable(hanging(integrator=integrator, floor={"height": 0.0})))
    assert run_checked(sim, 50) is None
    for p in range(0, sim.num_particles, 2):
        sim.cut(p)
    check_state(sim, 100.0)
    assert run_checked(sim, 300) is None
    assert not sim.alive[::2].any()
