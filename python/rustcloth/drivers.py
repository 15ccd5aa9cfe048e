"""Scripted motions that a built-in scene is meant to be shown with but that its scene file
does not hold: the ``twist`` scene's two pinned edges, turned in opposite directions. The demo
runs a scene's driver before every step; scripts and benchmarks can do the same.

    driver = rustcloth.drivers.driver_for("twist", sim)
    for _ in range(steps):
        driver.before_step(sim)
        sim.step()
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from .simulation import Simulation


class Driver(Protocol):
    def before_step(self, sim: Simulation) -> None:
        """Set what the coming step needs (pin targets, collider poses) from ``sim.time``."""


class TwistDriver:
    """Turns the left and right edges of a cloth about the axis through its centre along its
    first grid direction, in opposite directions, ``turns`` full turns each over ``seconds``
    of simulated time and then holds them (as newton's ``example_cloth_twist``). The edges
    must be pinned (the ``twist`` scene pins them); a particle cut since is left alone.

    Each step's targets are a rotation of where the edge particles were when the driver was
    made, by the angle at the end of the step, so the pins move smoothly at
    ``turns / seconds`` turns per second: 0.5 by default, 1.6 m/s at the corners of a 1 m cloth.
    """

    def __init__(self, sim: Simulation, turns: float = 2.0, seconds: float = 4.0) -> None:
        nx, ny = sim.nx, sim.ny
        self.left = np.arange(ny) * nx
        self.right = self.left + nx - 1
        positions = sim.positions
        self.center = np.asarray(sim.scene.cloth["center"], np.float64)
        # The axis: the cloth's first grid direction, from the left edge to the right.
        axis = positions[self.right].mean(0) - positions[self.left].mean(0)
        self.axis = axis / np.linalg.norm(axis)
        self.edges = np.concatenate([self.left, self.right])
        # Each edge particle's offset from the centre when the driver was made, left edge first.
        self.offsets = positions[self.edges].astype(np.float64) - self.center
        self.rate = turns * 2.0 * math.pi / seconds
        self.seconds = seconds

    def targets(self, time: float) -> dict[int, np.ndarray]:
        """Each edge particle's target at simulated ``time`` (s)."""
        return dict(zip(self.edges.tolist(), self._targets(time), strict=True))

    def _targets(self, time: float) -> np.ndarray:
        """The targets of ``self.edges`` at ``time``, one row each (m)."""
        angle = self.rate * min(time, self.seconds)
        out: np.ndarray = np.empty_like(self.offsets)
        ny = len(self.left)
        for side, sign in ((slice(None, ny), 1.0), (slice(ny, None), -1.0)):
            rotation = _rotation(self.axis, sign * angle)
            out[side] = self.center + self.offsets[side] @ rotation.T
        return out

    def before_step(self, sim: Simulation) -> None:
        # One call for both edges: pinning them one by one from Python cost more than a step
        # of a small cloth.
        alive = sim.alive[self.edges]
        sim.pin_many(self.edges[alive], self._targets(sim.time + sim.dt)[alive])


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """The rotation matrix by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rotation: np.ndarray = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return rotation


def driver_for(name: str, sim: Simulation) -> Driver | None:
    """The driver the built-in scene ``name`` is shown with, or None."""
    return TwistDriver(sim) if name == "twist" else None
