"""The stiff draping scene of docs/stiff.md (issue 14), shared by its implementations.

A square metre of heavy cloth (0.5 kg) starts horizontal at 1.5 m and drapes from its two
top corners under gravity, stepped at one display frame, dt = 1/60 s. Stiffness 500 / 125 / 25
N/m for the structural / shear / bending springs, damping 0.01 N s/m along each spring, no air
drag, no colliders (newton's VBD handles contact differently). At n x n particles each weighs
0.5 / n^2 kg, so ``k_structural dt^2 / m`` is 4600 at 128 x 128 (issue 14 asks for >= 100),
18500 at 256 and 74000 at 512: the same cloth, finer.

Each implementation script prints ``RESULT {json}`` with its time per frame and the stretch of
its last state; ``stretch`` computes that from positions alone, the same for every solver.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

SIZE = 1.0  # m
TOTAL_MASS = 0.5  # kg
K = (500.0, 125.0, 25.0)  # N/m: structural, shear, bending
DAMPING = 0.01  # N s/m
DT = 1.0 / 60.0  # s
HEIGHT = 1.5  # m
GRAVITY = (0.0, -9.81, 0.0)

# (di, dj, family) of the six springs each particle anchors.
STENCIL = ((1, 0, 0), (0, 1, 0), (1, 1, 1), (-1, 1, 1), (2, 0, 2), (0, 2, 2))


def particle_mass(n: int) -> float:
    return TOTAL_MASS / (n * n)


def rustcloth_scene(n: int, integrator: str, **solver: Any) -> dict[str, Any]:
    """rustcloth's scene dict; ``solver`` adds solver keys (cg_tolerance, preconditioner...)."""
    return {
        "integrator": integrator,
        "dt": DT,
        "substeps": 1,
        "gravity": list(GRAVITY),
        "air_drag": 0.0,
        **solver,
        "cloth": {
            "nx": n,
            "ny": n,
            "size": [SIZE, SIZE],
            "center": [0.0, HEIGHT, 0.0],
            "plane": "xz",
            "particle_mass": particle_mass(n),
            "k_structural": K[0],
            "k_shear": K[1],
            "k_bend": K[2],
            "damping": DAMPING,
            "pins": ["top_corners"],
        },
    }


def initial_positions(n: int) -> np.ndarray:
    """(n*n, 3) rest positions, particle (i, j) at row j*n+i: x along i, z along j."""
    u = (np.arange(n) / (n - 1) - 0.5) * SIZE
    x = np.zeros((n, n, 3))
    x[:, :, 0] = u[None, :]
    x[:, :, 1] = HEIGHT
    x[:, :, 2] = u[:, None]
    return x.reshape(-1, 3)


def pinned(n: int) -> list[int]:
    """rustcloth's "top_corners": the two corners of the row j = n - 1."""
    return [(n - 1) * n, n * n - 1]


def springs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every spring as (anchor, partner, family) index arrays."""
    idx = np.arange(n * n).reshape(n, n)  # [j, i]
    a, b, f = [], [], []
    for di, dj, family in STENCIL:
        i0, i1 = max(0, -di), n - max(0, di)
        a.append(idx[0 : n - dj, i0:i1].ravel())
        b.append(idx[dj:n, i0 + di : i1 + di].ravel())
        f.append(np.full(a[-1].size, family))
    return np.concatenate(a), np.concatenate(b), np.concatenate(f)


def stretch(x: np.ndarray, n: int) -> dict[str, float]:
    """Mean and largest ``l / L - 1`` of the structural springs of positions ``x``."""
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    rest = initial_positions(n)
    a, b, f = springs(n)
    s = f == 0
    length = np.linalg.norm(x[b[s]] - x[a[s]], axis=1)
    rest_length = np.linalg.norm(rest[b[s]] - rest[a[s]], axis=1)
    strain = length / rest_length - 1.0
    return {"mean_stretch": float(strain.mean()), "max_stretch": float(strain.max())}


def run(
    name: str,
    n: int,
    frames: int,
    build: Callable[[], Any],
    step: Callable[[Any], None],
    positions: Callable[[Any], np.ndarray],
    stats: Callable[[Any], dict[str, Any]] | None = None,
    out: str | None = None,
    every: int = 10,
) -> None:
    """Steps ``frames`` frames, timing each but the first, and prints the RESULT line; with
    ``out``, saves the final positions there (npz). The stretch is sampled every ``every``
    frames. CPU time is all threads' together."""
    t0 = time.perf_counter()
    sim = build()
    setup = time.perf_counter() - t0
    walls, cpus, samples = [], [], []
    for frame in range(1, frames + 1):
        u0, w0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
        step(sim)
        w1, u1 = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
        walls.append(w1 - w0)
        cpus.append((u1.ru_utime + u1.ru_stime) - (u0.ru_utime + u0.ru_stime))
        if frame % every == 0 or frame == frames:
            samples.append({"frame": frame, **stretch(positions(sim), n)})
    # The first frame pays for allocations (and newton's kernel compilation): not timed.
    walls, cpus = walls[1:] or walls, cpus[1:] or cpus
    x = np.asarray(positions(sim), dtype=np.float64).reshape(-1, 3)
    if out:
        np.savez_compressed(out, x=x)
    with open("/proc/loadavg") as f:
        load = float(f.read().split()[0])
    result = {
        "name": name,
        "n": n,
        "frames": frames,
        "setup_s": setup,
        "ms_per_frame": 1e3 * float(np.mean(walls)),
        "ms_per_frame_median": 1e3 * float(np.median(walls)),
        "cpu_ms_per_frame": 1e3 * float(np.mean(cpus)),
        "load": load,
        "finite": bool(np.isfinite(x).all()),
        "samples": samples,
        **stretch(x, n),
        **(stats(sim) if stats else {}),
    }
    sys.stdout.flush()
    print("RESULT " + json.dumps(result), flush=True)
