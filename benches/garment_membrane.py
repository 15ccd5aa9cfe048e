"""The built-in ``shirt`` under each mesh membrane, and with stiffer seams.

For each configuration (the shirt's ``cloth.mesh.membrane``, ``springs`` or ``triangle``, and
its seams' ``stiffness`` in N/m per sewn pair), sews the shirt on the mannequin with 240 frames
of ``advance(1 / 60)`` at the scene's own steps and prints the CPU time per frame
(``time.process_time()``; run it with ``RAYON_NUM_THREADS=1`` for one thread's), the largest
seam gap (``Simulation.seam_gap()``) at 2 s and 4 s and the kinetic energy at 4 s. The
configurations take turns ``--runs`` times, so a load on the shared machine falls on all alike.

    RAYON_NUM_THREADS=1 PYTHONPATH=python python benches/garment_membrane.py

writes its table into docs/garments.md between the markers (``--no-write`` prints it only);
about half a minute a run.
"""

from __future__ import annotations

import argparse
import platform
import time
import warnings
from pathlib import Path

import rustcloth
from generated import write_between_markers

FPS = 60.0
FRAMES = 240
DOC = Path(__file__).resolve().parent.parent / "docs" / "garments.md"


def shirt(membrane: str, seam_stiffness: float | None) -> rustcloth.Scene:
    """The built-in shirt with its compiled mesh's membrane and seam stiffness replaced; a step
    the stiffer seams make unstable is shortened to 0.9 of the estimated limit (at the scene's
    substeps), so the comparison includes what the stiffness costs in steps."""
    data = rustcloth.load_scene("shirt").to_dict()
    mesh = data["cloth"]["mesh"]
    mesh["membrane"] = membrane
    if seam_stiffness is not None:
        mesh["seams"]["stiffness"] = seam_stiffness
    scene = rustcloth.Scene.from_dict(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rustcloth.StabilityWarning)
        limit = rustcloth.Simulation(scene).stable_dt()
    if limit is not None and scene.dt > limit:
        scene = scene.replace(dt=0.9 * limit)
    return scene


def run(scene: rustcloth.Scene) -> tuple[float, float, float, float]:
    """CPU ms per frame, the seam gap at 2 s and 4 s (mm), the kinetic energy at 4 s (J)."""
    sim = rustcloth.Simulation(scene)
    gaps = []
    start = time.process_time()
    for frame in range(FRAMES):
        sim.advance(1 / FPS)
        if (frame + 1) % 120 == 0:
            gaps.append(1000 * (sim.seam_gap() or 0.0))
    ms = 1000 * (time.process_time() - start) / FRAMES
    return ms, gaps[0], gaps[1], sim.energy().kinetic


def table(rows: dict[tuple[str, float], list[tuple[float, float, float, float]]],
          steps: dict[tuple[str, float], float], runs: int, default_stiffness: float) -> str:
    def span(values: list[float], fmt: str) -> str:
        lo, hi = min(values), max(values)
        return format(lo, fmt) if format(lo, fmt) == format(hi, fmt) else \
            f"{format(lo, fmt)}-{format(hi, fmt)}"

    lines = [
        f"Measured on {platform.machine()}, {runs} run(s) per configuration, taking turns "
        f"(`python benches/garment_membrane.py`; CPU time per 1/60 s frame over 0-4 s):",
        "",
        "| membrane | seam stiffness (N/m) | step (ms) | CPU ms per frame "
        "| seam gap at 2 s / 4 s (mm) | kinetic energy at 4 s (J) |",
        "|---|---:|---:|---:|---|---:|",
    ]
    for (membrane, stiffness), results in rows.items():
        ms = [r[0] for r in results]
        name = f"{membrane} (the scene's)" if membrane == "springs" and \
            stiffness == default_stiffness else membrane
        gaps = f"{span([r[1] for r in results], '.2f')} / {span([r[2] for r in results], '.2f')}"
        lines.append(
            f"| {name} | {stiffness:g} | {1000 * steps[(membrane, stiffness)]:.3f} "
            f"| {span(ms, '.1f')} | {gaps} | {span([r[3] for r in results], '.1e')} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1, help="runs per configuration (default 1)")
    parser.add_argument("--stiffer", type=float, default=2.0,
                        help="the stiffer seams as a multiple of the scene's (default 2)")
    parser.add_argument("--no-write", action="store_true", help="print the table only")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    if args.stiffer <= 0:
        parser.error("--stiffer must be positive")
    default = float(rustcloth.load_scene("shirt").to_dict()["cloth"]["mesh"]["seams"]["stiffness"])
    configs = [(membrane, stiffness) for stiffness in (default, args.stiffer * default)
               for membrane in ("springs", "triangle")]
    rows: dict[tuple[str, float], list[tuple[float, float, float, float]]] = {
        c: [] for c in configs}
    scenes = {c: shirt(*c) for c in configs}
    for _ in range(args.runs):
        for membrane, stiffness in configs:
            rows[(membrane, stiffness)].append(run(scenes[(membrane, stiffness)]))
            print(membrane, stiffness, rows[(membrane, stiffness)][-1], flush=True)
    text = table(rows, {c: s.dt for c, s in scenes.items()}, args.runs, default)
    print(text)
    if not args.no_write:
        write_between_markers(DOC, "benches/garment_membrane.py", text)


if __name__ == "__main__":
    main()
