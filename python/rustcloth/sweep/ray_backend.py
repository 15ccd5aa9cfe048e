"""The ``ray`` backend (``pip install rustcloth[ray]``): each run is one Ray task.

The task is :func:`~rustcloth.sweep.runner.execute` itself, submitted with ``num_cpus =
threads`` and ``runtime_env={"env_vars": {"RAYON_NUM_THREADS": threads}}``, so Ray starts (and
reuses) worker processes whose rayon pool has that size; what is sent per task is the run (its
scene dict, step count and record spec, about a kilobyte) and what comes back is its
:class:`RunResult`, numpy arrays through Ray's object store. The driver writes the files, so on
a cluster the results live where the driver runs.

The driver keeps at most as many tasks in flight as the cluster has CPUs for, so a task starts
about when it is submitted: the run's own check stops it at its time limit, and a task still
running ``time_limit + grace`` after submission is cancelled with ``ray.cancel(force=True)``,
which kills its worker process. Ray's task retries are off (``max_retries=0``): a task whose
worker dies is recorded as ``crashed`` and runs again when the sweep is resumed.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterator, Sequence
from typing import Any

from .runner import RunResult, execute
from .spec import Run, SweepError


class RayBackend:
    """Runs on the Ray cluster this process is connected to; if none, ``ray.init(address)``
    (``address=None`` starts a local Ray on this machine; ``"auto"`` or ``"ray://host:10001"``
    connects to a running cluster), shut down again after the sweep."""

    name = "ray"

    def __init__(self, address: str | None = None, threads: int | None = None,
                 grace: float = 10.0, init_options: dict[str, Any] | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ImportError("the ray backend needs Ray: pip install 'rustcloth[ray]'") from None
        self._ray = ray
        self.threads = threads or 1
        if self.threads < 1:
            raise SweepError(f"threads must be >= 1, got {self.threads}")
        self.grace = grace
        self._owns = not ray.is_initialized()
        if self._owns:
            options = {"include_dashboard": False, "log_to_driver": False,
                       **(init_options or {})}
            ray.init(address=address, **options)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.slots = max(1, cpus // self.threads)
        self.workers = self.slots
        self._task = ray.remote(execute).options(
            num_cpus=self.threads,
            max_retries=0,
            runtime_env={"env_vars": {"RAYON_NUM_THREADS": str(self.threads)}},
        )

    def describe(self) -> str:
        return f"ray: {self.slots} task(s) at a time x {self.threads} thread(s)"

    def run(self, runs: Sequence[Run]) -> Iterator[tuple[Run, RunResult]]:
        ray = self._ray
        pending = deque(runs)
        inflight: dict[Any, tuple[Run, float]] = {}
        try:
            while pending or inflight:
                self._submit(pending, inflight)
                ready, rest = ray.wait(list(inflight), num_returns=1,
                                       timeout=self._next_deadline(inflight))
                if ready and rest:  # and whatever else is done by now
                    ready += ray.wait(rest, num_returns=len(rest), timeout=0)[0]
                finished = []
                for ref in ready:
                    run, sent = inflight.pop(ref)
                    try:
                        finished.append((run, ray.get(ref)))
                    except ray.exceptions.RayError as err:
                        finished.append((run, RunResult(
                            run.run_id, "crashed", _one_line(err),
                            info={"wall_s": time.monotonic() - sent})))
                self._submit(pending, inflight)  # before the results are stored
                yield from finished
                now = time.monotonic()
                for ref, (run, sent) in list(inflight.items()):
                    if run.time_limit is not None and now - sent > run.time_limit + self.grace:
                        ray.cancel(ref, force=True)
                        del inflight[ref]
                        yield run, RunResult(
                            run.run_id, "timeout",
                            f"over the {run.time_limit:g} s time limit; cancelled after "
                            f"{now - sent:.1f} s", info={"wall_s": now - sent})
        finally:
            for ref in inflight:
                ray.cancel(ref, force=True)

    def _submit(self, pending: deque[Run], inflight: dict[Any, tuple[Run, float]]) -> None:
        while pending and len(inflight) < self.slots:
            run = pending.popleft()
            inflight[self._task.remote(run, self.threads)] = (run, time.monotonic())

    def _next_deadline(self, inflight: dict[Any, tuple[Run, float]]) -> float:
        now, soonest = time.monotonic(), 1.0
        for run, sent in inflight.values():
            if run.time_limit is not None:
                soonest = min(soonest, sent + run.time_limit + self.grace - now)
        return max(soonest, 0.0)

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0] if text else ''}"
