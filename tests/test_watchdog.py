"""The Python face of the stability tools: the watchdog's settings, report and statistics,
per-particle masses and ``Scene.stability_report``."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import rustcloth
from conftest import small_scene, state_digest
from rustcloth import StabilityWarning


def stiff(**watchdog) -> rustcloth.Scene:
    """Springs 100 times too stiff for symplectic Euler at dt = 1 ms."""
    return small_scene(cloth={"k_structural": 2e4}, watchdog=watchdog)


def test_watchdog_settings_are_validated_and_named():
    with pytest.raises(rustcloth.ParameterError, match="watchdog.max_stretch") as e:
        rustcloth.Scene(watchdog={"max_stretch": 0.9})
    assert e.value.parameter == "watchdog.max_stretch"
    with pytest.raises(rustcloth.ParameterError, match="watchdog.on_trouble"):
        rustcloth.Scene(watchdog={"on_trouble": "ignore"})
    with pytest.raises(rustcloth.ParameterError, match="watchdog.max_substeps"):
        rustcloth.Scene(watchdog={"max_substeps": 0})
    with pytest.raises(rustcloth.ParameterTypeError, match="watchdog.hold_steps"):
        rustcloth.Scene(watchdog={"hold_steps": "many"})


def test_divergence_reports_reason_step_and_substeps():
    with pytest.warns(StabilityWarning):
        sim = rustcloth.Simulation(stiff(max_stretch=1.2))
    with pytest.raises(rustcloth.SimulationDiverged) as e:
        sim.step(500)
    err = e.value
    assert isinstance(err, FloatingPointError)
    assert err.reason == "overstretched" and err.substeps == 1
    assert sim.steps == err.step - 1
    assert "max_stretch = 1.2" in str(err)
    assert np.isfinite(sim.positions).all()
    assert sim.watchdog_stats() == {
        "caught": 1, "retried": 0, "retry_substeps": 0, "max_substeps_used": 0, "held_steps": 0,
        "largest_cascade": 0,
    }


def test_substep_retries_are_reported_in_the_statistics():
    with pytest.warns(StabilityWarning):
        sim = rustcloth.Simulation(stiff(max_stretch=1.2, on_trouble="substep"))
    sim.step(300)
    stats = sim.watchdog_stats()
    assert stats["retried"] == stats["caught"] >= 1
    assert stats["max_substeps_used"] >= 4
    assert sim.max_stretch() <= 0.2


def test_set_masses_validates_and_leaves_the_state_on_error(sim):
    n = sim.num_particles
    before = (state_digest(sim), sim.masses.copy())
    bad = [
        (np.ones(n - 1), rustcloth.ParameterError),
        (np.ones((n, 1)), rustcloth.ParameterError),
        (np.full(n, -1.0), rustcloth.ParameterError),
        (np.full(n, np.nan), rustcloth.ParameterError),
        (np.full(n, 1e-300), rustcloth.ParameterError),
        (np.full(n, 1e300), rustcloth.ParameterError),
        (np.ones(n, dtype=np.int64), rustcloth.ParameterTypeError),
        ([1.0] * n, rustcloth.ParameterTypeError),
    ]
    for masses, error in bad:
        with pytest.raises(error, match="masses"):
            sim.set_masses(masses)
        assert (state_digest(sim), sim.masses.tobytes()) == (before[0], before[1].tobytes())


def test_a_heavier_cloth_hangs_lower_and_the_stable_step_follows_the_lightest_particle(sim):
    m = sim.masses[0]
    limit = sim.stable_dt()
    masses = np.full(sim.num_particles, m, dtype=np.float64)
    masses[5] = m / 100
    sim.set_masses(masses)
    # omega ~ 1/sqrt(m): a particle 100 times lighter divides the limit by at least 10, more
    # since the damping rate c / m grows a hundredfold.
    assert 9.9 < limit / sim.stable_dt() < 30
    light = rustcloth.Simulation(small_scene())
    heavy = rustcloth.Simulation(small_scene())
    heavy.set_masses(np.full(heavy.num_particles, 4 * m))
    light.step(3000)
    heavy.step(3000)
    assert heavy.positions[:, 1].mean() < light.positions[:, 1].mean() - 0.005


def test_stability_report_matches_the_formula_and_warns():
    scene = small_scene(cloth={"damping": 0.0}, air_drag=0.0)
    report = scene.stability_report()
    c = scene.cloth
    omega = math.sqrt(4 * (c["k_structural"] + c["k_shear"] + c["k_bend"]) / c["particle_mass"])
    assert report.omega == pytest.approx(omega)
    assert report.stable_dt["symplectic_euler"] == pytest.approx(2 / omega)
    assert report.stable_dt["rk4"] == pytest.approx(2 * math.sqrt(2) / omega)
    assert report.stable_dt["implicit_euler"] is None
    assert report.stable_dt["explicit_euler"] == 0.0  # no damping: never stable
    assert report.stable and report.substeps_needed() == 1
    fast = scene.replace(dt=0.01)
    with pytest.warns(StabilityWarning, match="UNSTABLE"):
        unstable = fast.stability_report()
    assert not unstable.stable
    needed = unstable.substeps_needed()
    assert needed == math.ceil(0.01 / (2 / omega))
    assert "symplectic_euler" in str(unstable)
    # And it is right: the needed substeps hold the cloth, half of them do not.
    ok = rustcloth.Simulation(fast.replace(substeps=needed))
    ok.step(2000)
    assert ok.max_stretch() < 0.5
    with pytest.warns(StabilityWarning):
        bad = rustcloth.Simulation(fast.replace(substeps=max(1, needed // 2)))
    with pytest.raises(rustcloth.SimulationDiverged):
        bad.step(2000)


def test_stability_report_covers_both_implicit_solvers():
    # Both solve backward Euler implicitly: no step limit, no warning at a frame's step, and the
    # simulation's own estimate agrees.
    for integrator in ("implicit_euler", "projective_dynamics"):
        scene = small_scene(integrator=integrator, dt=1 / 30)
        report = scene.stability_report()
        assert report.stable_dt[integrator] is None
        assert report.stable and report.substeps_needed() is None
        with warnings.catch_warnings():
            warnings.simplefilter("error", StabilityWarning)
            sim = rustcloth.Simulation(scene)
        assert sim.stable_dt() is None
