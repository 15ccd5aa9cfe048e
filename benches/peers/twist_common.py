"""What both twist peers share: the checkpoint sample (intersections by ``tri_check``, and the
stretch of the mesh's edges against the first sample's) and the ``RESULT`` line."""

from __future__ import annotations

import json
import resource
import sys
import time
from typing import Any

import numpy as np
import tri_check

_rest: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _edges(triangles: np.ndarray) -> np.ndarray:
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def sample(frame: int, positions: np.ndarray, triangles: np.ndarray) -> dict[str, Any]:
    """Intersections at ``frame``, and the triangle edges' stretch ``l / L - 1`` (mean and
    largest), ``L`` taken from the first call (frame 0, the flat start)."""
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if 0 not in _rest:
        e = _edges(triangles)
        _rest[0] = (e, np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1))
    e, rest = _rest[0]
    strain = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1) / rest - 1.0
    t0 = time.perf_counter()
    crossings = tri_check.count(x, triangles)
    return {
        "frame": frame,
        "intersections": crossings,
        "check_s": time.perf_counter() - t0,
        "mean_stretch": float(strain.mean()),
        "max_stretch": float(strain.max()),
    }


def emit(result: dict[str, Any]) -> None:
    """Adds the per-frame summary (frames after the first, which pays for allocations and,
    in Warp, kernel compilation) and prints the ``RESULT`` line."""
    walls = result["walls"][1:] or result["walls"]
    with open("/proc/loadavg") as f:
        load = float(f.read().split()[0])
    result.update(
        ms_per_frame=1e3 * float(np.mean(walls)),
        ms_per_frame_median=1e3 * float(np.median(walls)),
        ms_per_frame_min=1e3 * float(np.min(walls)),
        load=load,
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    )
    sys.stdout.flush()
    print("RESULT " + json.dumps(result), flush=True)
