"""The accuracy-versus-time study: what each integrator's accuracy costs.

``python -m rustcloth accuracy --out DIR`` writes ``DIR/accuracy.md`` (tables, the measured
orders, Pareto fronts and a reading generated from the numbers) and ``DIR/accuracy.png``
(``DIR`` is ``out/accuracy`` unless given; ``make accuracy`` writes the repository's
``docs``). It has two parts.

**Orders.** Every integrator over a ladder of time steps on smooth motion that exercises the
springs: a cloth swinging down from two pinned corners, and a free sheet kicked into
vibration (no gravity), each in two regimes: *damped* (spring damping and air drag, forces that
depend on velocity) and *conservative* (neither). The error is the RMS particle distance at a
fixed time from a float64 reference that is none of the integrators under test: the same model
in numpy (``study/model.py``), integrated by adaptive Dormand-Prince 5(4) to a local error of
1e-11. rustcloth steps in float32, so errors below a floor of about 1e-6 m are round-off; each
integrator's order is the slope of log error against log dt at the fine end of its clean
stretch above three times that floor.

**Stiff cloth at a display frame.** The draping scene of docs/stiff.md (k dt^2 / m of 280 at
32 x 32) at dt = 1/60 s: the explicit integrators with the substeps they need and more,
implicit Euler with each preconditioner and tolerance and with substeps, projective dynamics
with several iteration counts. Error against cost (wall-clock ms per simulated second), the
Pareto front, and which method is cheapest for each accuracy.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import INTEGRATORS, Scene, Simulation
from .._cli import Parser, guarded, progress, writable_folder
from .._extras import require
from ..errors import SimulationDiverged
from .model import Cloth

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
    cloth = Cloth(case_scene.to_dict(), sim.positions, sim.velocities, sim.masses, sim.pinned,
                  rest=rest)
    cloth.advance(seconds)
    return cloth.x


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


# ----- the report ----------------------------------------------------------------------------

def fmt_dt(dt: float) -> str:
    return f"1/{1 / dt:.0f}"


def fmt(x: float, spec: str = ".1e") -> str:
    return "—" if x is None or math.isnan(x) else format(x, spec)


def pareto(points: list[tuple[float, float, Run]]) -> list[Run]:
    """Runs not beaten by another run that is both faster and more accurate."""
    front, best = [], math.inf
    for _, error, run in sorted(points, key=lambda p: (p[0], p[1])):
        if error < best:
            front.append(run)
            best = error
    return front


def front_of(runs: list[Run]) -> list[Run]:
    return pareto([(r.wall_per_second, r.error, r) for r in runs
                   if r.stable and not math.isnan(r.error)])


def order_words(s: float) -> str:
    if math.isnan(s):
        return "no slope (too few points above the floor)"
    return f"slope {s:.2f}"


def reading(orders: list[OrderResult], stiff: list[Run], integrators: list[str]) -> list[str]:
    """Every sentence computed from the numbers."""
    text = []
    by_regime: dict[bool, dict[str, list[float]]] = {True: {}, False: {}}
    for res in orders:
        for integrator, s in res.slopes.items():
            if not math.isnan(s):
                by_regime[res.case.damped].setdefault(integrator, []).append(s)

    def span(values: list[float]) -> str:
        return (f"{min(values):.2f}" if len(values) == 1 or max(values) - min(values) < 0.005
                else f"{min(values):.2f} to {max(values):.2f}")

    for integrator in integrators:
        cons, damp = by_regime[False].get(integrator), by_regime[True].get(integrator)
        if not cons and not damp:
            continue
        parts = []
        if cons:
            parts.append(f"{span(cons)} without velocity-dependent forces")
        if damp:
            parts.append(f"{span(damp)} with spring damping and air drag")
        sentence = f"- **{integrator}**: measured order " + "; ".join(parts) + "."
        if integrator == "verlet" and cons and damp:
            if min(cons) >= 1.7 and max(damp) <= 1.4:
                sentence += (" Second order only where the forces depend on positions alone: "
                             "its velocity `(x_n - x_{n-1}) / h` lags half a step, and damping "
                             "and drag fed that velocity make it first order in positions.")
            elif min(cons) >= 1.7 and min(damp) >= 1.7:
                sentence += " Second order in both regimes at these steps."
            else:
                sentence += " Not cleanly second order in either regime at these steps."
        if integrator == "rk4" and (cons or damp):
            best = max((cons or []) + (damp or []))
            if best >= 3.5:
                sentence += " Fourth order where its errors stand above the float32 floor."
            else:
                sentence += (" Its finer steps fall to the float32 floor, which flattens the "
                             "fitted slope.")
        if integrator in ("implicit_euler", "projective_dynamics") and min(
                (cons or []) + (damp or [])) < 0.85:
            sentence += (" Below one where the errors have not left the regime in which "
                         "backward Euler damps the motion away (the stretched sheet's vibration "
                         "at these steps): first order only at finer steps.")
        text.append(sentence)
    for res in orders:
        front = front_of(res.runs)
        if front:
            names = sorted({r.integrator for r in front})
            text.append(f"- **{res.case.label}**: float32 floor {res.floor:.1e} m; the Pareto "
                        f"front is made of {', '.join(names)}.")
    if stiff:
        stable = [r for r in stiff if r.stable and not math.isnan(r.error)]
        front = front_of(stiff)
        if front:
            text.append(
                "- **Stiff cloth at 1/60 s**: the Pareto front (fastest way to each error) is "
                + ", ".join(f"{r.method}"
                            + (f" with {r.substeps} substeps" if r.substeps > 1 else "")
                            + f" ({r.error:.1e} m, {1e3 * r.wall_per_second:.0f} ms/s)"
                            for r in front) + ".")
        for limit in (1e-2, 1e-3, 1e-4, 1e-5):
            within = [r for r in stable if r.error <= limit]
            if not within:
                text.append(f"  - to an error of at most {limit:g} m: nothing run gets there.")
                continue
            cheapest = min(within, key=lambda r: r.wall_per_second)
            text.append(
                f"  - to an error of at most {limit:g} m the cheapest is {cheapest.method}"
                + (f" with {cheapest.substeps} substeps" if cheapest.substeps > 1 else "")
                + f" ({cheapest.error:.1e} m at {1e3 * cheapest.wall_per_second:.0f} ms per "
                  "simulated second).")
        implicit = [r for r in stable if r.integrator in ("implicit_euler", "projective_dynamics")
                    and r.substeps == 1]
        explicit = [r for r in stable if r.integrator in EXPLICIT]
        if implicit and explicit:
            best_i = min(implicit, key=lambda r: r.error)
            cheap_e = min(explicit, key=lambda r: r.wall_per_second)
            text.append(
                f"- At one step per frame the implicit solvers' best error is {best_i.error:.1e} m "
                f"({best_i.method}, {1e3 * best_i.wall_per_second:.0f} ms/s): backward Euler "
                f"damps the cloth's motion at 1/60 s. The cheapest explicit run, "
                f"{cheap_e.method} with {cheap_e.substeps} substeps, is "
                f"{best_i.error / cheap_e.error:.0f} times more accurate at "
                f"{cheap_e.wall_per_second / best_i.wall_per_second:.2f} times the cost"
                + (". On this cloth substepping an explicit method is the better choice; the "
                   "implicit solvers earn their place where no substep count is safe (stiffer "
                   "or lighter cloth, fast drags, a step that must never blow up)."
                   if cheap_e.error < best_i.error and
                   cheap_e.wall_per_second <= 2 * best_i.wall_per_second else "."))
        unstable = sorted({r.method for r in stiff if not r.stable})
        if unstable:
            text.append(f"- Unstable at 1/60 s with the substeps given: {', '.join(unstable)}.")
    return text


def write_report(orders: list[OrderResult], stiff: list[Run], stiff_ratio: float,
                 integrators: list[str], out: Path, elapsed: float) -> None:
    lines = [
        "# Accuracy versus time",
        "",
        "Generated by `python -m rustcloth accuracy --out docs` (`make accuracy`); do not edit "
        "by hand.",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; the "
        f"study took {elapsed:.0f} s. Wall times are from one run on a shared machine: compare "
        "them within a table, not across reports.",
        "",
        "**error**: RMS particle distance from a float64 reference (the same model in numpy, "
        "adaptive Dormand-Prince 5(4) to 1e-11, none of the integrators under test) at the "
        "case's time. **ms/s**: wall-clock milliseconds of stepping per simulated second. "
        "**—**: unstable (diverged or left a 10 m box). **floor**: the smallest error any "
        "integrator reached on the case, the float32 round-off level. **order**: the slope of log "
        "error against log dt between the two finest steps of the clean stretch of each curve: "
        "the longest run of consecutive steps whose errors stand above three times the floor, "
        "below 1 cm, and fall from step to step (round-off grows with the step count).",
        "",
        "## Measured orders",
        "",
        "| case | time | floor | " + " | ".join(integrators) + " |",
        "|---|---|---|" + "---|" * len(integrators),
    ]
    for res in orders:
        lines.append(f"| {res.case.label} | {res.case.time:g} s | {res.floor:.1e} | "
                     + " | ".join(fmt(res.slopes.get(i, math.nan), ".2f") for i in integrators)
                     + " |")
    lines += ["", "## Largest stable dt of the ladder", "",
              "| case | " + " | ".join(integrators) + " |",
              "|---|" + "---|" * len(integrators)]
    for res in orders:
        cells = []
        for integrator in integrators:
            stable = [r.dt for r in res.runs if r.integrator == integrator and r.stable]
            cells.append(fmt_dt(max(stable)) if stable else "none")
        lines.append(f"| {res.case.label} | " + " | ".join(cells) + " |")
    lines += ["", "## Pareto fronts (fastest way to each accuracy)", ""]
    for res in orders:
        lines.append(f"- **{res.case.label}**: " + ", ".join(
            f"{r.integrator} {fmt_dt(r.dt)} ({fmt(r.error)} m, {1e3 * r.wall_per_second:.0f} ms/s)"
            for r in front_of(res.runs)))
    for res in orders:
        lines += ["", f"## {res.case.label}", "",
                  "| integrator | dt | error [m] | ms/s | solver it/step |",
                  "|---|---|---|---|---|"]
        for r in res.runs:
            lines.append(f"| {r.integrator} | {fmt_dt(r.dt)} | {fmt(r.error)} | "
                         f"{fmt(1e3 * r.wall_per_second, '.1f')} | {fmt(r.iterations, '.1f')} |")
    if stiff:
        lines += ["", f"## Stiff cloth at 1/60 s ({stiff[0].case}, k dt^2 / m = "
                  f"{stiff_ratio:.0f})", "",
                  "| method | substeps | error [m] | ms/s | solver it/substep |",
                  "|---|---|---|---|---|"]
        for r in stiff:
            lines.append(f"| {r.method} | {r.substeps} | {fmt(r.error)} | "
                         f"{fmt(1e3 * r.wall_per_second, '.0f')} | {fmt(r.iterations, '.1f')} |")
    lines += ["", "## Reading", ""] + reading(orders, stiff, integrators)
    lines += ["", "![error against dt and against time](accuracy.png)", ""]
    out.write_text("\n".join(lines))


def plot(orders: list[OrderResult], stiff: list[Run], integrators: list[str],
         out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = len(orders) + (1 if stiff else 0)
    cols = min(3, panels)
    rows = math.ceil(panels / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.3 * cols, 3.5 * rows), squeeze=False)
    colors = dict(zip(integrators, plt.rcParams["axes.prop_cycle"].by_key()["color"],
                      strict=False))
    for ax, res in zip(axes.flat, orders, strict=False):
        for integrator in integrators:
            rs = [r for r in res.runs if r.integrator == integrator and r.stable]
            if rs:
                ax.loglog([r.dt for r in rs], [max(r.error, 1e-9) for r in rs], "o-", ms=3,
                          color=colors[integrator], label=integrator)
        ax.axhline(res.floor, color="grey", lw=0.8, ls=":")
        ax.set_title(res.case.label, fontsize=9)
        ax.set_xlabel("dt [s]", fontsize=8)
        ax.set_ylabel(f"RMS error at {res.case.time:g} s [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.2)
    if stiff:
        ax = list(axes.flat)[len(orders)]
        for integrator in integrators:
            rs = [r for r in stiff if r.integrator == integrator and r.stable]
            if rs:
                ax.loglog([r.wall_per_second for r in rs], [r.error for r in rs], "o", ms=4,
                          color=colors[integrator], label=integrator)
        front = front_of(stiff)
        ax.loglog([r.wall_per_second for r in front], [r.error for r in front], "k--", lw=1)
        ax.set_title(f"{stiff[0].case}: Pareto front", fontsize=9)
        ax.set_xlabel("wall time per simulated second [s]", fontsize=8)
        ax.set_ylabel("RMS error [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.2)
    for ax in list(axes.flat)[panels:]:
        ax.axis("off")
    handles = [matplotlib.lines.Line2D([], [], color=colors[i], marker="o", ms=3, label=i)
               for i in integrators]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(out, dpi=110)
    plt.close(fig)


#: Where the study writes when --out is not given: a folder of the working directory's ``out``,
#: never the docs of whatever checkout the user stands in (``make accuracy`` passes --out docs).
DEFAULT_OUT = Path("out/accuracy")


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``rustcloth accuracy`` (matplotlib is needed only to run the study)."""
    parser = Parser(prog="rustcloth accuracy", description=__doc__)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="folder for accuracy.md and accuracy.png, created if missing "
                             "(the repository's own report: --out docs)")
    parser.add_argument("--quick", action="store_true",
                        help="a tiny study (8x8, three rungs of the ladder) to check the pipeline")
    return parser


def main(argv: list[str] | None = None) -> int:
    """``rustcloth accuracy``; returns the exit status (2: a bad argument, an unwritable
    folder or no matplotlib, said in one line)."""
    return guarded("rustcloth accuracy", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    writable_folder(args.out)
    require("rustcloth accuracy", "matplotlib")
    if args.quick:
        cases = [Case("hanging", True, 8, 0.05), Case("stretched", False, 8, 0.05)]
        ladder, stiff_n, stiff_seconds = LADDER[:3], 8, 0.1
    else:
        # Smooth motion that loads the springs from the start: the hanging cloth pivots about
        # its corners long before it buckles (about 0.5 s), the kicked sheet vibrates at once.
        cases = [Case(kind, damped, 24, t) for kind, t in (("hanging", 0.25), ("stretched", 0.1))
                 for damped in (False, True)]
        ladder, stiff_n, stiff_seconds = LADDER, 32, 0.5
    integrators: list[str] = list(INTEGRATORS)
    start = time.perf_counter()
    # One tick per case of the order study and one for the stiff study; their lines above it.
    bar = progress(len(cases) + 1, "part")

    def log(line: str) -> None:
        bar.write(line)
        bar.update()

    try:
        with warnings.catch_warnings():
            # Unstable settings and capped solves are part of what the study measures.
            warnings.simplefilter("ignore", RuntimeWarning)
            orders = order_study(cases, integrators, ladder, log)
            stiff, ratio = stiff_study(stiff_n, stiff_seconds, args.quick, log)
    finally:
        bar.close()
    elapsed = time.perf_counter() - start
    write_report(orders, stiff, ratio, integrators, args.out / "accuracy.md", elapsed)
    plot(orders, stiff, integrators, args.out / "accuracy.png")
    print(f"wrote {args.out / 'accuracy.md'} and {args.out / 'accuracy.png'} in {elapsed:.0f} s")
    return 0
