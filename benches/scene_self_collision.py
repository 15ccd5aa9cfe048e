"""What `[self_collision]` costs in each interactive scene, driven as the demo drives it.

For every scene: the CPU time per 1/60 s frame on one thread (``RAYON_NUM_THREADS=1``,
``time.process_time()``) without the pass and with it (``thickness`` 3 mm, below half of every
scene's spacing), over two windows:

- the opening: the scene's first ``--opening`` seconds, untouched;
- a fold: the free particle farthest from the pins (or from the cloth's centre) grabbed as the
  viewer grabs it (``grab``, one ``drag_to`` per frame, a grip of the default radius) and drawn
  over ``--drag`` seconds across the cloth, past its centre and a little above it, then held
  ``--hold`` seconds, so that the cloth folds onto itself.

It also counts, by the independent checker ``benches/peers/tri_check.py``, the pairs of
triangles crossing at the end of the fold, with and without the pass. The two builds of a scene
(without, with) run one after the other, so a load on the machine falls on both.

    RAYON_NUM_THREADS=1 PYTHONPATH=python python benches/scene_self_collision.py

writes its table into docs/contact.md between the markers (``--no-write`` prints it only).
All twelve scenes take about nine minutes on a loaded two-core machine, most of it the folds
with the pass of the scenes that are left off; ``--scenes`` picks some.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import rustcloth

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import tri_check  # noqa: E402
from generated import write_between_markers  # noqa: E402

FPS = 60.0
THICKNESS = 0.003
# A frame is interactive when the step fits a 60 Hz frame on the demo's two threads; one
# thread's CPU time stands for about 1.5 to 1.8 times that (the pass's search and the step
# share out to threads, the repulsion and the cap do not), so the rule reads 25 ms of one
# thread.
BUDGET_MS = 25.0
SCENES = ["drape", "drape_box", "tablecloth", "round_tablecloth", "hanging", "tear", "curtain",
          "mannequin", "flag", "flag_hole", "spinner", "freefall"]
DOC = Path(__file__).resolve().parent.parent / "docs" / "contact.md"


def fold_drag(sim: rustcloth.Simulation) -> tuple[int, np.ndarray, np.ndarray]:
    """The particle a fold grabs, where it starts and where the drag ends: the free particle
    farthest from the pinned ones (or from the cloth's centre), drawn past the centre to 0.6 of
    its distance on the other side, 5 cm above the cloth's top."""
    x = sim.positions.astype(np.float64)
    free = sim.alive & ~sim.pinned
    anchor = x[sim.pinned].mean(axis=0) if sim.pinned.any() else x.mean(axis=0)
    dist = np.where(free, np.linalg.norm(x - anchor, axis=1), -1.0)
    grab = int(np.argmax(dist))
    centre = x[sim.alive].mean(axis=0)
    target = centre + 0.6 * (centre - x[grab])
    target[1] = max(target[1], x[:, 1].max() + 0.05)
    return grab, x[grab], target


def frames(sim: rustcloth.Simulation, n: int, drag=None) -> list[float]:
    """CPU ms of each of ``n`` frames; ``drag(f)`` gives frame ``f``'s grab target."""
    out = []
    for f in range(n):
        if drag is not None:
            sim.drag_to(drag(f))
        t0 = time.process_time()
        sim.advance(1 / FPS)
        out.append((time.process_time() - t0) * 1e3)
    return out


def run(name: str, with_pass: bool, opening: float, drag: float, hold: float) -> dict:
    scene = rustcloth.load_scene(name)
    scene = scene.replace(self_collision={"thickness": THICKNESS} if with_pass else None)
    sim = rustcloth.Simulation(scene)
    open_ms = frames(sim, round(opening * FPS))
    grab, start, target = fold_drag(sim)
    sim.grab(grab)
    n = max(1, round(drag * FPS))
    fold_ms = frames(sim, n, lambda f: start + (target - start) * (f + 1) / n)
    fold_ms += frames(sim, round(hold * FPS))
    sim.release()
    crossings = tri_check.count(sim.positions, sim.triangles)
    finite = bool(np.isfinite(sim.positions).all())
    return {"open": float(np.mean(open_ms)), "fold": float(np.mean(fold_ms)),
            "fold_max": float(np.max(fold_ms)), "crossings": crossings, "finite": finite}


def table(rows: list[tuple[str, dict, dict]], args: argparse.Namespace) -> str:
    lines = [
        f"Measured on {platform.machine()}, {os.cpu_count()} cores, one thread "
        f"(`RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'unset')}`), "
        f"`python benches/scene_self_collision.py --opening {args.opening} --drag {args.drag} "
        f"--hold {args.hold}`. CPU ms per 1/60 s frame (mean; the fold's worst frame in "
        f"brackets); crossings by `benches/peers/tri_check.py` at the end of the fold. On when "
        f"both windows' mean with the pass is at most {BUDGET_MS:g} ms.",
        "",
        "| scene | opening without | opening with | fold without | fold with (worst) "
        "| crossings without / with | on? |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for name, off, on in rows:
        fits = max(on["open"], on["fold"]) <= BUDGET_MS and on["finite"]
        lines.append(
            f"| {name} | {off['open']:.1f} | {on['open']:.1f} | {off['fold']:.1f} | "
            f"{on['fold']:.1f} ({on['fold_max']:.0f}) | {off['crossings']} / {on['crossings']} "
            f"| {'on' if fits else 'off'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--opening", type=float, default=1.0, help="seconds untouched (1.0)")
    parser.add_argument("--drag", type=float, default=0.75, help="seconds of the drag (0.75)")
    parser.add_argument("--hold", type=float, default=0.5, help="seconds held after it (0.5)")
    parser.add_argument("--scenes", nargs="*", default=SCENES, help="scenes to run (all)")
    parser.add_argument("--no-write", action="store_true", help="print, leave the docs")
    args = parser.parse_args()
    rows = []
    for name in args.scenes:
        off = run(name, False, args.opening, args.drag, args.hold)
        on = run(name, True, args.opening, args.drag, args.hold)
        print(name, off, on, flush=True)
        rows.append((name, off, on))
    text = table(rows, args)
    print(text)
    if not args.no_write:
        write_between_markers(DOC, "benches/scene_self_collision.py", text)


if __name__ == "__main__":
    main()
