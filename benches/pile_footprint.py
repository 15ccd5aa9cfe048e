"""What ``pile`` piles into: the cloth's footprint seen from above (and its share of the flat
cloth's area) and its height after it settles, for the scene as built in and a few variants of
it. The footprint is tests/test_scene_behaviour.py's (a raster of 1 cm squares).

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

VARIANTS: dict[str, dict[str, Any]] = {
    "as built in": {},
    "floor friction 1": {"floor": {"friction": 1.0}},
    "floor friction 2": {"floor": {"friction": 2.0}},
}
MORE: dict[str, dict[str, Any]] = {
    "k_bend 2": {"cloth": {"k_bend": 2.0}},
    "k_bend 0.5": {"cloth": {"k_bend": 0.5}},
    "dropped from 0.55 m higher": {"cloth": {"center": [0.0, 1.2, 0.0]}},
    "a 0.36 x 1.5 m strip, k_bend 2": {"cloth": {"nx": 12, "ny": 48, "size": [0.36, 1.5],
                                                 "k_bend": 2.0, "center": [0.0, 0.9, 0.0]}},
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
              f"{time.perf_counter() - t:.0f} |", flush=True)


if __name__ == "__main__":
    main()
