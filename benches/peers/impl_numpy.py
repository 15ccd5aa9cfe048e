"""numpy peer: rustcloth.reference in float32 (vectorised grid slicing, one thread)."""

from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
from common import measure, parse_args, scene_dict  # noqa: E402
from rustcloth.reference import ReferenceCloth  # noqa: E402


def main() -> None:
    args = parse_args()
    if args.colliders:
        raise SystemExit("the reference model has no colliders")
    measure(
        args,
        build=lambda: ReferenceCloth(scene_dict(args.n), dtype=np.float32),
        step=lambda sim, k: sim.step(k),
        positions=lambda sim: sim.positions,
        info={"version": np.__version__},
    )


if __name__ == "__main__":
    main()
