"""What the viewer does when a step diverges: put the cloth back to a sane state, change the
least it can so the next steps hold, and say so in one line.

The core rolls a failed step back (``SimulationDiverged``), but an explicit integrator grows
for hundreds of steps before a value turns infinite, so the state before the failed step is
often already wild (springs at 1e20 times their rest length). Hence checkpoints: every
``CHECKPOINT_EVERY`` seconds of simulated time while the cloth is healthy, its positions and
velocities are kept, and a wild state is replaced by the last healthy one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from ..errors import SimulationDiverged

F32 = npt.NDArray[np.float32]

MAX_SUBSTEPS = 128
"""Most substeps a remedy asks for (explicit Euler needs up to 68 in the built-in scenes)."""
HEALTHY_STRETCH = 2.0
"""A state whose springs are all below this strain (l / L - 1) is sane: kept as a
checkpoint, and not replaced after a rollback."""
UNRESOLVED_SWING = 0.5
UNRESOLVED_SHARE = 0.01
"""The core's test of motion a step does not resolve (``SimulationDiverged.reason ==
"unresolved"``): more than this share of the edges changing length by more than this fraction
of the spacing within a substep. A state that would fail it is not a checkpoint."""
RUNAWAY_STRETCH = 1000.0
"""A spring this many times past its rest length means the cloth is running away (a fast
drag stretches the grabbed particle's springs tens of times, for a step or two)."""
CHECKPOINT_EVERY = 0.1
"""Seconds of simulated time between checkpoints."""
EPISODE = 2.0
"""Seconds of simulated time after a failure during which a new one counts as the same
trouble, so the next remedy is a stronger one."""
FALLBACK_INTEGRATOR = "implicit_euler"
"""Unconditionally stable: where the person's previous integrator is not to be had."""


class Steppable(Protocol):
    """The part of :class:`rustcloth.Simulation` recovery uses."""

    integrator: str
    substeps: int

    @property
    def dt(self) -> float: ...
    @property
    def time(self) -> float: ...
    @property
    def positions(self) -> F32: ...
    @property
    def velocities(self) -> F32: ...
    def set_positions(self, positions: F32) -> None: ...
    def set_velocities(self, velocities: F32) -> None: ...
    def stable_dt(self) -> float | None: ...
    @property
    def triangles(self) -> npt.NDArray[np.uint32]: ...
    def max_stretch(self) -> float: ...
    def grabbed(self) -> int | None: ...
    def release(self) -> None: ...
    def reset(self) -> None: ...


@dataclass(frozen=True)
class Checkpoint:
    time: float
    positions: F32
    velocities: F32


class Recovery:
    """Checkpoints and the remedies for one simulation. The viewer tells it what the person
    chose (:meth:`chose_integrator`, :meth:`chose_substeps`), calls :meth:`after_steps`
    after steps that went well and :meth:`handle` with each ``SimulationDiverged``."""

    def __init__(self, sim: Steppable) -> None:
        self.sim = sim
        self.chosen_substeps = sim.substeps
        self.previous_integrator: str | None = None
        self.failures = 0
        self._failed_at = -math.inf
        self.checkpoint: Checkpoint | None = None
        self.after_steps()

    @property
    def raised(self) -> bool:
        """Whether a remedy runs more substeps than the person chose."""
        return self.sim.substeps > self.chosen_substeps

    def chose_integrator(self, previous: str) -> None:
        """The person switched integrators: remedies for the old one no longer apply."""
        self.previous_integrator = previous
        self.sim.substeps = self.chosen_substeps
        self.failures = 0

    def chose_substeps(self, substeps: int) -> None:
        self.chosen_substeps = substeps
        self.sim.substeps = substeps

    def _healthy(self) -> bool:
        stretch = self.sim.max_stretch()
        return (math.isfinite(stretch) and stretch < HEALTHY_STRETCH
                and bool(np.isfinite(self.sim.velocities).all())
                and self._unresolved_share() <= UNRESOLVED_SHARE)

    def _unresolved_share(self) -> float:
        """The share of the cloth's edges whose length the velocities would change by more
        than half the typical edge within one substep: the core's ``"unresolved"`` trouble,
        foreseen from one state. A cloth boiling under an unstable integrator has its springs
        at sane lengths (the self-collision pass holds it) but not its velocities. As in the
        core, only past the integrator's estimated stable step: within it a fast drag may swing
        the edges round the grip as far."""
        sim = self.sim
        limit = sim.stable_dt()
        if limit is None or sim.dt <= limit:
            return 0.0
        tri = sim.triangles.astype(np.int64)
        if len(tri) == 0:
            return 0.0
        edges = np.unique(np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
        x = sim.positions.astype(np.float64)
        v = sim.velocities.astype(np.float64)
        a, b = edges.T
        d = x[b] - x[a]
        length = np.linalg.norm(d, axis=1)
        rate = np.abs(np.einsum("ij,ij->i", v[b] - v[a], d)) / np.maximum(length, 1e-12)
        swing = rate * sim.dt / sim.substeps
        return float(np.mean(swing > UNRESOLVED_SWING * np.median(length)))

    def after_steps(self) -> None:
        """Keep a checkpoint when one is due and the state is sane."""
        sim = self.sim
        if self.failures and sim.time - self._failed_at > EPISODE:
            self.failures = 0
        last = self.checkpoint
        if last is not None and 0.0 <= sim.time - last.time < CHECKPOINT_EVERY:
            return
        if self._healthy():
            self.checkpoint = Checkpoint(sim.time, sim.positions, sim.velocities)

    def handle(self, err: SimulationDiverged) -> str:
        """Undo what the failed step left behind and apply the next remedy; returns what
        happened and what was done, for the overlay."""
        what = {
            "non_finite": "became non-finite",
            "overstretched": "was overstretched",
            "unresolved": "moved faster than the step resolves",
        }.get(err.reason, err.reason)
        return self._recover(f"particle {err.particle} {what}", "rolled back the failed step")

    def runaway(self) -> str | None:
        """Check for a cloth running away without a step failing yet (explicit Euler grows
        for hundreds of steps before anything is infinite); handle it like a divergence and
        say what was done, or None when all is well."""
        stretch = self.sim.max_stretch()
        if math.isfinite(stretch) and stretch < RUNAWAY_STRETCH:
            return None
        return self._recover(f"springs at {stretch:.2g} times their rest length",
                             "stopped it")

    def _recover(self, what: str, first: str) -> str:
        sim = self.sim
        integrator, substeps = sim.integrator, sim.substeps
        dragging = sim.grabbed() is not None
        self.failures = self.failures + 1 if sim.time - self._failed_at <= EPISODE else 1
        self._failed_at = sim.time
        story = (f"{integrator} diverged at t = {sim.time:.3f} s ({what} at {substeps} "
                 f"substeps{', while dragging' if dragging else ''}): ")
        if self._healthy() or self.checkpoint is None:
            story += first
        else:
            cp = self.checkpoint
            sim.set_positions(cp.positions)
            sim.set_velocities(cp.velocities)
            story += (f"the steps before it were already unstable, so put back the cloth of "
                      f"t = {cp.time:.3f} s")
        return f"{story}, and {self._remedy(integrator, substeps, dragging)}"

    def _remedy(self, integrator: str, substeps: int, dragging: bool) -> str:
        sim = self.sim
        limit = sim.stable_dt()
        needed = 0 if limit is None else math.ceil(substeps * sim.dt / limit)
        if self.failures == 1 and needed > MAX_SUBSTEPS:
            return self._switch(integrator, f"{integrator} needs {needed} substeps here")
        if self.failures == 1 and substeps < needed:
            sim.substeps = needed
            return (f"raised substeps {substeps} -> {needed} (what the stability estimate "
                    f"asks of {integrator} at dt = {sim.dt:g} s)")
        if dragging and self.failures == 2:
            sim.release()
            return "let go of the grabbed particle"
        if self.failures <= 2 and substeps < MAX_SUBSTEPS:
            sim.substeps = min(2 * substeps, MAX_SUBSTEPS)
            return f"raised substeps {substeps} -> {sim.substeps}"
        if self.failures <= 4 and integrator != FALLBACK_INTEGRATOR:
            return self._switch(integrator, "more substeps did not hold")
        sim.reset()
        self.failures = 0
        self.checkpoint = None
        self.after_steps()
        return "reset the scene (nothing else held)"

    def _switch(self, integrator: str, why: str) -> str:
        sim = self.sim
        back = self.previous_integrator
        to = back if back is not None and back != integrator else FALLBACK_INTEGRATOR
        if to == integrator:
            to = "symplectic_euler"
        sim.integrator = to
        sim.substeps = self.chosen_substeps
        self.previous_integrator = None  # if this one fails too: the fallback, not back
        return f"switched to {to} ({why})"
