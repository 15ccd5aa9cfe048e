"""What ``pile`` piles into: the cloth's footprint seen from above (and its share of the flat
cloth's area) and its height after it settles, for the scene as built in and a few variants of
it, among them the square dropped edge first. The footprint is tests/test_scene_behaviour.py's
(a raster of 1 cm squares); the wall time of each run, all in one process, compares the cost of
a step (every run is the same number of steps).

    .venv/bin/python benches/pile_footprint.py [--all] [--seconds 3]

The default runs the scene and two variants (about a minute); ``--all`` adds the slower ones.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import rustcloth

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_scene_behaviour import pile_shape  # noqa: E402


def sinking(speed: float) -> dict[str, Any]:
    """The scene's ball sinking at ``speed`` (m/s) instead."""
    ball = dict(rustcloth.load_scene("pile").colliders[0])
    return {"colliders": [{**ball, "velocity": [0.0, -speed, 0.0]}]}


# The square dropped edge first from 15 cm onto the floor beside a 4 cm ball (stiffer bending,
# a less grippy floor): it lands as a band of folds as wide as the cloth.
EDGE_FIRST: dict[str, Any] = {
    "cloth": {"plane": "xy", "center": [0.0, 0.65, 0.0], "k_bend": 10.0},
    "floor": {"friction": 0.5},
    "colliders": [],
    "spheres": [{"center": [0.1, 0.04, 0.03], "radius": 0.04, "friction": 0.3,
                 "thickness": 0.003}],
}
VARIANTS: dict[str, dict[str, Any]] = {
    "as built in": {},
    "dropped edge first instead": EDGE_FIRST,
    "k_bend 10": {"cloth": {"k_bend": 10.0}},
}
MORE: dict[str, dict[str, Any]] = {
    "floor friction 0.5": {"floor": {"friction": 0.5}},
    "ball sinking at 0.1 m/s": sinking(0.1),
    "ball sinking at 0.3 m/s": sinking(0.3),
    "dropped edge first, k_bend 2, floor friction 1": {**EDGE_FIRST, "cloth": {
        **EDGE_FIRST["cloth"], "k_bend": 2.0}, "floor": {"friction": 1.0}},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--all", action="store_true", help="the slower variants too")
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated time")
    args = parser.parse_args()
    variants = VARIANTS | (MORE if args.all else {})
    print(f"| pile, after {args.seconds:g} s | footprint (m^2) | of the flat area | height (m) "
          "| wall (s) |")
    print("|---|---|---|---|---|")
    base = rustcloth.load_scene("pile")
    for name, changes in variants.items():
        scene = base.replace(**changes)
        width, depth = scene.cloth["size"]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rustcloth.StabilityWarning)
            sim = rustcloth.Simulation(scene)
        t = time.perf_counter()
        sim.advance(args.seconds)
        area, height = pile_shape(sim)
        print(f"| {name} | {area:.3f} | {area / (width * depth):.2f} | {height:.3f} | "
              f"{time.perf_counter() - t:.1f} |", flush=True)


if __name__ == "__main__":
    main()
