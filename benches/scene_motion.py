"""What two showcase scenes do when a user meets them: a drag of ``tear``'s lower corner as the
demo drives it, and how far ``curtain`` sways in its draught. Prints three tables (markdown).

    .venv/bin/python benches/scene_motion.py [--quick]

The first table drags the scene as it is (its perforation, tear strain 0.5), against the same
cloth without the perforation and with the tear strain of 0.3, each with the grip gliding
between frames (``drag_time`` 1/60 s, the default) and jumping to each frame's target in a
substep (``drag_time`` 0): the second piece after each drag.

The tables after it study ``tear`` as it was before its perforation: the same cloth uncut,
tearing at 0.3, its grip jumping to each frame's target (``plain_tear``).

The drag: a ray from in front of the cloth picks the lower-left corner, ``grab`` takes the grip,
``drag_to`` moves it once per 60 Hz frame along a straight line (``advance(1/60)`` between),
then the grip is held still for a second and released. For each grip radius, speed and
direction it reports the pieces the cloth ends in and the sizes of the two largest: a pluck
leaves a small second piece the size of the grip, a rip two large ones.

The third table asks what a rip across needs: the same drags of ``tear``'s cloth held taut
between pins along its top and bottom edges, its springs' rest lengths along the height
shortened so that it starts at rest at a uniform vertical ``pre-strain`` (a background tension
across the path a rip would take), for tear strains of 0.2, 0.3 and 0.4; and whether a gentle drag
(3 and 10 cm over a second) rips it too.

The fourth table frees the dragged corner (a pinned corner peels its pinned neighbours off under
any tug): frames of pins that stay clear of it, pre-strained at half the tear strain along the
height, the width or both, each dragged down and out fast and slow and tugged 10 cm.

The fifth table hangs a weighted hem on the free corner instead: ``tear``'s cloth pinned along its
top only, pre-strained along the height, its lower row given the mass whose weight the springs
above it carry at the start (so that it starts at rest under the tension of the hem, without the
swing of a hem let go), dragged and tugged as in the fourth.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
import rustcloth

FPS = 60.0
MOVES = {"down": (0.0, -0.8, 0.0), "down-out": (-0.6, -0.6, 0.0), "out": (-0.8, 0.0, 0.0)}


def drag_tear(radius: float | None, seconds: float, move: tuple[float, float, float],
              settle: float = 0.5, hold: float = 1.0) -> tuple[int, list[int], int]:
    """Drag ``tear``'s lower-left corner by ``move`` (m) over ``seconds``; returns the pieces,
    the two largest pieces' sizes, and the number of particles the grip held."""
    sim = plain_tear()
    if radius is not None:
        sim.grip_radius = radius
    return drag(sim, seconds, move, settle, hold)


def plain_tear(cuts: bool = False, max_strain: float = 0.3,
               drag_time: float = 0.0) -> rustcloth.Simulation:
    """``tear``'s curtain with or without its perforation, tearing at ``max_strain``, its grip
    reaching each drag target over ``drag_time`` (by default as studied before the
    perforation: uncut, 0.3, jumping)."""
    scene = rustcloth.load_scene("tear")
    cloth = scene.cloth if cuts else {**scene.cloth, "cuts": []}
    tearing = {**scene.tearing, "max_strain": max_strain}
    sim = rustcloth.Simulation(scene.replace(cloth=cloth, tearing=tearing))
    sim.drag_time = drag_time
    return sim


def scene_table() -> None:
    print("| cloth | drag time (s) | second piece after each drag (down, down-out, out; 0.2 s "
          "then 1.5 s) |")
    print("|---|---|---|")
    cloths = {"the scene (perforated, tear strain 0.5)": (True, 0.5),
              "without the perforation": (False, 0.5),
              "perforated, tear strain 0.3": (True, 0.3)}
    for name, (cuts, strain) in cloths.items():
        for drag_time, shown in ((1 / 60, "1/60"), (0.0, "0")):
            second = [(drag(plain_tear(cuts, strain, drag_time), s, m)[1] + [0])[1]
                      for m in MOVES.values() for s in (0.2, 1.5)]
            print(f"| {name} | {shown} | {', '.join(map(str, second))} |", flush=True)


def drag(sim: rustcloth.Simulation, seconds: float, move: tuple[float, float, float],
         settle: float = 0.5, hold: float = 1.0) -> tuple[int, list[int], int]:
    """After ``settle`` s, pick ``sim``'s lower-left corner with a ray from the viewer's side,
    grab it, drag it by ``move`` over ``seconds`` frame by frame, hold ``hold`` s, release;
    returns the pieces, the two largest pieces' sizes, and the number of particles held."""
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


GENTLE = {"3 cm": (-0.02, -0.02, 0.0), "10 cm": (-0.07, -0.07, 0.0)}


def taut_tear(prestrain: float, max_strain: float) -> rustcloth.Simulation:
    """``tear``'s cloth pinned along its top and bottom edges, its rest height shortened by
    ``1 + prestrain`` and its particles put back at full height, so that it starts at rest
    (but for its free side edges) under a uniform vertical strain ``prestrain``."""
    return framed_tear(["top_edge", "bottom_edge"], (0.0, prestrain), max_strain)


def framed_tear(pins: list[Any], prestrain: tuple[float, float],
                max_strain: float) -> rustcloth.Simulation:
    """``tear``'s cloth held by ``pins``, its rest width and height shortened by ``1 +
    prestrain`` and its particles put back at full size (the top edge where it was, the width
    about its middle), tearing at ``max_strain``."""
    scene = plain_tear().scene
    cloth = dict(scene.cloth)
    width, height = cloth["size"]
    cloth.update(size=[width / (1.0 + prestrain[0]), height / (1.0 + prestrain[1])], pins=pins)
    tearing = {**scene.tearing, "max_strain": max_strain}
    sim = rustcloth.Simulation(scene.replace(cloth=cloth, tearing=tearing))
    sim.drag_time = 0.0
    x = sim.positions.copy()
    mid, top = 0.5 * (x[:, 0].max() + x[:, 0].min()), x[:, 1].max()
    x[:, 0] = mid + (x[:, 0] - mid) * (1.0 + prestrain[0])
    x[:, 1] = top - (top - x[:, 1]) * (1.0 + prestrain[1])
    sim.set_positions(x)
    return sim


NX = 40
FRAMES: dict[str, list[Any]] = {
    "top and right edges, left edge from row 6 up": ["top_edge", "right_edge"]
    + [[0, j] for j in range(6, NX)],
    "top edge, bottom row from column 5 on": ["top_edge"] + [[i, 0] for i in range(5, NX)],
    "top and right edges, bottom and left from 8 on": ["top_edge", "right_edge"]
    + [[i, 0] for i in range(8, NX)] + [[0, j] for j in range(8, NX)],
}
ALONG = {"height": (0.0, 1.0), "width": (1.0, 0.0), "both": (1.0, 1.0)}


def free_corner_table(strains: list[float]) -> None:
    print("| frame (pins) | pre-strain along | tear strain | untouched 3 s: pieces | second piece "
          "after a down-out drag (0.2 s, 1.5 s) | 10 cm tug: second piece, peak strain |")
    print("|---|---|---|---|---|---|")
    for name, pins in FRAMES.items():
        for along, (ax, ay) in ALONG.items():
            for max_strain in strains:
                pre = (0.5 * max_strain * ax, 0.5 * max_strain * ay)
                idle = framed_tear(pins, pre, max_strain)
                idle.advance(3.0)
                second = [(drag(framed_tear(pins, pre, max_strain), s, MOVES["down-out"])[1]
                           + [0])[1] for s in (0.2, 1.5)]
                tug = framed_tear(pins, pre, max_strain)
                peak = max_stretch_during(tug, GENTLE["10 cm"])
                sizes = np.sort(np.bincount(tug.piece_labels()[tug.alive]))[::-1]
                print(f"| {name} | {along} | {max_strain:g} | {idle.pieces()} | "
                      f"{second[0]}, {second[1]} | {(list(sizes[sizes > 0]) + [0])[1]}, "
                      f"{peak:.2f} |", flush=True)


def hemmed_tear(prestrain: float, max_strain: float) -> tuple[rustcloth.Simulation, float]:
    """``tear``'s cloth pinned along its top, pre-strained by ``prestrain`` along the height,
    with each particle of its lower row as heavy as the springs above it pull up at the start
    (found by one step without gravity); returns it and the hem's mass (kg)."""
    probe = framed_tear(["top_edge"], (0.0, prestrain), max_strain)
    weightless = rustcloth.Simulation(probe.scene.replace(gravity=[0.0, 0.0, 0.0]))
    weightless.set_positions(probe.positions)
    mass = weightless.masses.copy()
    weightless.step(1)
    pull = weightless.velocities[:NX, 1] * mass[:NX] / weightless.scene.dt
    mass[:NX] = np.maximum(mass[:NX], pull / 9.81)
    probe.set_masses(mass)
    return probe, float(mass[:NX].sum())


def hem_table(cases: list[tuple[float, float]]) -> None:
    print("| pre-strain | tear strain | hem (kg) | untouched 3 s: pieces, largest strain | second "
          "piece after a down-out drag (0.2 s, 1.5 s) | 10 cm tug: second piece, peak strain |")
    print("|---|---|---|---|---|---|")
    for prestrain, max_strain in cases:
        idle, hem = hemmed_tear(prestrain, max_strain)
        idle.advance(3.0)
        second = [(drag(hemmed_tear(prestrain, max_strain)[0], s, MOVES["down-out"])[1]
                   + [0])[1] for s in (0.2, 1.5)]
        tug = hemmed_tear(prestrain, max_strain)[0]
        peak = max_stretch_during(tug, GENTLE["10 cm"])
        sizes = np.sort(np.bincount(tug.piece_labels()[tug.alive]))[::-1]
        print(f"| {prestrain:g} | {max_strain:g} | {hem:.1f} | {idle.pieces()}, "
              f"{idle.max_stretch():.2f} | {second[0]}, {second[1]} | "
              f"{(list(sizes[sizes > 0]) + [0])[1]}, {peak:.2f} |", flush=True)


def max_stretch_during(sim: rustcloth.Simulation, move: tuple[float, float, float]) -> float:
    """Drags ``sim``'s lower-left corner by ``move`` over a second after half a second's settle,
    holds it a second and releases it; returns the largest strain seen while held."""
    sim.advance(0.5)
    hit = sim.pick(sim.positions[0] + [0.0, 0.0, 3.0], [0.0, 0.0, -1.0])
    assert hit is not None
    sim.grab(hit[0])
    start = sim.positions[hit[0]].copy()
    peak = 0.0
    for f in range(1, round(2 * FPS) + 1):
        sim.drag_to(start + np.asarray(move) * min(f / FPS, 1.0))
        sim.advance(1 / FPS)
        peak = max(peak, sim.max_stretch())
    sim.release()
    return peak


def background_table(prestrains: list[float], speeds: list[float]) -> None:
    print("| pre-strain | tear strain | untouched 3 s: pieces | second piece after each drag "
          "(down-out, down, out; 0.2 s then 1.5 s) | gentle drag (3 cm, 10 cm): second piece |")
    print("|---|---|---|---|---|")
    for prestrain in prestrains:
        for max_strain in (0.2, 0.3, 0.4):
            if prestrain >= max_strain:
                continue
            idle = taut_tear(prestrain, max_strain)
            idle.advance(3.0)
            second = [(drag(taut_tear(prestrain, max_strain), s, m)[1] + [0])[1]
                      for s in speeds for m in MOVES.values()]
            gentle = [(drag(taut_tear(prestrain, max_strain), 1.0, m)[1] + [0])[1]
                      for m in GENTLE.values()]
            print(f"| {prestrain:g} | {max_strain:g} | {idle.pieces()} | "
                  f"{', '.join(map(str, second))} | {', '.join(map(str, gentle))} |", flush=True)


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
    scene_table()
    print()
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
    background_table([0.0, 0.1] if args.quick else [0.0, 0.05, 0.1, 0.15, 0.2], speeds)
    print()
    free_corner_table([0.3, 0.5])
    print()
    hem_table([(0.15, 0.3), (0.2, 0.4), (0.25, 0.5)])
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
