"""Stepping the simulation for the viewer: the steps a frame owes, within a wall-time budget
when running live (so slow rendering slows the picture, not the physics), every one of them
when rendering offline; divergences go to :class:`~.recovery.Recovery`."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from ..drivers import Driver
from ..errors import SimulationDiverged
from .recovery import Recovery

MIN_BUDGET_S = 1.0 / 120.0
"""Physics may always take half of a 60 Hz frame."""
MAX_FAILURES_PER_FRAME = 3
"""After this many divergences in one frame the frame's remaining steps are dropped."""


@dataclass
class FramePhysics:
    """What the physics did in one frame."""

    steps: int = 0
    seconds: float = 0.0
    """Wall time spent stepping."""
    notices: list[str] = field(default_factory=list)
    """One line per divergence, saying what happened and what was done."""


class Stepper:
    """Runs the steps of ``dt`` that the frames' simulated time adds up to, keeping the
    remainder for the next frame (as ``Simulation.advance`` does, but with a budget)."""

    def __init__(self, sim: Any, driver: Driver | None = None) -> None:
        self.sim = sim
        self.driver = driver
        """Run before every step (the scene's scripted motion), or None."""
        self.recovery = Recovery(sim)
        self.owed = 0.0
        self.step_s = 1e-4
        """Wall seconds per step, smoothed: sizes the chunks a budget is spent in."""
        self._history: deque[tuple[float, float, float]] = deque()

    def run(self, seconds: float, budget_s: float | None) -> FramePhysics:
        """Advance by ``seconds`` of simulated time; with ``budget_s``, stop stepping once
        that much wall time is spent and drop what is left (the run falls behind real time),
        except for less than one step."""
        sim = self.sim
        dt = sim.dt
        self.owed += seconds
        report = FramePhysics()
        start = time.perf_counter()
        deadline = start + budget_s if budget_s is not None else float("inf")
        failures = 0
        while (n := int(self.owed / dt + 1e-9)) > 0:
            if budget_s is not None:
                left = deadline - time.perf_counter()
                if left <= 0.0:
                    break
                n = min(n, max(1, int(0.5 * left / self.step_s)))
            before, t0 = sim.steps, time.perf_counter()
            try:
                self._step(n)
            except SimulationDiverged as err:
                report.notices.append(self.recovery.handle(err))
                failures += 1
            done = sim.steps - before
            self.owed -= done * dt
            report.steps += max(done, 0)
            if done > 0:
                self.step_s = 0.7 * self.step_s + 0.3 * (time.perf_counter() - t0) / done
            if failures >= MAX_FAILURES_PER_FRAME:
                break
        if budget_s is not None or failures >= MAX_FAILURES_PER_FRAME:
            self.owed = min(self.owed, dt)
        if report.steps and (notice := self.recovery.runaway()) is not None:
            report.notices.append(notice)
        report.seconds = time.perf_counter() - start
        self.recovery.after_steps()
        self._remember(seconds, report)
        return report

    def _step(self, n: int) -> None:
        if self.driver is None:
            self.sim.step(n)
            return
        for _ in range(n):
            self.driver.before_step(self.sim)
            self.sim.step(1)

    def step_once(self) -> FramePhysics:
        """One step, whatever the clock says (the N key)."""
        owed, self.owed = self.owed, 0.0
        report = self.run(self.sim.dt, None)
        self.owed = owed
        return report

    def _remember(self, seconds: float, report: FramePhysics) -> None:
        now = time.perf_counter()
        self._history.append((now, seconds, report.steps * self.sim.dt))
        while self._history and now - self._history[0][0] > 1.0:
            self._history.popleft()

    def real_time_ratio(self) -> float:
        """Simulated over asked-for time in the last second (1: the physics keeps up)."""
        asked = sum(h[1] for h in self._history)
        done = sum(h[2] for h in self._history)
        return done / asked if asked > 0.0 else 1.0

    def forget(self) -> None:
        """After a pause or a reset: the time before it does not count."""
        self.owed = 0.0
        self._history.clear()
