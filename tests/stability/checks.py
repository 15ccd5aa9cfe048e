"""The stability suite's one checker: every step of every case keeps the state finite and
bounded, keeps particles out of the colliders and pinned particles bitwise put; a step that
fails is the reported, rolled-back ``SimulationDiverged``, never a NaN in the state."""

from __future__ import annotations

import numpy as np
import rustcloth
from conftest import state_digest

EXPLICIT = ["explicit_euler", "symplectic_euler", "verlet", "rk4"]
IMPLICIT = ["implicit_euler", "projective_dynamics"]
ALL = [*EXPLICIT, *IMPLICIT]


def check_state(sim: rustcloth.Simulation, bound: float, dragged: set[int] = frozenset(),
                pins: dict[int, bytes] | None = None) -> None:
    """Asserts the invariants on the current state. ``pins``: pinned particle -> its bits."""
    x, v = sim.positions, sim.velocities
    assert np.isfinite(x).all() and np.isfinite(v).all(), "non-finite state"
    assert (np.abs(x) < bound).all(), f"a particle left the {bound} m box: {np.abs(x).max()}"
    moving = ~sim.pinned & sim.alive
    scene = sim.scene
    if scene.floor is not None:
        floor = scene.floor
        assert (x[moving, 1] >= floor["height"] + floor["thickness"] - 1e-6).all(), \
            "a particle is below the floor"
    for sphere in scene.spheres:
        r = sphere["radius"] + sphere["thickness"]
        d = np.linalg.norm(x[moving] - np.asarray(sphere["center"], np.float32), axis=1)
        assert (d >= r * (1 - 1e-5)).all(), f"a particle is inside a sphere ({d.min()} < {r})"
    for p, bits in (pins or {}).items():
        if p not in dragged:
            assert x[p].tobytes() == bits, f"pinned particle {p} moved"


def pinned_bits(sim: rustcloth.Simulation) -> dict[int, bytes]:
    x = sim.positions
    return {int(p): x[p].tobytes() for p in np.flatnonzero(sim.pinned)}


def run_checked(sim: rustcloth.Simulation, steps: int, bound: float = 100.0,
                dragged: set[int] = frozenset()) -> rustcloth.SimulationDiverged | None:
    """Steps one at a time checking every step. Returns None, or the divergence after checking
    it rolled the state back to the one before the failed step."""
    pins = pinned_bits(sim)
    history = {sim.steps: state_digest(sim)}
    check_state(sim, bound, dragged, pins)
    for _ in range(steps):
        try:
            sim.step(1)
        except rustcloth.SimulationDiverged as e:
            assert sim.steps == e.step - 1, (sim.steps, e.step)
            assert state_digest(sim) == history[e.step - 1], "the failed step was not rolled back"
            assert e.reason in ("non_finite", "overstretched")
            check_state(sim, bound, dragged, pins)
            return e
        history[sim.steps] = state_digest(sim)
        check_state(sim, bound, dragged, pins)
    return None


def hanging(n: int = 12, **changes) -> rustcloth.Scene:
    """An n x n cloth in the xy plane hanging from its top corners, with ``changes``."""
    scene = rustcloth.Scene(
        cloth={"nx": n, "ny": n, "plane": "xy", "center": [0, 1.5, 0], "pins": ["top_corners"]},
    )
    return scene.replace(**changes)


def stable(scene: rustcloth.Scene, implicit_dt: float = 1 / 60) -> rustcloth.Scene:
    """The scene at half its integrator's stable dt (at most its own dt); the implicit solvers
    at ``implicit_dt``."""
    if scene.integrator in IMPLICIT:
        return scene.replace(dt=implicit_dt)
    limit = scene.stability_report(warn=False).limit
    return scene if limit is None else scene.replace(dt=min(scene.dt, 0.5 * limit))
