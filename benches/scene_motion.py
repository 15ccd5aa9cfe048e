"""What two showcase scenes do when a user meets them: a drag of ``tear``'s lower corner as the
demo drives it, and how far ``curtain`` sways in its draught. Prints two tables (markdown).

    .venv/bin/python benches/scene_motion.py [--quick]

The drag: a ray from in front of the cloth picks the lower-left corner, ``grab`` takes the grip,
``drag_to`` moves it once per 60 Hz frame along a straight line (``advance(1/60)`` between),
then the grip is held still for a second and released. For each grip radius, speed and
direction it reports the pieces the cloth ends in and the sizes of the two largest: a pluck
leaves a small second piece the size of the grip, a rip two large ones.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import rustcloth

FPS = 60.0
MOVES = {"down": (0.0, -0.8, 0.0), "down-out": (-0.6, -0.6, 0.0), "out": (-0.8, 0.0, 0.0)}


def drag_tear(radius: float | None, seconds: float, move: tuple[float, float, float],
              settle: float = 0.5, hold: float = 1.0) -> tuple[int, list[int], int]:
    """Drag ``tear``'s lower-left corner by ``move`` (m) over ``seconds``; returns the pieces,
    the two largest pieces' sizes, and the number of particles the grip held."""
    sim = rustcloth.Simulation("tear")
    if radius is not None:
        sim.grip_radius = radius
    sim.advance(settle)
    hit = sim.pick(sim.positions[0] + [0.0, 0.0, 3.0], [0.0, 0.0, -1.0])
    assert hit is not None
    sim.grab(hit[0])
    held = len(sim.gripped())
    start = sim.positions[hit[0]].copy()
    frames = max(1, round(seconds * FPS))
    for f in range(1, frames + 1):
        sim.drag_to(start + np.asarray(move) * f / frames)
        sim.advance(1 / FPS)
    for _ in range(round(hold * FPS)):
        sim.advance(1 / FPS)
    sim.release()
    sizes = np.sort(np.bincount(sim.piece_labels()[sim.alive]))[::-1]
    return sim.pieces(), [int(s) for s in sizes[sizes > 0][:2]], held


def curtain_sway(seconds: float, wind: bool = True) -> tuple[float, float, float, float]:
    """The built-in curtain (without its ``[wind]`` if ``wind`` is False) over ``seconds``:
    the range of its lower edge's mean z after the first second (m), that edge's rms speed
    along z (m/s), and its closest approach to the sphere's surface (m)."""
    scene = rustcloth.load_scene("curtain")
    if not wind:
        data = scene.to_dict()
        data.pop("wind", None)
        scene = rustcloth.Scene.from_dict(data)
    sim = rustcloth.Simulation(scene)
    nx = scene.cloth["nx"]
    sphere = scene.spheres[0]
    centre, radius = np.asarray(sphere["center"]), sphere["radius"]
    z, clearance = [], np.inf
    for _ in range(round(seconds * FPS)):
        sim.advance(1 / FPS)
        x = sim.positions
        z.append(float(x[:nx, 2].mean()))
        clearance = min(clearance, float(np.linalg.norm(x - centre, axis=1).min() - radius))
    late = np.asarray(z[round(FPS):])
    speed = float(np.sqrt(np.mean(np.diff(late) ** 2)) * FPS)
    return float(late.min()), float(late.max()), speed, clearance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer cases, a shorter sway")
    args = parser.parse_args()
    radii: list[float | None] = [0.0, None] if args.quick else [0.0, None, 0.2, 0.3]
    speeds = [0.2, 1.5]
    print("| grip radius (m) | held | drag | over (s) | pieces | two largest |")
    print("|---|---|---|---|---|---|")
    for radius in radii:
        for seconds in speeds:
            for name, move in MOVES.items():
                pieces, sizes, held = drag_tear(radius, seconds, move)
                shown = "default" if radius is None else f"{radius:g}"
                print(f"| {shown} | {held} | {name} | {seconds:g} | {pieces} | {sizes} |",
                      flush=True)
    print()
    print("| curtain | lower edge z after 1 s (m) | rms speed (m/s) | sphere clearance (m) |")
    print("|---|---|---|---|")
    seconds = 4.0 if args.quick else 10.0
    for wind in (False, True):
        t = time.perf_counter()
        lo, hi, speed, clearance = curtain_sway(seconds, wind)
        label = "with its [wind]" if wind else "without wind"
        print(f"| {label} ({seconds:g} s, {time.perf_counter() - t:.1f} s to run) | "
              f"{lo:.3f} to {hi:.3f} | {speed:.3f} | {clearance:.3f} |", flush=True)


if __name__ == "__main__":
    main()
