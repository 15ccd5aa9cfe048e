"""Shared fixtures for the Python tests."""

from __future__ import annotations

import collections
import contextlib
import functools
import hashlib
import json
import os
import signal
import struct
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

# So that tests import the helpers beside them (conftest, sweep_helpers) by name, also from the
# copy of the suite that scripts/test-wheel.sh runs.
sys.path.insert(0, os.path.dirname(__file__))

import rustcloth  # noqa: E402


@contextlib.contextmanager
def python_ctrl_c() -> Iterator[None]:
    """Python's own Ctrl-C handler while a test sends itself SIGINT, whatever the process
    inherited: a suite started from a background job inherits SIGINT ignored, which Python
    keeps, and the signal would then never become a KeyboardInterrupt."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


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


def at_1ms(name: str) -> rustcloth.Scene:
    """The built-in ``pile`` or ``twist`` as it was tuned, and as the tests on it were built:
    symplectic Euler at 1 ms steps (the pile in two substeps), spring damping 0.01 N s/m and no
    self-contact term in a solve. The scenes themselves run implicit Euler at display-frame
    steps (docs/contact.md, "The scenes at display-frame steps")."""
    scene = rustcloth.load_scene(name)
    return scene.replace(
        integrator="symplectic_euler", dt=0.001, substeps=2 if name == "pile" else 1,
        cloth={"damping": 0.01}, self_collision={**scene.self_collision, "solve_stiffness": 0.0})


def state_digest(sim: rustcloth.Simulation) -> str:
    """A hash of every bit of the state."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(sim.positions).tobytes())
    h.update(np.ascontiguousarray(sim.velocities).tobytes())
    return h.hexdigest()


def _feed(h: Any, value: Any) -> None:
    """Feeds one value of a state dict into the hash, tagged by type, so that 0 and 0.0, -0.0
    and 0.0, a list and a tuple, an array's dtype, shape and byte order all count."""
    if isinstance(value, dict):
        h.update(b"{")
        for key in sorted(value):
            h.update(repr(key).encode())
            _feed(h, value[key])
        h.update(b"}")
    elif isinstance(value, list | tuple):
        h.update(b"[" if isinstance(value, list) else b"(")
        for item in value:
            _feed(h, item)
        h.update(b"]")
    elif isinstance(value, np.ndarray):
        h.update(f"a{value.dtype.str}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, bool | np.bool_):
        h.update(b"T" if value else b"F")
    elif isinstance(value, float | np.floating):
        h.update(b"f" + struct.pack("<d", float(value)))
    elif isinstance(value, int | np.integer):
        h.update(f"i{int(value)}".encode())
    elif isinstance(value, str):
        h.update(b"s" + value.encode() + b"\0")
    elif value is None:
        h.update(b"N")
    else:
        raise TypeError(f"unexpected {type(value).__name__} in a state")


def full_digest(
    sim: rustcloth.Simulation, *, versions: bool = True, exclude: tuple[str, ...] = ()
) -> str:
    """A hash of the whole ``get_state()``: scene (dt, substeps, integrator...), positions,
    velocities, masses, pins, targets, cuts, springs, steps and clock, the ``advance``
    remainder, the integrator's history, the watchdog's memory and the pick settings; every
    array's bytes and every scalar's bits. ``versions=False`` leaves out the two cache-version
    counters (``state_version``, ``topology_version``), which only ever count up and which a
    twin that took another path to the same state legitimately has at other values;
    ``exclude`` leaves out further top-level keys."""
    state = sim.get_state()
    drop = set(exclude) | (set() if versions else {"state_version", "topology_version"})
    h = hashlib.sha256()
    _feed(h, {k: v for k, v in state.items() if k not in drop})
    return h.hexdigest()


def state_differences(a: Any, b: Any, path: str = "state") -> list[str]:
    """Where two ``get_state()`` values differ (paths such as ``state.watchdog.previous``),
    bit for bit, for assertion messages."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                out.append(f"{path}.{key}")
            else:
                out += state_differences(a[key], b[key], f"{path}.{key}")
        return out
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        if len(a) != len(b) or type(a) is not type(b):
            return [path]
        pairs = enumerate(zip(a, b, strict=True))
        return [d for k, (x, y) in pairs for d in state_differences(x, y, f"{path}[{k}]")]
    ha, hb = hashlib.sha256(), hashlib.sha256()
    _feed(ha, a)
    _feed(hb, b)
    return [] if ha.digest() == hb.digest() else [path]


@pytest.fixture
def scene() -> rustcloth.Scene:
    return small_scene()


@pytest.fixture
def sim(scene: rustcloth.Scene) -> rustcloth.Simulation:
    return rustcloth.Simulation(scene)


@functools.cache
def worker_run(threads: int) -> dict[str, Any]:
    """``tests/reliability_worker.py`` run once per test session in a subprocess with
    ``RAYON_NUM_THREADS = threads`` (the pool is global, fixed at the first step): digests of
    many grid shapes and of every integrator with every optional pass, and energies, bit for
    bit."""
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    script = os.path.join(os.path.dirname(__file__), "reliability_worker.py")
    done = subprocess.run(
        [sys.executable, script],
        env=env, capture_output=True, text=True, timeout=300, check=False,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["threads"] == str(threads)
    return result


INPUT_COUNTS: collections.Counter[str] = collections.Counter()
"""What the input-type property tests (test_reliability_inputs.py) tried: inputs ``tried``,
``rejected`` cleanly, ``accepted``, and ``known_defect`` pairs skipped."""


HOSTILE_COUNTS: collections.Counter[str] = collections.Counter()
"""What the hostile-input tests (test_hostile_input.py) fed the entry points in a subprocess:
values ``tried``, ``refused`` by name, ``accepted``."""


def pytest_sessionfinish(session: Any) -> None:
    # Under pytest-xdist each worker counts its own tests' inputs: it hands its counts to the
    # controller, which adds them up (pytest_testnodedown) for the summary below.
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["input_counts"] = dict(INPUT_COUNTS)
        workeroutput["hostile_counts"] = dict(HOSTILE_COUNTS)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: Any) -> None:
    workeroutput = getattr(node, "workeroutput", {})
    INPUT_COUNTS.update(workeroutput.get("input_counts", {}))
    HOSTILE_COUNTS.update(workeroutput.get("hostile_counts", {}))


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if HOSTILE_COUNTS["tried"]:
        c = HOSTILE_COUNTS
        terminalreporter.write_line(
            f"hostile-input tests: {c['tried']} values tried in a subprocess, {c['refused']} "
            f"refused by name, {c['accepted']} accepted, {c['wrong']} wrong"
        )
    if INPUT_COUNTS["tried"]:
        c = INPUT_COUNTS
        terminalreporter.write_line(
            f"input-type property tests: {c['tried']} inputs tried, {c['rejected']} rejected "
            f"cleanly, {c['accepted']} accepted, {c['known_defect']} known-defect pairs skipped"
        )
