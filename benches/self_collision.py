"""What self-collision costs per 1/60 s frame, against the same frames without it, at 32^2 to
256^2 particles, for the scenes as they ship.

    PYTHONPATH=python python benches/self_collision.py          # quick: 32, 64; --help: how long
    PYTHONPATH=python python benches/self_collision.py --full   # adds 128, 256 and 1 ms at 64

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

Each case steps with the pass to its start and keeps that state. Then, ``--rounds`` times, the
simulation with the pass and the one without it (``self_collision`` turned off) are both built
again from that state, each steps one untimed frame, and their next ``--frames`` frames are
timed alternated: a frame with the pass, a frame without, and so on (odd rounds start without).
Both columns so share a shared machine's drift (timed one after the other they would not); each
frame's best over the rounds is kept (the rounds repeat one trajectory bit for bit, which the
script checks), and a row is the mean of those bests. Times are the wall time
(``time.perf_counter``) and the process's CPU time (``time.process_time``, every thread's) of
``Simulation.step`` alone (the driver's Python not counted), per frame; each thread count of
``--threads`` (2 and 1) runs in its own process, the pool's size being fixed per process. The
end state with the pass is checked for crossings by the independent checker
(``benches/peers/tri_check.py``). Writes the table into the generated
section of docs/contact.md and the plot to docs/contact.png.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import rustcloth  # noqa: E402
import tri_check  # noqa: E402
from generated import write_between_markers  # noqa: E402
from run import machine_info  # noqa: E402
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

# Left out of every run: the 256 x 256 twist tears itself apart from frame 45 and its pass
# ran out of memory at 21.8 GB (docs/notes/contact.md, "the 256 x 256 twist").
LEFT_OUT = {("twist", 256)}

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


def frame(sim: rustcloth.Simulation, driver: TwistDriver | None) -> tuple[float, float]:
    """Steps ``sim`` over one 1/60 s frame of simulated time; returns the wall and CPU seconds
    of its steps (the driver's Python not counted)."""
    wall = cpu = 0.0
    for _ in range(round(FRAME / sim.dt)):
        if driver is not None:
            driver.before_step(sim)
        w0, c0 = time.perf_counter(), time.process_time()
        sim.step()
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
    return wall, cpu


def digest(sim: rustcloth.Simulation) -> str:
    """A hash of the positions and velocities, to check that the rounds repeat one trajectory."""
    return hashlib.sha256(sim.positions.tobytes() + sim.velocities.tobytes()).hexdigest()[:16]


def pass_split(sim: rustcloth.Simulation, stats0: dict[str, float], prof0: rustcloth.Profile,
               frames: int) -> dict[str, float]:
    """The pass's counters per substep and its stages in wall ms per frame since ``stats0`` and
    ``prof0``, with the in-solve search apart (the pass's profiled time less its stages)."""
    stats1 = dict(sim.self_collision_stats() or {})
    split = per_substep(stats0, stats1)
    substeps_per_frame = (stats1.get("substeps", 0) - stats0.get("substeps", 0)) / frames
    for stage in STAGES:
        split[stage] *= substeps_per_frame
    prof1 = sim.profile()
    pass_ms = 1e3 * (prof1.passes["self_collision"].seconds
                     - prof0.passes["self_collision"].seconds) / frames
    split["in_solve"] = max(pass_ms - sum(split[stage] for stage in STAGES), 0.0)
    return split


def alternated(state: dict[str, Any], driver: TwistDriver | None, frames: int,
               rounds: int) -> dict[str, Any]:
    """Times ``frames`` frames with the pass and the same frames without it, from ``state``,
    alternated frame by frame in one window, ``rounds`` times over.

    Each round builds both simulations again from ``state`` and steps each one untimed frame
    (the pass's lists and the solver's buffers filled as in a running simulation), then times
    a frame with the pass, a frame without, and so on; odd rounds time the frame without the
    pass first, so that neither side always runs right after the other. A shared machine's
    speed drifts over minutes: alternating puts both sides under the same drift, and the best
    of the rounds for each frame (the same work each round, the trajectory being bitwise
    repeatable) drops the frames another process slowed. Returns each side's wall and CPU
    seconds per frame (best over the rounds) and, from the first round, the simulated window,
    the pass's stats over its timed frames and the simulation with the pass (for the
    crossings)."""
    best: dict[bool, dict[str, list[float]]] = {
        side: {"wall": [math.inf] * frames, "cpu": [math.inf] * frames} for side in (True, False)}
    ends: dict[bool, set[str]] = {True: set(), False: set()}
    out: dict[str, Any] = {}
    for r in range(rounds):
        sims = {True: rustcloth.Simulation.from_state(state),
                False: rustcloth.Simulation.from_state(state)}
        sims[False].self_collision = None
        for sim in sims.values():
            frame(sim, driver)
        stats0 = dict(sims[True].self_collision_stats() or {})
        prof0 = sims[True].profile()
        t0 = sims[True].time
        order = (True, False) if r % 2 == 0 else (False, True)
        for f in range(frames):
            for side in order:
                wall, cpu = frame(sims[side], driver)
                best[side]["wall"][f] = min(best[side]["wall"][f], wall)
                best[side]["cpu"][f] = min(best[side]["cpu"][f], cpu)
        for side, sim in sims.items():
            ends[side].add(digest(sim))
        if r == 0:
            out = {"from": t0, "to": sims[True].time, "without_from": t0,
                   "without_to": sims[False].time,
                   "split": pass_split(sims[True], stats0, prof0, frames), "end": sims[True]}
    if len(ends[True]) != 1 or len(ends[False]) != 1:
        raise SystemExit("the rounds did not repeat one trajectory: their best is not fair")
    return {**out, "best": best}


def measure(s: rustcloth.Scene, driven: Callable[[rustcloth.Simulation], TwistDriver] | None,
            start: float, frames: int, rounds: int = 3) -> dict[str, float]:
    """Steps ``s`` with the pass to ``start`` s, then times the next frames with the pass and
    without it alternated (``alternated``): per frame the mean over ``frames`` frames of each
    frame's best of ``rounds``, wall and CPU ms; the crossings of the end state with the pass."""
    sim = rustcloth.Simulation(s)
    driver = driven(sim) if driven is not None else None
    while sim.time < start - 0.5 * sim.dt:
        if driver is not None:
            driver.before_step(sim)
        sim.step()
    runs = alternated(sim.get_state(), driver, frames, rounds)
    del sim
    best = runs["best"]

    def ms(side: bool, key: str) -> float:
        return 1e3 * float(np.mean(best[side][key]))

    end = runs["end"]
    crossings = tri_check.count(end.positions.astype(np.float64), end.triangles)
    r = {"wall": ms(True, "wall"), "cpu": ms(True, "cpu"), "without_wall": ms(False, "wall"),
         "without_cpu": ms(False, "cpu"), "from": runs["from"], "to": runs["to"],
         "without_from": runs["without_from"], "without_to": runs["without_to"],
         "crossings": crossings, "rounds": rounds, "threads": rustcloth._core.thread_count()}
    return {**r, **runs["split"], "ratio_wall": r["wall"] / r["without_wall"],
            "ratio_cpu": r["cpu"] / r["without_cpu"]}


def steps_label(s: rustcloth.Scene) -> str:
    per_frame = FRAME / s.dt
    if s.integrator == "implicit_euler":
        return (f"implicit, {per_frame:.0f} a frame, "
                f"K {(s.self_collision or {}).get('solve_stiffness', 0.0):g}")
    return f"symplectic, 1 ms x {s.substeps}"


def row(case: str, cloth: str, settings: str, r: dict[str, float]) -> str:
    stages = " | ".join(f"{r.get(k, 0.0):.1f}" for k in ("in_solve", *STAGES))
    return (
        f"| {case} | {cloth} | {settings} | {r['threads']} | {r['wall']:.1f} | {r['cpu']:.1f} | "
        f"{r['without_wall']:.1f} | {r['without_cpu']:.1f} | {r['ratio_wall']:.1f} | "
        f"{r['ratio_cpu']:.1f} | {stages} | {r.get('boxes_tested', 0):.0f} | "
        f"{r.get('candidates', 0):.0f} | {r.get('pairs', 0):.0f} | {r.get('contacts', 0):.0f} | "
        f"{100 * r.get('swept_substeps', 0):.0f} % | {r['crossings']} |"
    )


# One measured case: (case, "now" or "before", particles a side, cloth, steps, measurements).
Record = tuple[str, str, int, str, str, dict[str, float]]


def run_cases(args: argparse.Namespace) -> list[Record]:
    """Measures every case in this process, on its thread pool, printing each row."""
    sizes = args.sizes or ([32, 64, 128, 256] if args.full else [32, 64])
    before_sizes = args.before_sizes if args.before_sizes is not None else [32]
    records: list[Record] = []

    def record(*rec: Any) -> None:
        records.append(rec)
        case, kind, _, cloth, settings, r = rec
        print(row(case if kind == "now" else f"{case} (before)", cloth, settings, r), flush=True)

    for case in args.cases:
        if case == "twist50":
            for label, (per_frame, stiffness) in TWIST50.items():
                s = twist50(per_frame, stiffness)
                r = measure(s, twist50_driver, 2.0, args.frames, args.rounds)
                record(f"twist50, {label}", "now", 50, "50 x 50", steps_label(s), r)
            continue
        name, driven, start = CASES[case]
        driver = TwistDriver if driven else None
        for n in sizes:
            if (name, n) in LEFT_OUT:
                continue
            s = shipped(name, n)
            r = measure(s, driver, start, args.frames, args.rounds)
            record(case, "now", n, f"{n} x {n}", steps_label(s), r)
        for n in sizes if case == "quiet" else before_sizes:
            s = scene(name, n, True)
            r = measure(s, driver, start, args.frames, args.rounds)
            record(case, "before", n, f"{n} x {n}", steps_label(s), r)
    return records


def cpu() -> str:
    """The CPU's model name and ``family F model M`` (the name alone does not tell Xeons
    apart), as the peers' run reads them from /proc/cpuinfo."""
    m = machine_info()
    return f"{m['cpu']} (family {m['cpu_family']} model {m['cpu_model']})"


def command(argv: list[str]) -> str:
    """The command that measures what ``argv`` measured: without where the results went, and
    with ``--threads`` the thread count that ran it."""
    kept: list[str] = []
    dropping = False
    for arg in argv:
        if arg.startswith("--"):
            dropping = arg in ("--results", "--threads")
            if dropping or arg in ("--worker", "--no-write", "--reuse"):
                continue
        elif dropping:
            continue
        kept.append(arg)
    threads = os.environ.get("RAYON_NUM_THREADS")
    return " ".join(["python", SCRIPT, *kept, *(["--threads", threads] if threads else [])])


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="Run times measured on the 2-core Xeon (family 6 model 167) at load average "
               "8-11 (other jobs on it, each process getting about a quarter of a core): the "
               "quick default (32 and 64, the 50 x 50 twist, 3 frames, 3 rounds) 13 minutes on "
               "2 threads and 14 on 1 (about 4 times less on a free machine, by that quarter "
               "core: an estimate). --full adds 128 "
               "and 256: not run through here (the 128 x 128 twist's 2 s to its window alone "
               "took about 5 minutes a thread count on a free machine, docs/notes/contact.md; "
               "at load 7-12 about 25).")
    parser.add_argument("--full", action="store_true",
                        help="sizes 32-256 (the 256 x 256 twist left out: it tears itself apart "
                             "and runs out of memory, docs/notes/contact.md, \"the 256 x 256 "
                             "twist\"), and the 1 ms runs at 64 x 64 too")
    parser.add_argument("--sizes", type=int, nargs="+", default=None)
    parser.add_argument("--before-sizes", type=int, nargs="*", default=None,
                        help="sizes of the 1 ms runs of twist and pile (quiet: every size); "
                             "default 32 (--full: 32 64)")
    parser.add_argument("--cases", nargs="+", default=[*CASES, "twist50"],
                        choices=[*CASES, "twist50"])
    parser.add_argument("--frames", type=int, default=3, help="frames timed per case")
    parser.add_argument("--rounds", type=int, default=3,
                        help="times each case's frames are run again from the same state; each "
                             "frame's best is kept (more rounds: steadier on a busy machine, "
                             "each round costs its frames twice over)")
    parser.add_argument("--threads", type=int, nargs="+", default=[2, 1],
                        help="thread counts, each run in its own process (the pool's size is "
                             "fixed per process), the first drawn in the plot")
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--results", type=Path, default=OUT / "self_collision.json",
                        help="where the measurements go as JSON")
    parser.add_argument("--replot", action="store_true",
                        help="only draw docs/contact.png again from --results")
    parser.add_argument("--reuse", action="store_true",
                        help="take a thread count's rows from its saved file (--results with "
                             "the thread count before the suffix) where there is one, instead "
                             "of measuring them again")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.full and args.before_sizes is None:
        args.before_sizes = [32, 64]
    if args.worker:
        load0, began = os.getloadavg(), time.perf_counter()
        records = run_cases(args)
        args.results.write_text(json.dumps({
            "records": records, "load_start": load0, "load_end": os.getloadavg(),
            "minutes": (time.perf_counter() - began) / 60,
            "command": command(sys.argv[1:]),
            "measured": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}))
        return
    if args.replot:
        plot([tuple(rec) for rec in json.loads(args.results.read_text())
              if rec[5]["threads"] == args.threads[0]], DOCS / "contact.png")
        return
    records: list[Record] = []
    loads: list[str] = []
    args.results.parent.mkdir(parents=True, exist_ok=True)
    for threads in args.threads:
        part = args.results.with_suffix(f".{threads}.json")
        if not (args.reuse and part.exists()):
            forwarded = [a for a in sys.argv[1:] if a not in ("--no-write", "--reuse")]
            subprocess.run([sys.executable, __file__, *forwarded, "--worker", "--results",
                            str(part)],
                           env={**os.environ, "RAYON_NUM_THREADS": str(threads)}, check=True)
        saved = json.loads(part.read_text())
        records += [tuple(rec) for rec in saved["records"]]
        loads.append(f"{threads} thread{'s' if threads > 1 else ''} (finished {saved['measured']}, "
                     f"`{saved['command']}`, {saved['minutes']:.0f} minutes): "
                     f"{' / '.join(f'{x:.1f}' for x in saved['load_start'])} at the start, "
                     f"{' / '.join(f'{x:.1f}' for x in saved['load_end'])} at the end")
    args.results.write_text(json.dumps(records))
    rows = [row(case if kind == "now" else f"{case} (before)", cloth, settings, r)
            for case, kind, _, cloth, settings, r in records]
    table = "\n".join([
        f"Measured on {cpu()}, {os.cpu_count()} cores shared with "
        f"other work; load average (1 / 5 / 15 min) {'; '.join(loads)}. Times per "
        f"1/60 s frame: the mean over {args.frames} frames of each frame's best of "
        f"{args.rounds} rounds. Each round builds the simulation with the pass and the one "
        "without it (`self_collision` turned off) from the same saved state, steps each one "
        "untimed frame, then times a frame with the pass, a frame without, and so on, "
        "alternated, so both columns share the machine's drift. Wall time and the process's "
        "CPU time (every thread's), each thread count in its own process; at a load average "
        "above the cores a frame's wall time includes waiting for a core, which a long frame "
        "(with the pass) pays more of than a short one, so the CPU ratio is the fairer one "
        "then. The stages "
        "(in-solve search: the pass's profiled time outside its own stages, the search at each "
        "step's start for the in-solve term; and the pass after the solve: search, repulsion, "
        "cap, redo) are wall ms per frame inside the step of the first round (not a best: under "
        "load they can add up past the frame's best wall time); boxes tested, "
        "candidates, pairs, contacts and swept per substep of the pass; crossings by "
        "`tri_check` at the end of the first round with the pass. \"before\": the scene at "
        "symplectic Euler's 1 ms steps (its frame is 16.7 steps)."
        + (" The 256 x 256 twist is left out: it tears itself apart and runs out of memory "
           "(docs/notes/contact.md)." if 256 in (args.sizes or ([256] if args.full else []))
           else ""),
        "",
        "| case | cloth | steps | threads | frame with the pass, wall (ms) | CPU (ms) | without, "
        "wall (ms) | CPU (ms) | ratio, wall | ratio, CPU | in-solve search | search | repulsion "
        "| cap | redo | boxes tested | candidates | pairs looked at | contacts "
        "| substeps on the swept search | crossings |",
        "| --- | --- | --- |" + " ---: |" * 18,
        *rows,
    ])
    if args.no_write:
        print(table)
        return
    write_between_markers(DOCS / "contact.md", SCRIPT, table)
    plot([rec for rec in records if rec[5]["threads"] == args.threads[0]], DOCS / "contact.png")


def plot(records: list[Record], path: Path) -> None:
    """Frame time against particle count, with and without the pass, from ``records`` of one
    thread count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results: dict[tuple[str, str], list[tuple[int, dict[str, float]]]] = {}
    for case, kind, n, _, _, r in records:
        results.setdefault((case, kind), []).append((n, r))
    threads = records[0][5]["threads"] if records else 0
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), sharey=True)
    colours = {"twist": "C0", "pile": "C1", "quiet": "C2"}
    for ax, key, title in ((axes[0], "wall", f"wall time, {threads} threads"),
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
