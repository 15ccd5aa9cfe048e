"""rustcloth peer: the Python API, ``rustcloth.Simulation(rustcloth.Scene.from_dict(d))``.

The rayon pool size is fixed per process: run.py sets ``RAYON_NUM_THREADS`` for each run.
"""

from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import rustcloth  # noqa: E402
from common import measure, parse_args, scene_dict  # noqa: E402


def passes(sim: rustcloth.Simulation) -> dict[str, float]:
    """Cumulative wall seconds per pass of ``Simulation.profile()``, and the whole step's."""
    prof = sim.profile()
    return {**{name: p.seconds for name, p in prof.passes.items()}, "total": prof.total_seconds}


def main() -> None:
    args = parse_args()
    env_threads = os.environ.get("RAYON_NUM_THREADS")
    if env_threads is not None and int(env_threads) != args.threads:
        raise SystemExit(f"RAYON_NUM_THREADS={env_threads} but --threads {args.threads}")
    measure(
        args,
        build=lambda: rustcloth.Simulation(
            rustcloth.Scene.from_dict(scene_dict(args.n, args.colliders))
        ),
        step=lambda sim, k: sim.step(k),
        positions=lambda sim: sim.positions,
        info={
            "version": getattr(rustcloth, "__version__", "0.1.0"),
            "module": rustcloth.__file__,
            "built": time.strftime(
                "%Y-%m-%d %H:%M UTC", time.gmtime(os.path.getmtime(rustcloth._core.__file__))
            ),
        },
        profile=passes,
    )


if __name__ == "__main__":
    main()
