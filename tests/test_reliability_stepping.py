"""The clock, Ctrl-C, and what a step count may be.

``sim.time`` is accumulated step by step, so that changing ``dt`` at run time changes the
future and not the past (``steps * dt`` would rewrite it).

Stepping asks Python for signals every ~20 ms: Ctrl-C interrupts a long ``step(n)`` or
``advance`` with ``KeyboardInterrupt`` and the state at a step boundary, and ``advance`` then
drops the rest of its request. Counts are integers ``>= 0`` that fit 64 bits; anything else is
the package's own error naming ``n``."""

from __future__ import annotations

import faulthandler
import os
import signal
import threading
import time

import pytest
import rustcloth
from conftest import full_digest, python_ctrl_c, small_scene
from rustcloth import ParameterError, ParameterTypeError, Simulation


def test_changing_dt_does_not_rewrite_the_past():
    sim = Simulation(small_scene())
    sim.step(1000)
    assert sim.time == 1.0
    sim.dt = 0.0001
    assert sim.time == 1.0
    sim.step(250)
    assert sim.time == 1.0 + 250 * 0.0001  # the 250 new steps, each of the new dt
    assert sim.steps == 1250
    sim.dt = 0.002
    sim.advance(0.01)
    assert sim.time == pytest.approx(1.035, abs=1e-12)
    # A copy keeps the clock too.
    assert Simulation.from_state(sim.get_state()).time == sim.time


def test_the_clock_is_exact_while_dt_is_fixed():
    sim = Simulation(small_scene(dt=0.0001))
    sim.step(12345)
    assert sim.time == 12345 * 0.0001


class _Interrupter:
    """Sends SIGINT to this process from another thread once the main thread is inside the
    call (after `delay` s), the way a terminal's Ctrl-C arrives; records when it was sent.
    A fail-safe ends the process with a traceback if the call never returns (a regression
    would otherwise hang the suite)."""

    def __init__(self, delay: float = 0.3) -> None:
        self.sent_at: float | None = None
        self._timer = threading.Timer(delay, self._send)

    def _send(self) -> None:
        self.sent_at = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    def __enter__(self) -> _Interrupter:
        faulthandler.dump_traceback_later(120, exit=True)
        self._timer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._timer.cancel()
        self._timer.join()
        faulthandler.cancel_dump_traceback_later()


def _interrupted(call) -> float:
    """Runs `call` until Ctrl-C; returns the seconds from the signal to the KeyboardInterrupt."""
    with python_ctrl_c(), _Interrupter() as ctrl_c, pytest.raises(KeyboardInterrupt):
        call()
    raised_at = time.monotonic()
    assert ctrl_c.sent_at is not None
    return raised_at - ctrl_c.sent_at


def test_ctrl_c_interrupts_a_long_step_at_a_step_boundary():
    sim = Simulation(small_scene())
    latency = _interrupted(lambda: sim.step(2**31))
    assert latency < 5.0  # generous: the check runs every ~20 ms
    taken = sim.steps
    assert 0 < taken < 2**31
    twin = Simulation(small_scene())
    twin.step(taken)
    assert full_digest(sim) == full_digest(twin)
    sim.step(10)  # and it goes on as usual
    twin.step(10)
    assert full_digest(sim) == full_digest(twin)


def test_ctrl_c_interrupts_advance_and_drops_the_rest():
    sim = Simulation(small_scene())
    latency = _interrupted(lambda: sim.advance(1e6))
    assert latency < 5.0
    taken = sim.steps
    assert 0 < taken < 10**9
    twin = Simulation(small_scene())
    twin.step(taken)
    # The rest of the request is dropped, not owed: the next call starts from nothing.
    assert full_digest(sim, exclude=("accumulator",)) == full_digest(twin, exclude=("accumulator",))
    assert sim.get_state()["accumulator"] < sim.dt
    assert sim.advance(0) == 0
    assert sim.steps == taken


def test_ctrl_c_with_held_substeps_keeps_a_step_boundary():
    # Springs too stiff for the step: the watchdog retries an early step with more substeps and
    # holds them for the rest of the run. An interrupt still lands between whole steps, and
    # the watchdog's memory is that of a twin stepped as far.
    scene = small_scene(
        cloth={"k_structural": 2e4},
        watchdog={"max_stretch": 1.2, "on_trouble": "substep", "hold_steps": 4_000_000_000},
    )
    with pytest.warns(rustcloth.StabilityWarning):
        sim = Simulation(scene)
    _interrupted(lambda: sim.step(2**40))
    with pytest.warns(rustcloth.StabilityWarning):
        twin = Simulation(scene)
    twin.step(sim.steps)
    assert full_digest(sim) == full_digest(twin)
    assert sim.watchdog_stats()["retried"] >= 1 and sim.get_state()["watchdog"]["hold"]


BAD_COUNTS = [
    # (n, exception, the exact class the package raises)
    (2**63, ValueError, ParameterError),
    (2**64, ValueError, ParameterError),
    (2**70, ValueError, ParameterError),
    (-1, ValueError, ParameterError),
    (-(2**63) - 1, ValueError, ParameterError),
    (1.0, TypeError, ParameterTypeError),
    (float("nan"), TypeError, ParameterTypeError),
    (True, TypeError, ParameterTypeError),
    (False, TypeError, ParameterTypeError),
    ("3", TypeError, ParameterTypeError),
    (b"3", TypeError, ParameterTypeError),
    ([3], TypeError, ParameterTypeError),
]


@pytest.mark.parametrize(("n", "builtin", "exception"), BAD_COUNTS, ids=repr)
def test_bad_step_counts_are_refused_naming_n(n, builtin, exception):
    sim = Simulation(small_scene())
    sim.step(3)
    before = full_digest(sim)
    with pytest.raises(builtin) as info:
        sim.step(n)
    assert type(info.value) is exception
    assert info.value.parameter == "n" and str(info.value).startswith("n: ")
    assert full_digest(sim) == before


def test_step_none_is_refused():
    sim = Simulation(small_scene())
    before = full_digest(sim)
    with pytest.raises(ParameterTypeError, match="^n: "):
        sim.step(None)
    assert full_digest(sim) == before


def test_step_counts_of_every_integer_type_are_accepted():
    import numpy as np

    sim = Simulation(small_scene())
    for n in (0, 1, np.int64(2), np.uint8(3), np.int32(0)):
        sim.step(n)
    assert sim.steps == 6
    sim.step()
    assert sim.steps == 7
