"""The ``ray`` backend (``pip install rustcloth[ray]``): each run is one Ray task.

The task runs :func:`~rustcloth.sweep.runner.execute`, submitted with ``num_cpus =
threads`` and ``runtime_env={"env_vars": {"RAYON_NUM_THREADS": threads}}``, so Ray starts (and
reuses) worker processes whose rayon pool has that size; what is sent per task is the run (its
scene dict, step count and record spec, about a kilobyte) and what comes back is its
:class:`RunResult`, numpy arrays through Ray's object store. The driver writes the files, so on
a cluster the results live where the driver runs.

The driver keeps at most as many tasks in flight as the cluster has CPUs for. A task is a
streaming generator that first says it has started, then returns the result: the run's own
check stops it at its time limit, and a task still running ``time_limit + grace`` after it
started (stuck where it cannot check) is cancelled with ``ray.cancel(force=True)``, which kills
its worker process. Ray's task retries are off (``max_retries=0``): a task whose
worker dies is recorded as ``crashed`` and runs again when the sweep is resumed.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

from .runner import Pending, RunResult, Runs, execute
from .spec import Run, SweepError

STARTED = "started"


def execute_streaming(run: Run, threads: int) -> Iterator[Any]:
    """The Ray task: says it has started (so the driver's clock for the time limit starts
    with the run, not with the wait for a worker), then returns the run's result."""
    yield STARTED
    yield execute(run, threads)


class _Task:
    __slots__ = ("run", "sent", "started")

    def __init__(self, run: Run) -> None:
        self.run, self.sent = run, time.monotonic()
        self.started: float | None = None

    def deadline(self, grace: float) -> float | None:
        if self.run.time_limit is None or self.started is None:
            return None
        return self.started + self.run.time_limit + grace


class RayBackend:
    """Runs on the Ray cluster this process is connected to; if none, ``ray.init(address)``
    (``address=None`` starts a local Ray on this machine; ``"auto"`` or ``"ray://host:10001"``
    connects to a running cluster), shut down again after the sweep. ``grace``: seconds past a
    run's time limit, counted from the moment its task started, before the task is cancelled
    (the run's own check stops it at the limit unless it is stuck)."""

    name = "ray"

    def __init__(self, address: str | None = None, threads: int | None = None,
                 grace: float = 2.0, init_options: dict[str, Any] | None = None) -> None:
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
        cpus = int(ray.cluster_resources().get("CPU", 1))  # type: ignore[no-untyped-call]
        self.slots = max(1, cpus // self.threads)
        self.workers = self.slots
        self._task = ray.remote(execute_streaming).options(
            num_returns="streaming",
            num_cpus=self.threads,
            max_retries=0,
            runtime_env={"env_vars": {"RAYON_NUM_THREADS": str(self.threads)}},
        )

    def describe(self) -> str:
        return f"ray: {self.slots} task(s) at a time x {self.threads} thread(s)"

    def run(self, runs: Runs) -> Iterator[tuple[Run, RunResult]]:
        ray = self._ray
        pending = Pending(runs)
        inflight: dict[Any, _Task] = {}  # the task's ObjectRefGenerator: its state
        try:
            while pending or inflight:
                self._submit(pending, inflight)
                ready, rest = ray.wait(list(inflight), num_returns=1,
                                       timeout=self._next_deadline(inflight))
                if ready and rest:  # and whatever else is done by now
                    ready += ray.wait(rest, num_returns=len(rest), timeout=0)[0]
                finished = [done for gen in ready if (done := self._advance(gen, inflight))]
                now = time.monotonic()
                for gen, task in list(inflight.items()):
                    deadline = task.deadline(self.grace)
                    if deadline is not None and now > deadline:
                        ray.cancel(gen, force=True)
                        del inflight[gen]
                        elapsed = now - task.started  # type: ignore[operator]
                        finished.append((task.run, RunResult(
                            task.run.run_id, "timeout",
                            f"over the {task.run.time_limit:g} s time limit; cancelled after "
                            f"{elapsed:.1f} s", info={"wall_s": elapsed})))
                self._submit(pending, inflight)  # before the results are stored
                yield from finished
        finally:
            for gen in inflight:
                ray.cancel(gen, force=True)

    def _advance(self, gen: Any, inflight: dict[Any, _Task]) -> tuple[Run, RunResult] | None:
        """Take the next item a task has produced: its start, or its result (or its death)."""
        ray, task = self._ray, inflight[gen]
        try:
            value = ray.get(next(gen))
        except (StopIteration, ray.exceptions.RayError) as err:
            del inflight[gen]
            reason = _one_line(err) if isinstance(err, ray.exceptions.RayError) else \
                "the task ended without a result"
            return task.run, RunResult(task.run.run_id, "crashed", reason,
                                       info={"wall_s": time.monotonic() - task.sent})
        if isinstance(value, str) and value == STARTED:
            task.started = time.monotonic()
            return None
        del inflight[gen]
        return task.run, value

    def _submit(self, pending: Pending, inflight: dict[Any, _Task]) -> None:
        while pending and len(inflight) < self.slots:
            run = pending.popleft()
            inflight[self._task.remote(run, self.threads)] = _Task(run)

    def _next_deadline(self, inflight: dict[Any, _Task]) -> float:
        now, soonest = time.monotonic(), 1.0
        for task in inflight.values():
            deadline = task.deadline(self.grace)
            if deadline is not None:
                soonest = min(soonest, deadline - now)
        return max(soonest, 0.0)

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0] if text else ''}"
