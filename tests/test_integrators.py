"""Every integrator from Python: against the numpy reference, and its solver reporting."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rustcloth
from conftest import small_scene
from rustcloth import Simulation
from rustcloth.reference import ReferenceCloth

# (integrator, dt, tolerance on positions in m after 0.1 s). The implicit solve is compared at a
# tight CG tolerance; its float32 CG against a float64 dense solve still differs slightly.
# Projective dynamics runs 400 iterations a step against the exact backward-Euler step (Newton).
CASES = [
    ("explicit_euler", 5e-5, 2e-5),
    ("symplectic_euler", 1e-3, 2e-5),
    ("verlet", 1e-3, 2e-5),
    ("rk4", 2e-3, 2e-5),
    ("implicit_euler", 2e-3, 1e-4),
    ("projective_dynamics", 2e-3, 1e-4),
]


@pytest.mark.parametrize(("integrator", "dt", "tolerance"), CASES)
def test_every_integrator_matches_the_numpy_reference(integrator, dt, tolerance):
    scene = small_scene(integrator=integrator, dt=dt, cg_tolerance=1e-6, cg_max_iterations=500,
                        pd_iterations=400, pd_tolerance=0.0)
    sim, ref = Simulation(scene), ReferenceCloth(scene.to_dict())
    kick = np.zeros_like(ref.positions)
    kick[:, 2] = np.sin(np.arange(len(kick)) * 0.7)
    kick[sim.pinned] = 0.0
    sim.set_velocities(kick.astype(np.float32))
    ref.set_velocities(kick.astype(np.float32).astype(float))
    n = round(0.025 / dt)
    for _ in range(4):
        sim.step(n)
        ref.step(n)
        np.testing.assert_allclose(sim.positions, ref.positions, atol=tolerance)


@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
def test_every_integrator_keeps_pins_and_colliders(integrator):
    # Explicit Euler amplifies the stiff modes faster than spring damping removes them at the
    # scene's 0.5 ms substeps; it needs about 30 us.
    substeps = 32 if integrator == "explicit_euler" else 2
    cloth = {"nx": 24, "ny": 24, "pins": ["top_corners"]}
    scene = rustcloth.load_scene("drape").replace(
        integrator=integrator, substeps=substeps, cloth=cloth
    )
    sim = Simulation(scene)
    pinned = sim.pinned
    before = sim.positions[pinned].copy()
    sphere = scene.spheres[0]
    c, r = np.array(sphere["center"]), sphere["radius"] + sphere["thickness"]
    for _ in range(20):
        sim.step(25)
        x = sim.positions.astype(float)
        assert np.isfinite(x).all() and (np.abs(x) < 10).all()
        assert (x[:, 1] >= scene.floor["thickness"] - 1e-7).all()
        assert (np.linalg.norm(x - c, axis=1) >= r * (1 - 1e-6)).all()
    np.testing.assert_array_equal(sim.positions[pinned], before)


def test_implicit_solver_statistics_are_in_the_profile():
    sim = Simulation(small_scene(integrator="implicit_euler", dt=1 / 60))
    sim.step(10)
    profile = sim.profile()
    assert profile.solver["solves"] == 10
    assert profile.solver["iterations"] >= 10
    assert 0 <= profile.solver["last_residual"] <= 1e-4
    assert profile.solver["not_converged"] == 0
    assert "CG:" in str(profile)
    assert Simulation(small_scene()).profile().solver is None


def test_projective_dynamics_reports_iterations_residual_and_factorisations():
    sim = Simulation(small_scene(integrator="projective_dynamics", dt=1 / 60, pd_iterations=7))
    sim.step(10)
    stats = sim.solver_stats()
    assert stats["solves"] == 10 and stats["iterations"] == 70 and stats["most_iterations"] == 7
    # The relative gradient after seven iterations: reduced, not yet small.
    assert 0 < stats["last_residual"] < 0.5
    assert stats["not_converged"] == 0  # pd_tolerance = 0: a fixed iteration count
    assert stats["factorizations"] == 1 and stats["setup_seconds"] > 0
    sim.pin(10)
    sim.step(1)
    assert sim.solver_stats()["factorizations"] == 2, "a new pin changes the matrix"


def test_an_unconverged_projective_dynamics_step_is_warned_about_once():
    scene = small_scene(integrator="projective_dynamics", dt=1 / 60, pd_iterations=2,
                        pd_tolerance=1e-6)
    sim = Simulation(scene)
    with pytest.warns(RuntimeWarning, match="pd_iterations"):
        sim.step(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.step(3)
    assert sim.solver_stats()["not_converged"] == 6


def test_an_unconverged_solve_is_reported_and_warned_about_once():
    sim = Simulation(small_scene(integrator="implicit_euler", dt=1 / 30, cg_max_iterations=1))
    with pytest.warns(RuntimeWarning, match="cg_max_iterations"):
        sim.step(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.step(3)  # no second warning
    assert sim.profile().solver["not_converged"] == 6


def test_switching_integrators_at_run_time_continues_the_motion():
    sim = Simulation(small_scene())
    sim.step(50)
    for name in rustcloth.INTEGRATORS:
        sim.integrator = name
        sim.step(20)
        assert sim.effects[len(sim.effects) - 1] == name
    assert np.isfinite(sim.positions).all()


@pytest.mark.parametrize(
    ("changes", "text"),
    [
        ({"cg_tolerance": 0.0}, "cg_tolerance"),
        ({"cg_tolerance": -1e-3}, "cg_tolerance"),
        ({"cg_max_iterations": 0}, "cg_max_iterations"),
        ({"integrator": "leapfrog"}, "implicit_euler"),
    ],
)
def test_bad_solver_settings(changes, text):
    with pytest.raises(ValueError, match=text):
        small_scene(**changes)
