"""The fixed peer-benchmark scene and the measuring harness shared by every implementation.

Each implementation file (``impl_*.py``) is a script run in its own process by ``run.py``:
it builds the scene, warms up, times the steps and prints one ``RESULT {json}`` line with the
set-up time, the step time, the minimum y after the run and the process's peak RSS.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

SPACING = 0.01  # m
PARTICLE_MASS = 1e-3  # kg
K = 50.0  # N/m, every family
DAMPING = 0.01  # N s/m
GRAVITY = (0.0, -9.81, 0.0)  # m/s^2
DT = 1e-3  # s
WARMUP = 5
STEPS = {128: 1000, 256: 300, 512: 50}
QUICK_STEPS = {128: 100, 256: 30, 512: 5}
BOTTOM_Y = 1.0  # m: the lower edge of the hanging cloth at rest

# The 6 spring directions (di, dj) of the 12-neighbour stencil: structural, shear, bend.
DIRECTIONS = ((1, 0), (0, 1), (1, 1), (-1, 1), (2, 0), (0, 2))


def extent(n: int) -> float:
    return SPACING * (n - 1)


def scene_dict(n: int, colliders: bool = False) -> dict[str, Any]:
    """rustcloth's scene dict for the benchmark: n x n, plane xy, hanging from the top corners.

    With ``colliders``: a floor 5 mm below the lower edge and a sphere just under its middle.
    """
    size = extent(n)
    scene: dict[str, Any] = {
        "integrator": "symplectic_euler",
        "dt": DT,
        "substeps": 1,
        "gravity": list(GRAVITY),
        "air_drag": 0.0,
        "cloth": {
            "nx": n,
            "ny": n,
            "size": [size, size],
            "center": [0.0, BOTTOM_Y + size / 2, 0.0],
            "plane": "xy",
            "particle_mass": PARTICLE_MASS,
            "k_structural": K,
            "k_shear": K,
            "k_bend": K,
            "damping": DAMPING,
            "pins": ["top_corners"],
        },
    }
    if colliders:
        radius = 0.2 * size
        scene["floor"] = {"height": BOTTOM_Y - 0.005, "friction": 0.3, "thickness": 0.002}
        scene["spheres"] = [
            {"center": [0.0, BOTTOM_Y - radius - 0.002, 0.0], "radius": radius, "friction": 0.2}
        ]
    return scene


def initial_positions(n: int) -> np.ndarray:
    """(n*n, 3) float64 rest positions, particle (i, j) at row j*n+i (plane xy)."""
    size = extent(n)
    u = (np.arange(n) / (n - 1) - 0.5) * size
    x = np.zeros((n, n, 3))
    x[:, :, 0] = u[None, :]
    x[:, :, 1] = BOTTOM_Y + size / 2 + u[:, None]
    return x.reshape(-1, 3)


def pinned(n: int) -> list[int]:
    """The two corners of the top edge j = n-1."""
    return [(n - 1) * n, (n - 1) * n + n - 1]


def parse_args(
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=128)
    p.add_argument("--steps", type=int, default=None)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--colliders", action="store_true")
    if extra:
        extra(p)
    args = p.parse_args()
    if args.steps is None:
        args.steps = STEPS.get(args.n, 100)
    return args


def measure(
    args: argparse.Namespace,
    build: Callable[[], Any],
    step: Callable[[Any, int], None],
    positions: Callable[[Any], np.ndarray],
    info: dict[str, Any] | None = None,
    profile: Callable[[Any], dict[str, float]] | None = None,
) -> None:
    """Build, warm up, time ``args.steps`` steps and print the ``RESULT`` line.

    ``profile(sim)``, if given, returns cumulative seconds per pass (and ``"total"``); the
    result then carries ``"profile"``: ms per step of each pass over the timed steps only.
    """
    t0 = time.perf_counter()
    sim = build()
    t1 = time.perf_counter()
    step(sim, WARMUP)
    positions(sim)  # also synchronises
    before = profile(sim) if profile else {}
    u2 = resource.getrusage(resource.RUSAGE_SELF)
    t2 = time.perf_counter()
    step(sim, args.steps)
    x = positions(sim)
    t3 = time.perf_counter()
    u3 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (u3.ru_utime + u3.ru_stime) - (u2.ru_utime + u2.ru_stime)
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    result = {
        "n": args.n,
        "particles": args.n * args.n,
        "threads": args.threads,
        "colliders": bool(args.colliders),
        "steps": args.steps,
        "setup_s": t1 - t0,
        "warmup_s": t2 - t1,
        "run_s": t3 - t2,
        "ms_per_step": 1e3 * (t3 - t2) / args.steps,
        "cpu_per_wall": cpu / (t3 - t2),  # ~ threads actually busy (all threads' CPU time)
        "min_y": float(x[:, 1].min()),
        "finite": bool(np.isfinite(x).all()),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        **(info or {}),
    }
    if profile:
        after = profile(sim)
        result["profile"] = {
            name: 1e3 * (s - before.get(name, 0.0)) / args.steps for name, s in after.items()
        }
    sys.stdout.flush()
    print("RESULT " + json.dumps(result), flush=True)
