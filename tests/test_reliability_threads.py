"""One simulation, several threads.

Every call takes a fair lock for its whole length: calls from other threads wait their turn
(without the GIL) and see the state at a call boundary, and a reader is not starved by a thread
that steps; a call from the thread already inside a call (a signal handler during ``step``)
raises ``SimulationBusy`` instead of deadlocking. These tests check what a reader sees, that it
is not starved (a count, not a time), and the signal handler."""

from __future__ import annotations

import faulthandler
import hashlib
import signal
import threading
import time

import numpy as np
import pytest
from conftest import full_digest, small_scene
from rustcloth import RustclothError, Simulation
from rustcloth.errors import SimulationBusy

READS_WANTED = 100
"""Successful reads of each kind the reader must make while the physics thread runs: far
below what the fair lock gives (about 2,100 of each in the 5,000 calls of eight steps, on
two cores idle or beside three busy loops), far above the zero of the starved reader."""

STEPS_A_CALL = 8
"""Steps in each of the physics thread's calls. The reader gets a turn at a call's end when
it is waiting then; a reader descheduled for a time slice on a busy machine misses every call
made meanwhile, so calls of one 24 x 24 step (tens of microseconds) left it 200-1,300 reads of
each kind in 5,000 calls, and 88 in a `make test` beside a Rust build."""



def _h(array: np.ndarray) -> bytes:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).digest()


def _race(
    sim: Simulation, call, calls: int, twin_states: dict[bytes, int], full: dict[str, int]
) -> None:
    """A physics thread makes `call(sim)` up to `calls` times (fewer once the reader has its
    reads) while this thread reads
    positions and whole states; every read must be a state the twin passed through at a call
    boundary, in order, and the reader must get READS_WANTED of each within 60 s."""
    errors: list[BaseException] = []
    reads = {"positions": 0, "state": 0}
    stop = threading.Event()

    def physics() -> None:
        try:
            for _ in range(calls):
                if stop.is_set() or min(reads.values()) >= READS_WANTED:
                    return
                call(sim)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    worker = threading.Thread(target=physics)
    faulthandler.dump_traceback_later(120, exit=True)  # a deadlock fails, never hangs
    worker.start()
    last = -1
    deadline = time.monotonic() + 60
    try:
        while worker.is_alive() and time.monotonic() < deadline:
            if reads["positions"] <= reads["state"]:
                index = twin_states.get(_h(sim.positions))
                kind = "positions"
            else:
                index = full.get(full_digest(sim))
                kind = "state"
            assert index is not None, f"a {kind} read matches no state of the twin"
            assert index >= last, "a read went back in time"
            last = index
            reads[kind] += 1
    finally:
        stop.set()
        worker.join()
        faulthandler.cancel_dump_traceback_later()
    assert not errors, errors
    assert min(reads.values()) >= READS_WANTED, reads


def _twin_states(scene, call, calls: int) -> tuple[dict[bytes, int], dict[str, int]]:
    twin = Simulation(scene)
    positions, full = {_h(twin.positions): 0}, {full_digest(twin): 0}
    for k in range(1, calls + 1):
        call(twin)
        positions.setdefault(_h(twin.positions), k)
        full.setdefault(full_digest(twin), k)
    return positions, full


def test_a_reader_is_not_starved_by_a_stepping_thread():
    scene = small_scene(cloth={"nx": 24, "ny": 24})

    def call(s: Simulation) -> None:
        s.step(STEPS_A_CALL)

    calls = 5000
    _race(Simulation(scene), call, calls, *_twin_states(scene, call, calls))


def test_reads_during_advance_see_whole_frames():
    # A reader never sees the middle of an advance call: each read is the state after a
    # whole number of frames.
    scene = small_scene(cloth={"nx": 24, "ny": 24})

    def call(s: Simulation) -> None:
        s.advance(1 / 60)

    frames = 2000
    _race(Simulation(scene), call, frames, *_twin_states(scene, call, frames))


def test_a_signal_handler_touching_the_simulation_gets_simulation_busy():
    # SIGALRM arrives while the main thread is inside step(); its handler runs on that same
    # thread, between steps, and reads the simulation: the lock is the thread's own, so the
    # read raises SimulationBusy (waiting would deadlock), and the exception ends the step at
    # a step boundary.
    sim = Simulation(small_scene())
    seen: list[BaseException] = []

    def handler(signum, frame):
        try:
            _ = sim.positions
        except BaseException as e:
            seen.append(e)
            raise

    previous = signal.signal(signal.SIGALRM, handler)
    faulthandler.dump_traceback_later(120, exit=True)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.2)
        with pytest.raises(SimulationBusy) as info:
            sim.step(2**40)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        faulthandler.cancel_dump_traceback_later()
    assert len(seen) == 1 and seen[0] is info.value
    assert isinstance(info.value, RustclothError) and isinstance(info.value, RuntimeError)
    assert 0 < sim.steps < 2**40
    twin = Simulation(small_scene())
    twin.step(sim.steps)
    assert full_digest(sim) == full_digest(twin)
    sim.step(5)  # the lock was released: the simulation goes on
    assert sim.steps == twin.steps + 5
