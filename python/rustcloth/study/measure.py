"""The accuracy study's measurements: its scenes (:class:`Case`, the stiff drape), runs of the
solver timed and compared with the float64 reference, and the orders fitted to them. What is
written from them is :mod:`rustcloth.study.report`."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import Scene, Simulation
from ..errors import SimulationDiverged
from ..reference import ReferenceCloth

Start = Callable[[Simulation], None]
"""Puts a fresh simulation into a case's starting state (a kick, a swing)."""
Log = Callable[[str], None]

LADDER = [1 / (240 * 2**k) for k in range(7)]  # 1/240 s down to 1/15360 s
EXPLICIT = ["explicit_euler", "symplectic_euler", "verlet", "rk4"]


@dataclass(frozen=True)
class Case:
    """A scene of the order study."""

    kind: str
    """"hanging": pinned at two corners, swinging down from horizontal; "stretched": a free
    sheet with no gravity released from 5 % stretch in its plane, which sets every structural
    and shear spring vibrating at once."""
    damped: bool
    n: int
    time: float
    """The time (s) at which the error is taken."""

    @property
    def label(self) -> str:
        return f"{self.kind} {'damped' if self.damped else 'conservative'} {self.n}x{self.n}"

    def scene(self, integrator: str, dt: float, **changes: Any) -> Scene:
        base: dict[str, Any] = {
            "integrator": integrator,
            "dt": dt,
            "substeps": 1,
            "gravity": [0.0, -9.81, 0.0] if self.kind == "hanging" else [0.0, 0.0, 0.0],
            "air_drag": 2e-4 if self.damped else 0.0,
            # The implicit solvers converged, so that what is measured is the time stepping.
            "cg_tolerance": 1e-6,
            "cg_max_iterations": 2000,
            # (Projective dynamics' relative gradient bottoms out near 1e-4 in float32 at the
            # finest steps, where its first iterate is already close.)
            "pd_iterations": 60,
            "pd_tolerance": 1e-4,
            "cloth": {
                "nx": self.n,
                "ny": self.n,
                "size": [1.0, 1.0],
                "center": [0.0, 1.5, 0.0],
                "plane": "xz",
                "mass": 1.0,
                "k_structural": 800.0,
                "k_shear": 200.0,
                "k_bend": 20.0,
                "damping": 0.02 if self.damped else 0.0,
                "pins": ["top_corners"] if self.kind == "hanging" else [],
            },
        }
        return Scene.from_dict({**base, **changes})

    def start(self, sim: Simulation) -> None:
        if self.kind == "stretched":
            x = sim.positions.astype(np.float64)
            center = np.array([0.0, 1.5, 0.0])
            sim.set_positions(center + (x - center) * np.array([1.05, 1.0, 1.05]))


@dataclass
class Run:
    case: str
    integrator: str
    dt: float
    stable: bool
    substeps: int = 1
    variant: str = ""
    """What else distinguishes the run (a preconditioner and tolerance, an iteration count)."""
    wall_per_second: float = math.nan
    error: float = math.nan
    """RMS position error in m at the case's time."""
    iterations: float = math.nan

    @property
    def method(self) -> str:
        return self.integrator + (f" ({self.variant})" if self.variant else "")


def simulate(scene: Scene, seconds: float,
             start: Start | None = None) -> tuple[Simulation | None, float]:
    """Runs ``seconds``: the simulation (None if it diverged or left a 10 m box) and its
    stepping wall time per simulated second."""
    sim = Simulation(scene)
    if start:
        start(sim)
    x0 = sim.positions
    steps = round(seconds / scene.dt)
    try:
        for chunk in np.array_split(np.arange(steps), 10):
            sim.step(len(chunk))
            if not np.abs(sim.positions - x0).max() < 10.0:
                return None, math.nan
    except SimulationDiverged:
        return None, math.nan
    return sim, sim.profile().total_seconds / seconds


def reference(case_scene: Scene, seconds: float, start: Start | None = None) -> np.ndarray:
    """The float64 reference positions after ``seconds``."""
    sim = Simulation(case_scene)
    rest = sim.positions
    if start:
        start(sim)
    cloth = ReferenceCloth(case_scene.to_dict(), positions=sim.positions,
                           velocities=sim.velocities, masses=sim.masses, rest=rest)
    cloth.integrate(seconds)
    return cloth.positions


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((np.asarray(a, np.float64) - b) ** 2).sum(axis=1).mean()))


def measure(run: Run, scene: Scene, seconds: float, ref: np.ndarray,
            start: Start | None = None) -> Run:
    sim, wall = simulate(scene, seconds, start)
    if sim is not None:
        run.stable = True
        run.wall_per_second = wall
        run.error = rms(sim.positions, ref)
        solver = sim.solver_stats()
        if solver:
            run.iterations = solver["iterations"] / max(solver["solves"], 1)
    else:
        run.stable = False
    return run


# ----- part 1: orders ------------------------------------------------------------------------

@dataclass
class OrderResult:
    case: Case
    runs: list[Run]
    floor: float
    slopes: dict[str, float] = field(default_factory=dict)


def slope(runs: list[Run], floor: float) -> float:
    """The measured order: the slope of log error against log dt between the two finest steps
    of the curve's clean stretch, the longest run of consecutive steps (coarse to fine) whose
    errors stand above three times the round-off floor, below a centimetre (beyond that a step
    on the edge of stability, or a step so large the motion is damped away, is in no
    asymptotic regime) and fall by at least a fifth from step to step (round-off grows with the
    step count, so at the finest steps the error can rise again). NaN with fewer than two."""
    best: list[tuple[float, float]] = []
    current: list[tuple[float, float]] = []
    for run in sorted(runs, key=lambda r: -r.dt):
        valid = run.stable and 3 * floor < run.error < 1e-2
        if valid and current and run.error < current[-1][1] / 1.2:
            current.append((run.dt, run.error))
        else:
            if len(current) >= len(best):
                best = current
            current = [(run.dt, run.error)] if valid else []
    if len(current) >= len(best):
        best = current
    if len(best) < 2:
        return math.nan
    (dt1, e1), (dt2, e2) = best[-2], best[-1]
    return math.log(e1 / e2) / math.log(dt1 / dt2)


def order_study(cases: list[Case], integrators: list[str], ladder: list[float],
                log: Log = print) -> list[OrderResult]:
    results = []
    for case in cases:
        t0 = time.perf_counter()
        ref = reference(case.scene("rk4", ladder[-1]), case.time, case.start)
        runs = []
        for integrator in integrators:
            for dt in ladder:
                runs.append(measure(Run(case.label, integrator, dt, False),
                                    case.scene(integrator, dt), case.time, ref, case.start))
        # The round-off floor: the smallest error any run reached (RK4 at the finest steps has
        # no truncation error to speak of), and no less than float32's 1e-7 relative.
        floor = max(min((r.error for r in runs if r.stable), default=1e-7), 1e-7)
        result = OrderResult(case, runs, floor)
        for integrator in integrators:
            result.slopes[integrator] = slope([r for r in runs if r.integrator == integrator],
                                              floor)
        log(f"{case.label}: floor {floor:.1e} m, slopes "
            + ", ".join(f"{i} {s:.2f}" for i, s in result.slopes.items())
            + f" ({time.perf_counter() - t0:.0f} s)")
        results.append(result)
    return results


# ----- part 2: stiff cloth at 1/60 s ---------------------------------------------------------

STIFF_DT = 1 / 60


def stiff_scene(n: int, integrator: str, substeps: int = 1, **solver: Any) -> Scene:
    """The docs/stiff.md drape at n x n."""
    return Scene.from_dict({
        "integrator": integrator, "dt": STIFF_DT, "substeps": substeps, "air_drag": 0.0,
        **solver,
        "cloth": {"nx": n, "ny": n, "size": [1.0, 1.0], "center": [0.0, 1.5, 0.0],
                  "plane": "xz", "particle_mass": 0.5 / n**2, "k_structural": 500.0,
                  "k_shear": 125.0, "k_bend": 25.0, "damping": 0.01,
                  "pins": ["top_corners"]},
    })


def stiff_study(n: int, seconds: float, quick: bool, log: Log = print) -> tuple[list[Run], float]:
    """Every method at 1/60 s on the stiff drape; also returns k_structural dt^2 / m."""
    t0 = time.perf_counter()
    ref = reference(stiff_scene(n, "rk4"), seconds)
    label = f"stiff drape {n}x{n} at 1/60 s"
    runs: list[Run] = []
    report = stiff_scene(n, "symplectic_euler").stability_report(warn=False)
    for integrator in EXPLICIT:
        needed = report.substeps_needed(integrator) or 64
        for factor in (1, 2) if quick else (1, 2, 4, 8):
            s = needed * factor
            runs.append(measure(Run(label, integrator, STIFF_DT, False, substeps=s),
                                stiff_scene(n, integrator, s), seconds, ref))
    for preconditioner in ("jacobi", "block_jacobi", "multigrid"):
        for tol in (1e-2, 1e-4) if quick else (1e-2, 1e-4, 1e-6):
            runs.append(measure(
                Run(label, "implicit_euler", STIFF_DT, False,
                    variant=f"{preconditioner}, {tol:.0e}"),
                stiff_scene(n, "implicit_euler", preconditioner=preconditioner,
                            cg_tolerance=tol, cg_max_iterations=5000), seconds, ref))
    for s in (2, 4) if quick else (2, 4, 8):
        runs.append(measure(
            Run(label, "implicit_euler", STIFF_DT, False, substeps=s,
                variant="multigrid, 1e-4"),
            stiff_scene(n, "implicit_euler", s, preconditioner="multigrid"), seconds, ref))
    for k in (5, 20) if quick else (5, 10, 20, 40):
        for s in (1,) if quick else (1, 4):
            runs.append(measure(
                Run(label, "projective_dynamics", STIFF_DT, False, substeps=s,
                    variant=f"{k} iterations"),
                stiff_scene(n, "projective_dynamics", s, pd_iterations=k), seconds, ref))
    scene = stiff_scene(n, "implicit_euler")
    ratio = scene.cloth["k_structural"] * STIFF_DT**2 / scene.cloth["particle_mass"]
    log(f"{label}: {len(runs)} runs ({time.perf_counter() - t0:.0f} s)")
    return runs, ratio
