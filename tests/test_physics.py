"""The solver checked by physics, from Python: against the numpy reference model, analytic
solutions and invariants."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import rustcloth
from conftest import small_scene
from rustcloth import Simulation
from rustcloth.reference import ReferenceCloth


# Explicit Euler amplifies every undamped mode a little each step, so it needs a much smaller
# step (here 50 us substeps, under its estimated limit of 81 us) to stay bounded long enough
# for a comparison; symplectic Euler is stable at 1 ms here.
@pytest.mark.parametrize(
    ("integrator", "dt", "substeps"),
    [("explicit_euler", 1e-4, 2), ("symplectic_euler", 1e-3, 1), ("symplectic_euler", 1e-3, 2)],
)
def test_trajectories_match_the_numpy_reference(integrator, dt, substeps):
    scene = small_scene(integrator=integrator, substeps=substeps, dt=dt)
    sim, ref = Simulation(scene), ReferenceCloth(scene.to_dict())
    np.testing.assert_allclose(sim.positions, ref.positions, atol=1e-6)
    # A push out of the plane, varying across the cloth, so that every spring family works.
    kick = np.zeros_like(ref.positions)
    kick[:, 2] = np.sin(np.arange(len(kick)) * 0.7)
    kick[sim.pinned] = 0.0
    sim.set_velocities(kick.astype(np.float32))
    ref.set_velocities(kick.astype(np.float32).astype(float))
    for _ in range(4):
        n = round(0.05 / dt)
        sim.step(n)
        ref.step(n)
        # f32 against f64 over hundreds of steps of a swinging cloth: micrometres.
        np.testing.assert_allclose(sim.positions, ref.positions, atol=2e-5)
        np.testing.assert_allclose(sim.velocities, ref.velocities, atol=2e-3)
    start = ReferenceCloth(scene.to_dict()).positions
    assert np.abs(ref.positions - start).max() > 0.05  # it did move


def test_free_fall_matches_the_discrete_closed_form():
    scene = small_scene(cloth={"pins": []}, air_drag=0.0)
    sim = Simulation(scene)
    y0 = sim.positions[:, 1].astype(float)
    n, h, g = 400, scene.dt, 9.81
    sim.step(n)
    expected = y0 - g * h * h * n * (n + 1) / 2  # symplectic Euler
    np.testing.assert_allclose(sim.positions[:, 1], expected, atol=2e-5)


def test_two_particle_spring_period():
    k, m = 40.0, 0.01
    scene = rustcloth.Scene(
        dt=1e-5,
        gravity=[0, 0, 0],
        cloth={"nx": 2, "ny": 2, "plane": "xy", "size": [1.0, 1.0], "particle_mass": m,
               "k_structural": k, "k_shear": 0, "k_bend": 0, "damping": 0, "pins": [[0, 0]]},
    )
    sim = Simulation(scene)
    sim.cut(2)
    sim.cut(3)
    pos = sim.positions.copy()
    rest = pos[1, 0]
    pos[1, 0] += 0.02
    sim.set_positions(pos)
    expected = 2 * np.pi * np.sqrt(m / k)
    xs = []
    for _ in range(int(3.2 * expected / scene.dt) // 50):
        sim.step(50)
        xs.append(sim.positions[1, 0] - rest)
    xs = np.array(xs)
    t = np.arange(1, len(xs) + 1) * 50 * scene.dt
    up = np.nonzero((xs[:-1] < 0) & (xs[1:] >= 0))[0]
    crossings = t[up] + (t[up + 1] - t[up]) * (-xs[up]) / (xs[up + 1] - xs[up])
    period = np.diff(crossings).mean()
    assert period == pytest.approx(expected, rel=2e-3)


def test_floor_and_sphere_are_never_penetrated():
    scene = rustcloth.load_scene("drape")
    sim = Simulation(scene)
    floor = scene.floor["height"] + scene.floor["thickness"]
    sphere = scene.spheres[0]
    c, r = np.array(sphere["center"]), sphere["radius"] + sphere["thickness"]
    vel = sim.velocities.copy()
    vel[:, 1] = -30.0  # a hard throw
    sim.set_velocities(vel)
    for _ in range(300):
        sim.step(2)
        x = sim.positions.astype(float)
        assert np.isfinite(x).all() and (np.abs(x) < 10).all()
        assert (x[:, 1] >= floor - 1e-7).all()
        assert (np.linalg.norm(x - c, axis=1) >= r * (1 - 1e-6)).all()


def test_divergence_restores_the_last_finite_state_and_names_the_step():
    with pytest.warns(rustcloth.StabilityWarning, match="stability limit"):
        sim = Simulation(small_scene(cloth={"k_structural": 1e6}))
    good = None
    with pytest.raises(rustcloth.SimulationDiverged) as info:
        for _ in range(10_000):
            good = (sim.positions, sim.velocities, sim.steps)
            sim.step(1)
    err = info.value
    assert isinstance(err, FloatingPointError)
    assert err.step == good[2] + 1 and 0 <= err.particle < sim.num_particles
    assert f"step {err.step}" in str(err) and f"particle {err.particle}" in str(err)
    np.testing.assert_array_equal(sim.positions, good[0])
    np.testing.assert_array_equal(sim.velocities, good[1])
    assert sim.steps == good[2]


DIGEST_SCRIPT = textwrap.dedent(
    """
    import hashlib, sys, rustcloth
    if len(sys.argv) > 2:
        # A built-in scene as it is, 40 of its steps.
        scene = rustcloth.load_scene(sys.argv[2])
    else:
        scene = rustcloth.load_scene("drape")
        cloth = {"nx": 96, "ny": 96, "pins": ["corners"]}
        scene = scene.replace(integrator=sys.argv[1], cloth=cloth)
    sim = rustcloth.Simulation(scene)
    # Projective dynamics' step costs about ten of the others'; every stage runs in ten.
    sim.step(10 if sys.argv[1] == "projective_dynamics" else 40)
    digest = hashlib.sha256(sim.positions.tobytes() + sim.velocities.tobytes()).hexdigest()
    print(digest, rustcloth._core.instruction_set(), rustcloth._core.thread_count())
    """
)

ISAS = ("baseline", "avx2", "avx512")


def digest_with(
    env: dict[str, str], integrator: str = "symplectic_euler", scene: str | None = None
) -> tuple[str, str, int]:
    """``(state digest, instruction set used, threads used)`` of a run in a fresh process: the
    96 x 96 drape under ``integrator`` (40 steps, projective dynamics 10), or the built-in
    ``scene`` as it is (40 steps)."""
    chosen = ("RUSTCLOTH_SIMD", "RAYON_NUM_THREADS")
    clean = {k: v for k, v in os.environ.items() if k not in chosen}
    args = [sys.executable, "-c", DIGEST_SCRIPT, integrator, *([scene] if scene else [])]
    out = subprocess.run(args, env=dict(clean, **env), check=True, capture_output=True, text=True)
    digest, isa, threads = out.stdout.split()
    return digest, isa, int(threads)


@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
def test_state_is_bitwise_identical_across_vector_instruction_sets(integrator):
    # The hot loops are compiled for SSE2, AVX2 and AVX-512 and chosen at run time; none
    # reorders arithmetic, so all give the same bits. Each run reports the instruction set it
    # used: the one asked for, or the CPU's widest where it lacks that one, checked so that
    # the test cannot compare one set three times.
    best = digest_with({})[1]
    runs = {isa: digest_with({"RUSTCLOTH_SIMD": isa}, integrator) for isa in ISAS}
    for isa, (_, used, _) in runs.items():
        assert used == ISAS[min(ISAS.index(isa), ISAS.index(best))], (isa, used, best)
    assert len({digest for digest, _, _ in runs.values()}) == 1, runs


def test_mesh_cloth_state_is_bitwise_identical_across_instruction_sets_and_threads():
    # The mesh's spring pass gathers its ends and vectorises the arithmetic per block; the
    # shirt has stretch, bend and seam springs, the seams closing. The unforced run (the
    # widest set, every thread) gives the same bits as every forced one.
    auto = digest_with({}, scene="shirt")
    best = auto[1]
    runs = {
        (isa, threads): digest_with(
            {"RUSTCLOTH_SIMD": isa, "RAYON_NUM_THREADS": str(threads)}, scene="shirt"
        )
        for isa, threads in (("baseline", 1), ("avx2", 2), ("avx512", 1), ("avx512", 3))
    }
    for (isa, threads), (_, used, used_threads) in runs.items():
        assert used == ISAS[min(ISAS.index(isa), ISAS.index(best))] and used_threads == threads
    assert len({digest for digest, _, _ in [auto, *runs.values()]}) == 1, (auto, runs)


def test_membrane_cloth_state_is_bitwise_identical_across_instruction_sets_and_threads(tmp_path):
    # The triangle membrane's pass gathers each block's edges and vectorises the arithmetic
    # without a branch; a hanging jittered square, 40 steps.
    from test_mesh_cloth import jittered_square

    vertices, triangles = jittered_square(40, seed=3)
    scene = rustcloth.Scene(dt=2e-4).with_cloth_mesh(
        vertices, triangles, pins=[40 * 39, 40 * 40 - 1], membrane="triangle", stretch=60.0
    )
    path = tmp_path / "membrane.toml"
    path.write_text(scene.to_toml())
    best = digest_with({}, scene=str(path))[1]
    runs = {
        (isa, threads): digest_with(
            {"RUSTCLOTH_SIMD": isa, "RAYON_NUM_THREADS": str(threads)}, scene=str(path)
        )
        for isa, threads in (("baseline", 1), ("avx2", 2), ("avx512", 1), ("avx512", 3))
    }
    for (isa, threads), (_, used, used_threads) in runs.items():
        assert used == ISAS[min(ISAS.index(isa), ISAS.index(best))] and used_threads == threads
    assert len({digest for digest, _, _ in runs.values()}) == 1, runs


def test_state_is_bitwise_identical_across_thread_counts():
    runs = {threads: digest_with({"RAYON_NUM_THREADS": str(threads)}) for threads in (1, 2, 3)}
    assert all(used == threads for threads, (_, _, used) in runs.items()), runs
    assert len({digest for digest, _, _ in runs.values()}) == 1, runs
