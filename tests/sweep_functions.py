"""Record functions for the sweep tests: one that behaves, one that raises, one that hangs and one
that crashes its process. Standard library and numpy only, so a worker can load this file by
path (``"tests/sweep_functions.py:name"``) as well as by module name."""

from __future__ import annotations

import os
import time


def lowest_point(sim) -> float:
    return float(sim.positions[:, 1].min())


def fragile(sim) -> float:
    """Raises for runs with a large dt: the 'raising run' of the failure tests."""
    if sim.dt > 0.0015:
        raise ValueError(f"dt = {sim.dt} is too large for this probe")
    return float(sim.positions[:, 1].mean())


def stuck_when_soft(sim) -> float:
    """Never returns for soft cloth: a run only a kill can stop."""
    if sim.steps > 0 and sim.scene.cloth["k_bend"] < 5.0:
        time.sleep(600)
    return 0.0


def crash_when_soft(sim) -> float:
    """Kills its own process for soft cloth: a worker that dies mid-run."""
    if sim.steps > 0 and sim.scene.cloth["k_bend"] < 5.0:
        os.kill(os.getpid(), 9)
    return 0.0


def reject_high(arrays) -> str | None:
    """A quality filter: drops runs whose cloth's lowest point ends above y = 0.7494 m (two of
    the six runs of the small sweep, both with damping 0.01)."""
    low = float(arrays["lowest"][-1])
    return f"lowest point {low:.5f} m is above 0.7494 m" if low > 0.7494 else None
