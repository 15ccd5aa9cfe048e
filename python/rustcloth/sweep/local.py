"""The ``local`` backend: a pool of worker processes on this machine, standard library only.

Each worker is a fresh interpreter (the ``spawn`` start method: a forked child of a driver whose
rayon pool already exists would inherit a pool without threads) that sets
``RAYON_NUM_THREADS`` before its first step, reports the pool size it got, then runs one run
at a time. The driver keeps one run in flight per worker, so a run starts the moment it is
sent; a run still going ``time_limit + grace`` seconds after it was sent (stuck in a user
function, say) is killed with its worker, recorded as ``timeout``, and the worker replaced. A
worker that dies (a crash, the OOM killer) is recorded as ``crashed`` and replaced. Workers
die with the driver (``PR_SET_PDEATHSIG`` on Linux; elsewhere they exit at their next read).
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import sys
import time
from collections.abc import Iterator
from multiprocessing.connection import Connection, wait
from typing import Any

from .runner import Pending, RunResult, Runs, execute, rayon_threads
from .spec import Run, SweepError


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity), not every core of the machine."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _die_with_parent() -> None:
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:
            pass


def _worker(conn: Connection, threads: int) -> None:
    """A worker's life: size the rayon pool, say how it went, then run what comes."""
    _die_with_parent()
    os.environ["RAYON_NUM_THREADS"] = str(threads)  # read by rayon when its pool is built
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle
    conn.send(("ready", rayon_threads()))
    while True:
        try:
            run = conn.recv()
        except (EOFError, OSError):
            return
        if run is None:
            return
        result = execute(run, threads)
        try:
            conn.send(("done", result))
        except (BrokenPipeError, OSError):
            return


class _Worker:
    def __init__(self, ctx: Any, threads: int) -> None:
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker, args=(child, threads), daemon=True)
        self.process.start()
        child.close()
        self.run: Run | None = None
        self.sent = 0.0
        self.threads: int | None = None
        self.ready = False

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join(5)
        self.conn.close()

    def exit_reason(self) -> str:
        self.process.join(1)
        code = self.process.exitcode
        if code is not None and code < 0:
            try:
                return f"worker killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"worker killed by signal {-code}"
        return f"worker exited with code {code}"


class LocalBackend:
    """``workers`` processes with ``threads`` rayon threads each (default: the available
    cores, split evenly). ``grace``: seconds past a run's time limit before its worker is
    killed (the run's own check stops it at the limit unless it is stuck)."""

    name = "local"

    def __init__(self, workers: int | None = None, threads: int | None = None,
                 grace: float = 2.0) -> None:
        cores = available_cores()
        if workers is None:
            workers = max(1, cores // (threads or 1))
        if threads is None:
            threads = max(1, cores // workers)
        if workers < 1 or threads < 1:
            raise SweepError(f"workers and threads must be >= 1, got {workers} and {threads}")
        self.workers, self.threads, self.grace = workers, threads, grace
        self.slots = workers
        self.observed_threads: list[int | None] = []
        #: Seconds from the start of run() until every worker was ready (the last sweep's).
        self.startup_s: float | None = None

    def describe(self) -> str:
        return f"local: {self.workers} worker(s) x {self.threads} thread(s)"

    def run(self, runs: Runs) -> Iterator[tuple[Run, RunResult]]:
        """Run everything, yielding each run with its result as it finishes."""
        ctx = mp.get_context("spawn")
        self.startup_s = None
        pending = Pending(runs)
        start = time.monotonic()
        pool = [_Worker(ctx, self.threads) for _ in range(min(self.workers, len(runs)))]

        def feed() -> None:  # every idle worker gets the next run
            for worker in pool:
                if worker.ready and worker.run is None and pending:
                    worker.run, worker.sent = pending.popleft(), time.monotonic()
                    worker.conn.send(worker.run)
            if self.startup_s is None and all(w.ready for w in pool):
                self.startup_s = time.monotonic() - start

        try:
            while pending or any(w.run is not None for w in pool):
                feed()
                timeout = self._next_deadline(pool)
                ready = wait([w.conn for w in pool] + [w.process.sentinel for w in pool],
                             timeout)
                finished = []
                for worker in list(pool):
                    result = self._poll(worker, worker.conn in ready
                                        or worker.process.sentinel in ready)
                    if result is not None:
                        finished.append(result)
                    if worker.run is None and not worker.process.is_alive():
                        if not worker.ready:  # the environment, not a run: do not loop
                            raise RuntimeError(
                                f"a sweep worker failed to start ({worker.exit_reason()}; its "
                                "error is above). A script that runs a sweep must start it "
                                "under `if __name__ == '__main__':`, as workers import it")
                        worker.kill()  # killed over time, or crashed: replace it if needed
                        pool.remove(worker)
                        if len(pending) > len(pool) - sum(w.run is not None for w in pool):
                            pool.append(_Worker(ctx, self.threads))
                feed()  # before the results are stored, so no worker waits for the disk
                yield from finished
        finally:
            for worker in pool:
                if worker.run is None and worker.process.is_alive():
                    try:
                        worker.conn.send(None)
                    except OSError:
                        pass
            deadline = time.monotonic() + 2
            for worker in pool:
                if worker.run is None:
                    worker.process.join(max(0.0, deadline - time.monotonic()))
                worker.kill()

    def _next_deadline(self, pool: list[_Worker]) -> float:
        now, soonest = time.monotonic(), 1.0
        for w in pool:
            if w.run is not None and w.run.time_limit is not None:
                soonest = min(soonest, w.sent + w.run.time_limit + self.grace - now)
        return max(soonest, 0.0)

    def _poll(self, worker: _Worker, signalled: bool) -> tuple[Run, RunResult] | None:
        """A finished run of this worker, if any: a result, a death, or a run over time."""
        if signalled:
            try:
                while worker.conn.poll():
                    kind, payload = worker.conn.recv()
                    if kind == "ready":
                        worker.ready, worker.threads = True, payload
                        self.observed_threads.append(payload)
                    elif kind == "done" and worker.run is not None:
                        run, worker.run = worker.run, None
                        return run, payload
            except (EOFError, OSError):
                pass
            if worker.run is not None and not worker.process.is_alive():
                run, worker.run = worker.run, None
                return run, RunResult(run.run_id, "crashed", worker.exit_reason(),
                                      info={"wall_s": time.monotonic() - worker.sent})
        current = worker.run
        if current is not None and current.time_limit is not None:
            elapsed = time.monotonic() - worker.sent
            if elapsed > current.time_limit + self.grace:
                worker.run = None
                worker.process.kill()
                worker.process.join(5)
                return current, RunResult(current.run_id, "timeout",
                                          f"over the {current.time_limit:g} s time limit; killed "
                                          f"after {elapsed:.1f} s", info={"wall_s": elapsed})
        return None
