"""numpy peer: benches/numpy_cloth.py (vectorised grid slicing, float32, one thread)."""

from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402
from common import measure, parse_args, scene_dict  # noqa: E402
from numpy_cloth import NumpyCloth  # noqa: E402


def main() -> None:
    args = parse_args()
    if args.colliders:
        raise SystemExit("numpy_cloth has no colliders")
    measure(
        args,
        build=lambda: NumpyCloth.from_scene(scene_dict(args.n)),
        step=lambda sim, k: sim.step(k),
        positions=lambda sim: sim.positions,
        info={"version": np.__version__},
    )


if __name__ == "__main__":
    main()
