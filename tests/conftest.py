"""Shared fixtures for the Python tests."""

from __future__ import annotations

import hashlib
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))  # so tests can import reference.py

import rustcloth  # noqa: E402


def small_scene(**changes) -> rustcloth.Scene:
    """An 8 x 6 cloth in the xy plane, pinned at its top corners, stable at dt = 1 ms."""
    scene = rustcloth.Scene(
        dt=0.001,
        air_drag=0.001,
        cloth={
            "nx": 8,
            "ny": 6,
            "size": [0.7, 0.5],
            "center": [0.1, 1.0, -0.2],
            "plane": "xy",
            "particle_mass": 0.002,
            "k_structural": 300.0,
            "k_shear": 60.0,
            "k_bend": 15.0,
            "damping": 0.02,
            "pins": ["top_corners"],
        },
    )
    return scene.replace(**changes) if changes else scene


def state_digest(sim: rustcloth.Simulation) -> str:
    """A hash of every bit of the state."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(sim.positions).tobytes())
    h.update(np.ascontiguousarray(sim.velocities).tobytes())
    return h.hexdigest()


@pytest.fixture
def scene() -> rustcloth.Scene:
    return small_scene()


@pytest.fixture
def sim(scene: rustcloth.Scene) -> rustcloth.Simulation:
    return rustcloth.Simulation(scene)
