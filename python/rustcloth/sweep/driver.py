"""Running a sweep: expand and validate it, skip what is already on disk, hand the rest to a
backend, store each result as it comes, keep the index current."""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .local import LocalBackend
from .runner import RETRIED
from .spec import Run, Sweep, SweepError, check_picklable
from .store import Keyed, RunKey, Store, load_run, statuses

BACKENDS = ("local", "ray")

#: Called after each finished run with (record, done, total, failed).
Progress = Callable[[dict[str, Any], int, int, int], None]
#: Called once the runs are checked, before any starts, with (total, already complete).
Plan = Callable[[int, int], None]


@dataclass
class SweepResult:
    """What a sweep left in its folder: ``records`` (one dict per run, in sweep order, each
    with ``run``, ``run_id``, ``params``, ``status``, ``reason``, ``file`` and the run's
    ``info``), how many ran now and how many were ``skipped`` (already complete)."""

    out: str
    records: list[dict[str, Any]]
    ran: int = 0
    skipped: int = 0
    wall_s: float = 0.0
    backend: str = ""
    counts: dict[str, int] = field(default_factory=dict)

    def ok(self) -> list[dict[str, Any]]:
        return [r for r in self.records if r["status"] == "ok"]

    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.records if r["status"] not in ("ok", "filtered")]

    def load(self, record_or_id: Mapping[str, Any] | str) -> dict[str, np.ndarray]:
        """The arrays of an ``ok`` run, by record or run id."""
        run_id = record_or_id if isinstance(record_or_id, str) else record_or_id["run_id"]
        return load_run(self.out, run_id)


def make_backend(backend: str = "local", workers: int | None = None,
                 threads: int | None = None, address: str | None = None) -> Any:
    """A backend by name (``"local"`` or ``"ray"``)."""
    if backend == "local":
        if address is not None:
            raise SweepError("--address is for the ray backend")
        return LocalBackend(workers=workers, threads=threads)
    if backend == "ray":
        from .ray_backend import RayBackend

        if workers is not None:
            raise SweepError("the ray backend runs as many tasks as the cluster has CPUs for; "
                             "set threads (CPUs per task), not workers")
        return RayBackend(address=address, threads=threads)
    raise SweepError(f"unknown backend {backend!r}; expected one of {', '.join(BACKENDS)}")


def run_sweep(sweep: Sweep | Sequence[Run], out: str | os.PathLike[str],
              backend: str | Any = "local", *, workers: int | None = None,
              threads: int | None = None, address: str | None = None,
              retry_failed: bool = False, progress: Progress | None = None,
              on_plan: Plan | None = None, index_every: float = 1.0) -> SweepResult:
    """Run every run of ``sweep`` not already complete in ``out``; see docs/sweeps.md.

    ``backend``: ``"local"`` (``workers`` processes x ``threads`` rayon threads, default the
    available cores split evenly), ``"ray"`` (``address``: None starts a local Ray, ``"auto"``
    joins a running one; ``threads`` CPUs per task), or a backend object. ``retry_failed``:
    run ``diverged`` and ``error`` runs again too (``timeout`` and ``crashed`` always are).
    ``on_plan(total, complete)`` is called once every run is checked, before any starts;
    ``progress(record, done, total, failed)`` after each run. Only the runs' ids and
    parameters are kept: each run's scene is built again when it is sent (with ``scene_fn``,
    that calls the function a second time, and it must return the same scene).
    """
    start = time.perf_counter()
    runs: Sequence[Keyed]
    if isinstance(sweep, Sweep):
        # Every run is built and checked before any starts, but only its id and parameters
        # are kept: the scenes are built again one at a time as the backend takes them.
        runs = []
        for run in sweep.iter_runs():
            if not runs and getattr(backend, "name", backend) == "local":
                check_picklable([run])
            runs.append(RunKey(run.index, run.run_id, run.params))
    else:
        given = list(sweep)
        if getattr(backend, "name", backend) == "local":
            check_picklable(given)
        runs = given
    if not runs:
        raise SweepError("the sweep has no runs")
    store = Store(out)
    with store.lock():
        store.clean()
        if isinstance(sweep, Sweep):
            store.write_description(sweep.to_dict())
        records = store.completed(runs, retry_failed=retry_failed)
        todo = _Todo(sweep, [run for run in runs if run.run_id not in records])
        skipped = len(runs) - len(todo)
        if on_plan is not None:
            on_plan(len(runs), skipped)
        store.write_index(runs, records)
        engine = (make_backend(backend, workers, threads, address) if isinstance(backend, str)
                  else backend)
        failed = sum(1 for r in records.values() if r["status"] not in ("ok", "filtered"))
        done = skipped
        try:
            for run, result in engine.run(todo) if todo else ():
                record = store.write(run, result)
                records[run.run_id] = record
                done += 1
                failed += record["status"] not in ("ok", "filtered")
                _check_threads(record, engine)
                store.write_index(runs, records, every=index_every)
                if progress is not None:
                    progress(record, done, len(runs), failed)
        finally:
            store.write_index(runs, records)
            close = getattr(engine, "close", None)
            if close is not None and isinstance(backend, str):
                close()
    ordered = [records[r.run_id] for r in runs if r.run_id in records]
    return SweepResult(os.fspath(out), ordered, ran=len(todo), skipped=skipped,
                       wall_s=time.perf_counter() - start, backend=engine.describe(),
                       counts=statuses(ordered))


_warned: set[tuple[int | None, int]] = set()


def _check_threads(record: dict[str, Any], engine: Any) -> None:
    """Warn (once per mismatch) if a worker's rayon pool is not the size it was asked for:
    the results are the same, the speed is not."""
    got, wanted = record.get("threads"), getattr(engine, "threads", None)
    if got is None or wanted is None or got == wanted or record["status"] in RETRIED:
        return
    if (got, wanted) not in _warned:
        _warned.add((got, wanted))
        warnings.warn(f"a sweep worker has {got} rayon thread(s), not the {wanted} it asked for "
                      "(RAYON_NUM_THREADS was read before it was set?)", RuntimeWarning,
                      stacklevel=3)


class _Todo:
    """The runs still to do, in order: a sized iterable that builds each :class:`Run` (its
    scene) only when a backend takes it."""

    def __init__(self, sweep: Sweep | Sequence[Run], todo: Sequence[Keyed]) -> None:
        self.sweep, self.todo = sweep, todo

    def __len__(self) -> int:
        return len(self.todo)

    def __iter__(self) -> Iterator[Run]:
        if not isinstance(self.sweep, Sweep):
            yield from self.todo  # type: ignore[misc]
            return
        wanted = {p.run_id: p for p in self.todo}
        left = len(wanted)
        for run in self.sweep.iter_runs() if left else ():
            if run.run_id in wanted:
                yield run
                left -= 1
                if not left:
                    return
        if left:  # a scene function that gives another scene the second time
            raise SweepError(f"{left} run(s) were not the same when built again: scene_fn must "
                             "return the same scene for the same parameters")
