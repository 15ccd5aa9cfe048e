"""What self-collision costs per 1/60 s frame, against the same frames without it, at 32^2 to
256^2 particles, for the scenes as they ship.

    PYTHONPATH=python python benches/self_collision.py          # quick: 32-128, 9 min at load 3-4
    PYTHONPATH=python python benches/self_collision.py --full   # adds 256 and 1 ms at 64

Run it with ``PYTHONPATH`` pointing at another build (``--no-write``) to compare two builds in
one session; stages and counters a build does not report print as 0.

Cases, each a 1 m cloth with ``thickness`` 3 mm (at most 0.4 of the grid spacing, so that a
flat cloth's own neighbours are not in contact at rest: 1.57 mm at 256 x 256):

- ``twist``: the built-in scene (implicit Euler, 4 steps a frame, ``solve_stiffness`` 300)
  turned by its driver (``rustcloth.drivers.TwistDriver``, half a turn per second each edge in
  opposite directions), timed from 2.0 s in, when it is wound onto itself in heavy contact;
- ``pile``: the built-in scene (implicit Euler, 2 steps a frame, ``solve_stiffness`` 30),
  lowered onto the floor on its sinking ball, timed from 1.0 s in, folded on itself;
- ``quiet``: the twist scene left at rest, where nothing is close: what the pass costs when it
  finds no pair;
- ``twist50``: newton's ``example_cloth_twist`` as ``benches/peers/impl_rustcloth_twist.py``
  sets it up (50 x 50, 1.5 m x 1 m, implicit Euler), timed from 2.0 s in, at 2 steps a frame
  with ``solve_stiffness`` 30 (the setting docs/contact.md recommends) and at newton's
  10 steps a frame without the in-solve term (the peer comparison's setting).

"before": the same cases at the settings every scene had until they moved to display-frame
steps (``scene()``: symplectic Euler at 1 ms steps, no in-solve term), timed over the same
simulated time, so that their frame is 16.7 steps.

Each case steps with the pass to its start, keeps that state, times ``--frames`` frames with
the pass, then restores the state, turns ``self_collision`` off and times the same frames
without it: one process, the same frames. Times are the wall time (``time.perf_counter``) and
the process's CPU time (``time.process_time``, every thread's) of ``Simulation.step`` alone (the
driver's Python not counted), per frame. The end state with the pass is checked for crossings
by the independent checker (``benches/peers/tri_check.py``). Writes the table into the generated
section of docs/contact.md and the plot to docs/contact.png.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
import tri_check  # noqa: E402
from generated import write_between_markers  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent / "docs"
OUT = Path(__file__).resolve().parent.parent / "out"
SCRIPT = "benches/self_collision.py"
THICKNESS = 0.003
FRAME = 1.0 / 60.0


def thickness(base: rustcloth.Scene, n: int) -> float:
    """The scene's contact thickness, at most 0.4 of the grid spacing of an ``n x n`` cloth."""
    return min(THICKNESS, 0.4 * base.cloth["size"][0] / (n - 1))


def scene(name: str, n: int, contact: bool) -> rustcloth.Scene:
    """The built-in scene at ``n x n`` as these tables measured it until the scenes moved to
    display-frame steps: symplectic Euler at 1 ms steps (the pile in two substeps, its springs
    damped 0.01 N s/m), no contact term in a solve (``benches/self_collision_cpu.py`` and the
    "before" runs here)."""
    base = rustcloth.load_scene(name)
    changes: dict[str, object] = {
        "cloth": {"nx": n, "ny": n, "damping": 0.01},
        "integrator": "symplectic_euler",
        "dt": 0.001,
        "substeps": 2 if name == "pile" else 1,
    }
    changes["self_collision"] = (
        {**base.self_collision, "thickness": thickness(base, n), "solve_stiffness": 0.0}
        if contact else None
    )
    return base.replace(**changes)


def shipped(name: str, n: int) -> rustcloth.Scene:
    """The built-in scene at ``n x n`` as it ships (its integrator, step and in-solve term),
    with the pass's ``thickness`` limited as ``thickness()`` says."""
    base = rustcloth.load_scene(name)
    return base.replace(cloth={"nx": n, "ny": n},
                        self_collision={**base.self_collision, "thickness": thickness(base, n)})


def twist50(steps_per_frame: int, solve_stiffness: float) -> rustcloth.Scene:
    """newton's 50 x 50 twist as the peer comparison sets it up."""
    import impl_rustcloth_twist as peer

    return peer.scene("implicit_euler", (1000.0, 250.0, 10.0), steps_per_frame, solve_stiffness)


def twist50_driver(sim: rustcloth.Simulation) -> TwistDriver:
    import impl_rustcloth_twist as peer

    return TwistDriver(sim, turns=peer.RATE_TURNS * peer.END, seconds=peer.END)


# case: (scene name, driven, start of the timed window in s)
CASES = {
    "twist": ("twist", True, 2.0),
    "pile": ("pile", False, 1.0),
    "quiet": ("twist", False, 0.1),
}
# twist50's settings: label -> (steps a frame, solve_stiffness)
TWIST50 = {"2 steps, K 30": (2, 30.0), "10 steps, K 0": (10, 0.0)}

STAGES = ("search", "repulsion", "cap", "redo")


def per_substep(before: dict[str, float], after: dict[str, float]) -> dict[str, float]:
    """The pass's counters and stage times per substep between two ``self_collision_stats()``
    (times in ms)."""
    substeps = max(after.get("substeps", 0) - before.get("substeps", 0), 1)

    def delta(key: str) -> float:
        return (after.get(key, 0.0) - before.get(key, 0.0)) / substeps

    out = {key: delta(key) for key in ("pairs", "contacts", "swept_substeps", "redone",
                                          "boxes_tested", "candidates")}
    for stage in STAGES:
        out[stage] = 1e3 * delta(f"{stage}_seconds")
    return out


def timed(sim: rustcloth.Simulation, driver: TwistDriver | None, frames: int) -> dict[str, float]:
    """Steps ``sim`` over ``frames`` 1/60 s frames of simulated time; returns the wall and CPU
    ms per frame of its steps, and (with the pass) the pass's counters per substep and its
    stages in ms per frame, with the in-solve search apart (the pass's profiled time less its
    stages)."""
    steps = round(frames * FRAME / sim.dt)
    stats0 = dict(sim.self_collision_stats() or {})
    prof0 = sim.profile()
    t0 = sim.time
    wall = cpu = 0.0
    for _ in range(steps):
        if driver is not None:
            driver.before_step(sim)
        w0, c0 = time.perf_counter(), time.process_time()
        sim.step()
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
    out = {"wall": 1e3 * wall / frames, "cpu": 1e3 * cpu / frames, "from": t0, "to": sim.time}
    stats1 = sim.self_collision_stats()
    if stats1 is None:
        return out
    split = per_substep(stats0, dict(stats1))
    substeps_per_frame = (stats1.get("substeps", 0) - stats0.get("substeps", 0)) / frames
    for stage in STAGES:
        split[stage] *= substeps_per_frame
    prof1 = sim.profile()
    pass_ms = 1e3 * (prof1.passes["self_collision"].seconds
                     - prof0.passes["self_collision"].seconds) / frames
    split["in_solve"] = max(pass_ms - sum(split[stage] for stage in STAGES), 0.0)
    return {**out, **split}


def measure(s: rustcloth.Scene, driven: Callable[[rustcloth.Simulation], TwistDriver] | None,
            start: float, frames: int) -> dict[str, float]:
    """The frames from ``start`` s with the pass, then the same frames from the same state
    without it; the crossings of the end state with the pass."""
    sim = rustcloth.Simulation(s)
    driver = driven(sim) if driven is not None else None
    while sim.time < start - 0.5 * sim.dt:
        if driver is not None:
            driver.before_step(sim)
        sim.step()
    state = sim.get_state()
    with_pass = timed(sim, driver, frames)
    crossings = tri_check.count(sim.positions.astype(np.float64), sim.triangles)
    without = rustcloth.Simulation.from_state(state)
    without.self_collision = None
    plain = timed(without, driver, frames)
    return {**with_pass, "crossings": crossings, "without_wall": plain["wall"],
            "without_cpu": plain["cpu"], "without_from": plain["from"],
            "without_to": plain["to"], "ratio_wall": with_pass["wall"] / plain["wall"],
            "ratio_cpu": with_pass["cpu"] / plain["cpu"]}


def steps_label(s: rustcloth.Scene) -> str:
    per_frame = FRAME / s.dt
    if s.integrator == "implicit_euler":
        return (f"implicit, {per_frame:.0f} a frame, "
                f"K {(s.self_collision or {}).get('solve_stiffness', 0.0):g}")
    return f"symplectic, 1 ms x {s.substeps}"


def row(case: str, cloth: str, settings: str, r: dict[str, float]) -> str:
    stages = " | ".join(f"{r.get(k, 0.0):.1f}" for k in ("in_solve", *STAGES))
    return (
        f"| {case} | {cloth} | {settings} | {r['wall']:.1f} | {r['cpu']:.1f} | "
        f"{r['without_wall']:.1f} | {r['without_cpu']:.1f} | {r['ratio_wall']:.1f} | "
        f"{r['ratio_cpu']:.1f} | {stages} | {r.get('boxes_tested', 0):.0f} | "
        f"{r.get('candidates', 0):.0f} | {r.get('pairs', 0):.0f} | {r.get('contacts', 0):.0f} | "
        f"{100 * r.get('swept_substeps', 0):.0f} % | {r['crossings']} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true",
                        help="sizes 32-256, and the 1 ms runs at 64 x 64 too (not run through: the "
                             "256 x 256 twist tore itself apart and ran out of memory before "
                             "cascades were retried, and has not been timed since; "
                             "docs/contact.md)")
    parser.add_argument("--sizes", type=int, nargs="+", default=None)
    parser.add_argument("--before-sizes", type=int, nargs="+", default=None,
                        help="sizes of the 1 ms runs of twist and pile (quiet: every size)")
    parser.add_argument("--cases", nargs="+", default=[*CASES, "twist50"],
                        choices=[*CASES, "twist50"])
    parser.add_argument("--frames", type=int, default=3, help="frames timed per case")
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--results", type=Path, default=OUT / "self_collision.json",
                        help="where the measurements go as JSON")
    parser.add_argument("--replot", action="store_true",
                        help="only draw docs/contact.png again from --results")
    args = parser.parse_args()
    if args.replot:
        saved = json.loads(args.results.read_text())
        plot({tuple(key.split("|")): value for key, value in saved.items()},
             DOCS / "contact.png")
        return
    sizes = args.sizes or ([32, 64, 128, 256] if args.full else [32, 64, 128])
    before_sizes = args.before_sizes or ([32, 64] if args.full else [32])
    load0 = os.getloadavg()[0]
    began = time.perf_counter()
    rows: list[str] = []
    results: dict[tuple[str, str], list[tuple[int, dict[str, float]]]] = {}

    def record(case: str, kind: str, n: int, cloth: str, settings: str,
               r: dict[str, float]) -> None:
        results.setdefault((case, kind), []).append((n, r))
        rows.append(row(case if kind == "now" else f"{case} (before)", cloth, settings, r))
        print(rows[-1], flush=True)

    for case in args.cases:
        if case == "twist50":
            for label, (per_frame, stiffness) in TWIST50.items():
                s = twist50(per_frame, stiffness)
                r = measure(s, twist50_driver, 2.0, args.frames)
                record(f"twist50, {label}", "now", 50, "50 x 50", steps_label(s), r)
            continue
        name, driven, start = CASES[case]
        driver = TwistDriver if driven else None
        for n in sizes:
            s = shipped(name, n)
            r = measure(s, driver, start, args.frames)
            record(case, "now", n, f"{n} x {n}", steps_label(s), r)
        for n in sizes if case == "quiet" else before_sizes:
            s = scene(name, n, True)
            r = measure(s, driver, start, args.frames)
            record(case, "before", n, f"{n} x {n}", steps_label(s), r)
    load1 = os.getloadavg()[0]
    args.results.parent.mkdir(parents=True, exist_ok=True)
    args.results.write_text(json.dumps({"|".join(k): v for k, v in results.items()}))
    minutes = (time.perf_counter() - began) / 60
    command = " ".join(["python", SCRIPT, *sys.argv[1:]])
    table = "\n".join([
        f"Measured on {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"{rustcloth._core.thread_count()} threads, load average {load0:.1f} at the start and "
        f"{load1:.1f} at the end, {minutes:.0f} minutes (`{command}`). Times per 1/60 s frame "
        f"over {args.frames} frames; the frames without the pass are the same frames from the "
        "same state with `self_collision` turned off. The stages (in-solve search: the pass's "
        "profiled time outside its own stages, the search at each step's start for the "
        "in-solve term; and the pass after the solve: search, repulsion, cap, redo) are wall "
        "ms per frame inside the step; boxes tested, candidates, pairs, contacts and swept "
        "per substep of the pass; crossings by `tri_check` at the end of the window with the "
        "pass. \"before\": the scene at symplectic Euler's 1 ms steps (its frame is 16.7 steps).",
        "",
        "| case | cloth | steps | frame with the pass, wall (ms) | CPU (ms) | without, wall "
        "(ms) | CPU (ms) | ratio, wall | ratio, CPU | in-solve search | search | repulsion "
        "| cap | redo | boxes tested | candidates | pairs looked at | contacts "
        "| substeps on the swept search | crossings |",
        "| --- | --- | --- |" + " ---: |" * 17,
        *rows,
    ])
    if args.no_write:
        return
    write_between_markers(DOCS / "contact.md", SCRIPT, table)
    plot(results, DOCS / "contact.png")


def plot(results: dict[tuple[str, str], list[tuple[int, dict[str, float]]]],
         path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), sharey=True)
    colours = {"twist": "C0", "pile": "C1", "quiet": "C2"}
    for ax, key, title in ((axes[0], "wall", "wall time, 2 threads"),
                           (axes[1], "cpu", "CPU time (every thread's)")):
        for (case, kind), points in results.items():
            if case not in colours or len(points) < 1:
                continue
            x = [n * n for n, _ in points]
            faint = {"alpha": 0.35, "lw": 1} if kind == "before" else {}
            label = case if kind == "now" else f"{case}, before (1 ms steps)"
            ax.plot(x, [r[key] for _, r in points], "o-", color=colours[case],
                    label=f"{label}, with the pass", **faint)
            ax.plot(x, [r[f"without_{key}"] for _, r in points], "s--", color=colours[case],
                    label=f"{label}, without", **faint)
        for (case, _), points in results.items():
            if case.startswith("twist50, 2"):
                ax.plot([2500], [points[0][1][key]], "k*", ms=10,
                        label="newton's twist 50 x 50, 2 steps a frame")
        ax.axhline(6.5, color="grey", ls=":", lw=1, label="6.5 ms (twist50 target)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("particles")
        ax.set_title(title)
    axes[0].set_ylabel("ms per 1/60 s frame")
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
    fig.suptitle("Self-collision: frame time against particle count")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
