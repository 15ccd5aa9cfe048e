"""One run, in whatever process it lands in: :func:`execute` builds the simulation from the
run's scene, steps it, records its frames and returns a :class:`RunResult`. Every backend calls
this same function, so a run's arrays depend only on the run.
"""

from __future__ import annotations

import os
import time
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .._core import thread_count
from ..errors import SimulationDiverged
from ..simulation import Simulation
from .spec import Run

#: Statuses. A run that ends ``ok``, ``filtered``, ``diverged`` or ``error`` would end the
#: same way again (the solver is deterministic), so a resumed sweep keeps it; ``timeout`` and
#: ``crashed`` depend on the machine and are run again.
COMPLETE = ("ok", "filtered", "diverged", "error")
RETRIED = ("timeout", "crashed")
STATUSES = COMPLETE + RETRIED

# At most this many steps between two checks of the time limit.
_CHUNK = 256


@dataclass
class RunResult:
    """What a run produced. ``arrays`` is empty unless ``status == "ok"``; ``info`` has
    ``wall_s`` and ``cpu_s`` (the run's wall and process CPU time), ``steps`` (taken),
    ``threads`` (the worker's rayon threads), ``peak_stretch``, ``energy`` (final total, J),
    ``warnings`` and, for an error, ``traceback``."""

    run_id: str
    status: str
    reason: str = ""
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)


class _TimeLimit(Exception):
    pass


class Runs(Protocol):
    """What a backend's ``run`` takes: runs it can count and take in order (a list, or the
    driver's lazy list that builds each run's scene when it is taken)."""

    def __len__(self) -> int: ...
    def __iter__(self) -> Iterator[Run]: ...


class Pending:
    """The runs a backend has yet to send, taken from ``runs`` one at a time."""

    def __init__(self, runs: Runs) -> None:
        self._left = len(runs)
        self._runs = iter(runs)

    def __len__(self) -> int:
        return self._left

    def popleft(self) -> Run:
        run = next(self._runs)
        self._left -= 1
        return run


def rayon_threads() -> int:
    """The size of this process's rayon pool, as rayon itself reports it (rayon builds its
    global pool on first use, reading ``RAYON_NUM_THREADS`` then, so a worker that set the
    variable too late sees the size it got, not the one it asked for). A sweep worker calls it
    before its first run."""
    return thread_count()


def _frames(steps: int, every: int) -> list[int]:
    if every <= 0:
        return [steps]
    frames = list(range(0, steps + 1, every))
    if frames[-1] != steps:
        frames.append(steps)
    return frames


def execute(run: Run, threads: int | None = None) -> RunResult:
    """Run one simulation and return its result; never raises for the run's own failures.

    A :class:`~rustcloth.SimulationDiverged` gives status ``"diverged"``, any other exception
    (in the solver, a record function or a filter) ``"error"``, the run's ``time_limit``
    ``"timeout"``, a filter ``"filtered"``. Warnings (a ``StabilityWarning``) are recorded in
    ``info["warnings"]``, not raised. ``threads`` is what the caller asked the worker's rayon
    pool to be; it is only reported.
    """
    start, cpu_start = time.perf_counter(), time.process_time()
    info: dict[str, Any] = {"threads": rayon_threads(), "pid": os.getpid()}
    if threads is not None:
        info["threads_requested"] = threads
    record = run.record
    frames = _frames(run.steps, record.every)
    out: dict[str, list[Any]] = {"steps": [], "time": []}
    status, reason, arrays = "ok", "", {}
    sim: Simulation | None = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            sim = Simulation(run.scene)
            for frame in frames:
                while sim.steps < frame:
                    if run.time_limit is not None and time.perf_counter() - start > run.time_limit:
                        raise _TimeLimit
                    sim.step(min(frame - sim.steps, _CHUNK))
                _take_frame(sim, record, out)
            arrays = _stack(out)
            if record.final_mesh:
                arrays["final_positions"] = sim.positions
                arrays["triangles"] = sim.triangles
            status, reason = _filter(run, arrays)
        except SimulationDiverged as err:
            status, reason = "diverged", f"{err.reason} at step {err.step} (particle " \
                f"{err.particle}, {err.substeps} substeps)"
        except _TimeLimit:
            status = "timeout"
            reason = (f"over the {run.time_limit:g} s time limit at step "
                      f"{sim.steps if sim else 0} of {run.steps}")
        except Exception as err:  # the run's failure, recorded; the sweep goes on
            status, reason = "error", f"{type(err).__name__}: {err}"
            info["traceback"] = traceback.format_exc()
    info["warnings"] = sorted({f"{w.category.__name__}: {w.message}" for w in caught})
    if sim is not None:
        info["steps"] = sim.steps
    if "max_stretch" in arrays:
        info["peak_stretch"] = float(np.max(arrays["max_stretch"]))
    if "energy" in arrays:
        info["energy"] = float(arrays["energy"][-1].sum())
    info["wall_s"] = time.perf_counter() - start
    info["cpu_s"] = time.process_time() - cpu_start
    if status != "ok":
        arrays = {}
    return RunResult(run.run_id, status, reason, arrays, info)


def _take_frame(sim: Simulation, record: Any, out: dict[str, list[Any]]) -> None:
    out["steps"].append(sim.steps)
    out["time"].append(sim.time)
    if record.positions:
        out.setdefault("positions", []).append(sim.positions)
    if record.energy:
        out.setdefault("energy", []).append(tuple(sim.energy()))
    if record.max_stretch:
        out.setdefault("max_stretch", []).append(sim.max_stretch())
    for name, fn in record.functions.items():
        try:
            value = np.asarray(fn(sim))
        except Exception as err:
            raise RuntimeError(f"record function {name!r} raised {type(err).__name__}: "
                               f"{err}") from err
        out.setdefault(name, []).append(value)


def _stack(out: dict[str, list[Any]]) -> dict[str, np.ndarray]:
    arrays = {"steps": np.asarray(out.pop("steps"), dtype=np.int64),
              "time": np.asarray(out.pop("time"), dtype=np.float64)}
    if "positions" in out:
        arrays["positions"] = np.stack(out.pop("positions")).astype(np.float32, copy=False)
    if "energy" in out:
        arrays["energy"] = np.asarray(out.pop("energy"), dtype=np.float64)
    if "max_stretch" in out:
        arrays["max_stretch"] = np.asarray(out.pop("max_stretch"), dtype=np.float64)
    for name, values in out.items():
        try:
            arrays[name] = np.stack(values)
        except ValueError as err:
            raise ValueError(f"record function {name!r} returned arrays of different shapes "
                             f"at different frames: {err}") from None
    return arrays


def _filter(run: Run, arrays: dict[str, np.ndarray]) -> tuple[str, str]:
    bound = run.filters.max_stretch
    if bound is not None and "max_stretch" in arrays:
        peak = float(np.max(arrays["max_stretch"]))
        if peak > bound:
            return "filtered", f"max stretch {peak:.4g} > {bound:g}"
    if run.filters.reject is not None:
        verdict = run.filters.reject(arrays)
        if verdict:
            return "filtered", str(verdict)
    return "ok", ""
