"""Scaffolding for the render tests: one EGL context per session, a GL-error check around every
test, an X display for the glfw demo, and a numpy stand-in sheet whose geometry is known
exactly (for the G-buffer and lighting tests)."""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

moderngl = pytest.importorskip("moderngl")

_SCENE = {
    "integrator": "symplectic_euler", "dt": 0.001, "substeps": 2, "gravity": [0.0, -9.81, 0.0],
    "air_drag": 0.0,
    "cloth": {"nx": 24, "ny": 24, "size": [1.2, 1.2], "center": [0.0, 1.0, 0.0], "plane": "xz",
              "pins": []},
    "floor": {"height": 0.0, "friction": 0.5, "thickness": 0.005},
    "spheres": [{"center": [0.0, 0.4, 0.0], "radius": 0.4, "friction": 0.3}],
}


class _SceneDict:
    def __init__(self, d: dict[str, Any]) -> None:
        self._d = d

    def to_dict(self) -> dict[str, Any]:
        return {k: (dict(v) if isinstance(v, dict) else v) for k, v in self._d.items()}


class StandInSimulation:
    """A gently waving flat sheet with the attributes the renderer and the demo read; the
    geometry is analytic, so tests know exactly where the cloth is."""

    def __init__(self, nx: int = 24, ny: int = 24, height: float = 1.0, amp: float = 0.0) -> None:
        d = {**_SCENE, "cloth": {**_SCENE["cloth"], "nx": nx, "ny": ny,
                                 "center": [0.0, height, 0.0]}}
        self.scene = _SceneDict(d)
        self.nx, self.ny, self.num_particles = nx, ny, nx * ny
        self.dt, self.substeps, self.integrator = 0.001, 2, "symplectic_euler"
        self.effects = ["gravity", "springs", "floor", "spheres"]
        self.amp, self.height = amp, height
        u, v = np.meshgrid(np.linspace(-0.6, 0.6, nx), np.linspace(-0.6, 0.6, ny))
        self._xz = np.column_stack([u.ravel(), v.ravel()]).astype(np.float32)
        self._targets: dict[int, np.ndarray] = {}
        self.reset()

    def reset(self) -> None:
        self.time, self.steps, self.topology_version = 0.0, 0, 0
        self._alive = np.ones(self.num_particles, dtype=bool)
        self._pinned = np.zeros(self.num_particles, dtype=bool)
        self._targets.clear()
        i, j = np.meshgrid(np.arange(self.nx - 1), np.arange(self.ny - 1))
        a = (j * self.nx + i).ravel()
        self._tris = np.concatenate([
            np.column_stack([a, a + self.nx, a + 1]), np.column_stack([a + 1, a + self.nx,
                                                                       a + self.nx + 1]),
        ]).astype(np.uint32)
        self._update()

    def _update(self) -> None:
        y = self.height + self.amp * np.sin(3.0 * self._xz[:, 0] + 2.0 * self.time)
        self._pos = np.column_stack([self._xz[:, 0], y, self._xz[:, 1]]).astype(np.float32)
        for k, t in self._targets.items():
            self._pos[k] = t

    @property
    def positions(self) -> np.ndarray:
        return self._pos.copy()

    @property
    def velocities(self) -> np.ndarray:
        return np.zeros_like(self._pos)

    @property
    def normals(self) -> np.ndarray:
        slope = 3.0 * self.amp * np.cos(3.0 * self._xz[:, 0] + 2.0 * self.time)
        n = np.column_stack([-slope, np.ones_like(slope), np.zeros_like(slope)])
        return (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)

    @property
    def triangles(self) -> np.ndarray:
        return self._tris.copy()

    @property
    def pinned(self) -> np.ndarray:
        return self._pinned.copy()

    def render_positions(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions, self.normals

    def render_topology(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u, v = np.meshgrid(np.linspace(0, 1, self.nx), np.linspace(0, 1, self.ny))
        uvs = np.column_stack([u.ravel(), v.ravel()]).astype(np.float32)
        return self.triangles, uvs, np.arange(self.num_particles, dtype=np.uint32)

    @property
    def alive(self) -> np.ndarray:
        return self._alive.copy()

    def colliders(self) -> list[dict[str, Any]]:
        return []  # its scene has [[spheres]] and no [[colliders]]

    def collider_poses(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros((0, 3)), np.zeros((0, 4))

    def spring_strain(self) -> np.ndarray:
        return np.abs(self._pos[:, 1] - self.height).astype(np.float32)

    def step(self, n: int = 1) -> None:
        self.steps += n
        self.time += n * self.dt
        self._update()

    def advance(self, seconds: float) -> int:
        n = int(round(seconds / self.dt))
        self.step(n)
        return n

    def pin(self, index: int, target: Any = None) -> None:
        self._pinned[index] = True
        if target is not None:
            self._targets[index] = np.asarray(target, dtype=np.float32)
        self._update()

    def unpin(self, index: int) -> None:
        self._pinned[index] = False
        self._targets.pop(index, None)

    def cut(self, index: int) -> None:
        self._alive[index] = False
        keep = self._alive[self._tris].all(axis=1)
        self._tris = self._tris[keep]
        self.topology_version += 1

    def profile(self) -> str:
        return "stand-in"


@pytest.fixture(scope="session")
def gl_ctx() -> Iterator[Any]:
    from rustcloth.render import GLUnavailable, create_standalone_context

    try:
        ctx = create_standalone_context()
    except GLUnavailable as err:
        pytest.skip(f"no OpenGL 3.3 context for the render tests: {err}")
    yield ctx
    ctx.release()


@pytest.fixture
def ctx(gl_ctx: Any) -> Iterator[Any]:
    """The shared context, made current; any GL error a test leaves behind fails it."""
    with gl_ctx:
        assert gl_ctx.error == "GL_NO_ERROR"
        yield gl_ctx
        assert gl_ctx.error == "GL_NO_ERROR"


@pytest.fixture
def standin_cls() -> type[StandInSimulation]:
    """The stand-in class, handed out by fixture: ``from conftest import`` would be ambiguous
    next to the suite's top-level conftest."""
    return StandInSimulation


@pytest.fixture(scope="session")
def xdisplay() -> Iterator[str]:
    """An X display for the glfw demo: the existing one, or a private Xvfb started here."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("no DISPLAY and no Xvfb (Debian package xvfb) for the glfw demo test")
    # Xvfb picks a free display itself and writes its number once it accepts clients: two
    # pytest-xdist workers, or two suites on one machine, each get their own, with no race
    # between looking for a free number and taking it.
    ready, write_end = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-screen", "0", "640x480x24",
                             "-nolisten", "tcp"], pass_fds=(write_end,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    with os.fdopen(ready) as f:
        num = f.readline().strip()
    if not num:
        proc.wait(timeout=10)
        pytest.fail(f"Xvfb exited with {proc.returncode} before it opened a display")
    try:
        yield f":{num}"
    finally:
        proc.terminate()
        proc.wait(timeout=10)
