"""Energy at contacts, and ``energy()`` itself.

Contact and strain-limit corrections move positions only; turned into velocity they would pump
energy into a cloth resting against a sphere (hundreds of joules in milliseconds, at a
128 x 128 cloth with ``[strain_limit]``). So energy must not rise at contacts.

``energy()`` is a reduction over fixed chunks in float64: bitwise the same on every call and
at every thread count, and finite for every finite state (a float32 square of a large velocity
would overflow to ``inf``)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import rustcloth
from conftest import small_scene, worker_run
from rustcloth import Scene, Simulation

# A cloth dropped flat onto a sphere standing on a floor: sphere and floor contact, friction.
DROPPED = Scene(
    dt=0.001,
    substeps=2,
    cloth={
        "nx": 24, "ny": 24, "size": [1.0, 1.0], "center": [0.1, 0.9, 0.0], "plane": "xz",
        "pins": [], "particle_mass": 0.0005, "k_structural": 300.0, "k_shear": 60.0,
        "k_bend": 10.0, "damping": 0.01,
    },
    floor={"height": 0.0, "friction": 0.4, "thickness": 0.003},
    spheres=[{"center": [0.0, 0.3, 0.0], "radius": 0.3, "friction": 0.3, "thickness": 0.005}],
)

SCENES = {
    "drape": rustcloth.load_scene("drape"),
    "freefall": rustcloth.load_scene("freefall"),
    # Without its draught: wind does work on the cloth, and this checks that nothing else does.
    "curtain": rustcloth.load_scene("curtain").replace(wind=None),
    "dropped": DROPPED,
}


def with_every_pass(scene: Scene, integrator: str) -> Scene:
    """Strain limiting, air drag and the watchdog (with retries) on, at a 24 x 24 cloth."""
    changed = scene.replace(
        integrator=integrator,
        air_drag=max(scene.air_drag, 0.001),
        strain_limit={"max_strain": 0.1, "iterations": 4},
        watchdog={"max_stretch": 3.0, "on_trouble": "substep"},
        cloth={"nx": 24, "ny": 24},
    )
    if integrator == "explicit_euler":
        # Explicit Euler grows every undamped mode; with this damping and 16 substeps the
        # spring damping outruns the growth (docs/stability.md).
        changed = changed.replace(substeps=16, cloth={"damping": 0.05})
    return changed


# The energy scale of a scene is the gravitational energy its cloth can release, m g y_max
# (4.5 to 16 J here). Tolerances are fractions of it:
#  - 1e-6 for the integrators whose energy does not grow: float32 positions near 1 m round at
#    6e-8 m, so the sum of the potential energies is known to about m g 1e-7 (1e-7 of the
#    scale); symplectic Euler's and Verlet's bounded energy oscillation at these steps is
#    smaller still. Measured rises: none (every sample at or below the running minimum to
#    within 2e-7 of the scale). A correction turned into velocity injects hundreds of joules,
#    20 to 70 times the scale.
#  - 1e-5 for explicit Euler with damping, whose undamped error grows like (1 + (omega h)^2)
#    per step before the damping takes it back out; measured at most 1.1e-6.
TOLERANCE = {"explicit_euler": 1e-5}
STABLE = 1e-6


@pytest.mark.parametrize("integrator", rustcloth.INTEGRATORS)
@pytest.mark.parametrize("name", list(SCENES))
def test_energy_never_rises_at_contacts(name, integrator):
    with warnings.catch_warnings():
        warnings.simplefilter("error", rustcloth.StabilityWarning)
        sim = Simulation(with_every_pass(SCENES[name], integrator))
    assert {"strain_limit", "air_drag"} <= set(sim.effects)
    start = sim.energy().total
    scale = float(sim.masses.sum()) * 9.81 * float(sim.positions[:, 1].max())
    tolerance = TOLERANCE.get(integrator, STABLE) * scale
    lowest = start
    touched = False
    for _ in range(400):
        sim.step(3)
        e = sim.energy().total
        assert math.isfinite(e)
        # Never above the start, nor above the lowest energy so far: with gravity counted in
        # the total and no moving pins, nothing may add energy, only take it away.
        assert e <= start + tolerance, (e - start) / scale
        assert e <= lowest + tolerance, (e - lowest) / scale
        lowest = min(lowest, e)
        touched = touched or _touching(sim)
    # The cloth did reach a collider (the curtain hangs clear of its sphere and floor: it
    # checks the strain limit and drag on a swinging pinned cloth).
    assert touched == (name != "curtain")
    assert lowest < start  # and something dissipated


def _touching(sim: Simulation) -> bool:
    """Whether a particle is within 5 mm of the floor or a sphere's surface."""
    x = sim.positions.astype(np.float64)
    scene = sim.scene
    if scene.floor is not None and x[:, 1].min() < scene.floor["height"] + 0.005:
        return True
    return any(
        (np.linalg.norm(x - s["center"], axis=1) < s["radius"] + s["thickness"] + 0.005).any()
        for s in scene.spheres
    )


def _intersecting(strain_limit: dict | None, integrator: str = "symplectic_euler") -> Scene:
    # The reported case: a 128 x 128 cloth at rest, cutting through a sphere.
    return Scene(
        integrator=integrator,
        dt=0.001,
        cloth={
            "nx": 128, "ny": 128, "size": [1.0, 1.0], "center": [0.0, 0.5, 0.0],
            "plane": "xz", "pins": [],
        },
        spheres=[{"center": [0.0, 0.5, 0.0], "radius": 0.3}],
        strain_limit=strain_limit,
    )


@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet", "rk4", "implicit_euler"])
def test_strain_limit_does_not_pump_energy_at_a_sphere(integrator):
    # The sphere pushes the particles inside it to its surface, which stretches the springs:
    # about 318 J of elastic energy with or without the limit, a position change that the
    # contact does not turn into speed (0.13 J of kinetic energy). The limit may move which
    # particles carry that stretch, a small change (0.14 % measured; 1 % allowed), but it must
    # not turn its corrections into velocity: kinetic energy and top speed as without it (5 %
    # and 10 % allowed; a correction turned into velocity gives thousands of times the kinetic
    # energy).
    results = {}
    for label, limit in (("without", None), ("with", {"max_strain": 0.1, "iterations": 4})):
        sim = Simulation(_intersecting(limit, integrator))
        start = sim.energy().total
        sim.step(2)
        e = sim.energy()
        speed = float(np.linalg.norm(sim.velocities, axis=1).max())
        results[label] = (e.total - start, e.kinetic, speed)
    (gain0, kinetic0, speed0), (gain1, kinetic1, speed1) = results["without"], results["with"]
    assert gain1 <= gain0 + 0.01 * abs(gain0), results
    assert kinetic1 <= 1.05 * kinetic0, results
    assert speed1 <= 1.1 * speed0 and speed1 < 5.0, results


def test_energy_is_bitwise_the_same_on_every_call():
    sim = Simulation(small_scene(cloth={"nx": 300, "ny": 200}))  # 15 fixed chunks
    sim.step(5)
    rng = np.random.default_rng(3)
    sim.set_velocities(rng.normal(size=(sim.num_particles, 3)).astype(np.float32))
    first = [x.hex() for x in sim.energy()]
    for _ in range(50):
        assert [x.hex() for x in sim.energy()] == first


@pytest.mark.xdist_group("reliability_worker")  # the worker's runs are cached per process
def test_energy_is_bitwise_the_same_at_every_thread_count():
    # The worker (tests/reliability_worker.py) computes energies of many-chunk states at 1, 2
    # and 7 threads in subprocesses; the bits agree with each other and with this process.
    runs = [worker_run(t)["energies"] for t in (1, 2, 7)]
    assert runs[0] == runs[1] == runs[2]
    sim = Simulation(small_scene(cloth={"nx": 300, "ny": 200, "size": [1.0, 0.5],
                                        "pins": ["top_edge"]}))
    sim.step(2)
    rng = np.random.default_rng(7)
    sim.set_velocities(rng.normal(size=(sim.num_particles, 3)).astype(np.float32))
    assert [float(x).hex() for x in sim.energy()] == runs[0]["random_velocities"]


def test_energy_is_finite_for_huge_finite_velocities():
    # 1e20 m/s squared is 1e40, past float32's 3.4e38: the square is taken in float64.
    sim = Simulation(small_scene())
    v = np.full((sim.num_particles, 3), 1e20, np.float32)
    sim.set_velocities(v)
    e = sim.energy()
    moving = ~sim.pinned
    expected = 0.5 * float(sim.masses[moving].astype(np.float64).sum()) * 3 * float(v[0, 0]) ** 2
    assert math.isfinite(e.kinetic) and math.isfinite(e.total)
    assert e.kinetic == pytest.approx(expected, rel=1e-12)
    biggest = np.float32(3.4e38)
    sim.set_velocities(np.full((sim.num_particles, 3), biggest, np.float32))
    assert math.isfinite(sim.energy().kinetic)
