"""Mouse interaction shared by the demo and the headless renderer: grab, drag, cut and orbit,
plus replayable scripts of those gestures.

The simulation's own picking API (``pick``/``grab``/``drag_to``/``release``/``cut_ray``) is
used when it exists; until then :func:`nearest_particle_to_ray` stands in for ``pick`` and a
drag pins the grabbed particle at the cursor's target.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..camera import Camera

Ray = tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]
# Pixels between stroke samples: well under the on-screen particle spacing at demo sizes,
# so a fast swipe between two frames still cuts a continuous line.
STROKE_STEP_PX = 2.0


def nearest_particle_to_ray(
    positions: npt.NDArray[np.float32], alive: npt.NDArray[np.bool_], origin: npt.ArrayLike,
    direction: npt.ArrayLike, radius: float,
) -> tuple[int, float] | None:
    """The live particle in front of the ray within ``radius`` of it, nearest along the ray:
    ``(index, distance along the ray)`` or None. Stand-in for ``Simulation.pick``."""
    o = np.asarray(origin, dtype=np.float32)
    d = np.asarray(direction, dtype=np.float32)
    rel = positions - o
    t = rel @ d
    perp2 = np.einsum("ij,ij->i", rel, rel) - t * t
    ok = alive & (t > 0.0) & (perp2 <= radius * radius)
    if not ok.any():
        return None
    # The first layer along the ray is what the cursor is on; within it, the particle closest
    # to the ray. (Nearest-along-the-ray alone would reach through a grazing sheet.)
    candidates = np.flatnonzero(ok)
    front = candidates[t[candidates] <= t[candidates].min() + radius]
    k = front[np.argmin(perp2[front])]
    return int(k), float(t[k])


class Interaction:
    """Grab, drag and cut on one simulation; remembers the stroke for highlighting."""

    def __init__(self, sim: Any, spacing: float) -> None:
        self.sim = sim
        self.spacing = spacing
        self.grabbed: int | None = None
        self.grab_point: npt.NDArray[np.float32] | None = None
        self._was_pinned = False
        self.segments: list[npt.NDArray[np.float32]] = []
        self.stroke_version = 0
        self.cut_count = 0
        self._last_hit: npt.NDArray[np.float32] | None = None

    def begin_stroke(self) -> None:
        """A new cut gesture: its line does not join the previous one."""
        self._last_hit = None

    def pick(self, ray: Ray, radius_factor: float = 1.5) -> tuple[int, float] | None:
        if hasattr(self.sim, "pick"):
            return self.sim.pick(ray[0], ray[1])
        return nearest_particle_to_ray(self.sim.positions, self.sim.alive, ray[0], ray[1],
                                       radius_factor * self.spacing)

    def grab(self, ray: Ray) -> bool:
        hit = self.pick(ray)
        if hit is None:
            return False
        index = hit[0]
        self.grabbed = index
        self.grab_point = self.sim.positions[index]
        self._was_pinned = bool(self.sim.pinned[index])
        if hasattr(self.sim, "grab"):
            self.sim.grab(index)
        return True

    def drag(self, ray: Ray, camera: Camera) -> None:
        if self.grabbed is None or self.grab_point is None:
            return
        target = camera.drag_plane_point(ray, self.grab_point)
        if hasattr(self.sim, "drag_to"):
            self.sim.drag_to(target)
        else:
            self.sim.pin(self.grabbed, target)

    def release(self) -> None:
        if self.grabbed is None:
            return
        if hasattr(self.sim, "release"):
            self.sim.release()
        elif not self._was_pinned:
            # A particle the scene pinned stays pinned where it was dropped.
            self.sim.unpin(self.grabbed)
        self.grabbed = None
        self.grab_point = None

    def cut(self, rays: list[Ray], camera: Camera) -> int:
        """Cut where the rays of one stroke sample hit the cloth; returns particles cut."""
        if hasattr(self.sim, "cut_stroke") or hasattr(self.sim, "cut_ray"):
            if hasattr(self.sim, "cut_stroke"):
                cut = len(self.sim.cut_stroke(rays))
            else:
                cut = sum(self.sim.cut_ray(o, d) is not None for o, d in rays)
            # The core does the hit test; the stroke is drawn on the plane through the target.
            hits = [camera.drag_plane_point(r, camera.target) for r in rays]
        else:
            cut, hits = 0, []
            positions, alive = self.sim.positions, self.sim.alive
            for ray in rays:
                hit = nearest_particle_to_ray(positions, alive, ray[0], ray[1], 0.55 * self.spacing)
                if hit is None:
                    continue
                hits.append(positions[hit[0]])
                if hasattr(self.sim, "cut"):
                    self.sim.cut(hit[0])
                    alive[hit[0]] = False
                    cut += 1
        if hits and self._last_hit is not None:
            hits.insert(0, self._last_hit)  # join up with the previous frame's samples
        if hits:
            self._last_hit = np.asarray(hits[-1], dtype=np.float32)
        if len(hits) >= 2:
            pts = np.asarray(hits, dtype=np.float32)
            self.segments.append(np.stack([pts[:-1], pts[1:]], axis=1).reshape(-1, 3))
            self.stroke_version += 1
        self.cut_count += cut
        return cut

    def stroke(self) -> npt.NDArray[np.float32]:
        if not self.segments:
            return np.zeros((0, 3), dtype=np.float32)
        return np.concatenate(self.segments)

    def clear(self) -> None:
        self.release()
        self.segments.clear()
        self.stroke_version += 1


class Pointer:
    """Cursor gestures in window pixels, mapped to the interaction and the camera. The demo's
    glfw callbacks and scripted events both drive this, so they behave the same."""

    def __init__(self, interaction: Interaction, camera: Camera, size: tuple[int, int]) -> None:
        self.interaction = interaction
        self.camera = camera
        self.size = size
        self.mode: str | None = None
        self.pos = (0.0, 0.0)
        self.cut_supported = any(
            hasattr(interaction.sim, name) for name in ("cut", "cut_ray", "cut_stroke"))

    def ray(self, x: float, y: float) -> Ray:
        return self.camera.ray(x, y, *self.size)

    def press(self, mode: str, x: float, y: float) -> None:
        """``mode`` is "grab", "cut" or "orbit"."""
        self.mode, self.pos = mode, (x, y)
        if mode == "grab":
            self.interaction.grab(self.ray(x, y))
        elif mode == "cut":
            self.interaction.begin_stroke()
            self.interaction.cut([self.ray(x, y)], self.camera)

    def move(self, x: float, y: float) -> None:
        x0, y0 = self.pos
        self.pos = (x, y)
        if self.mode == "grab":
            self.interaction.drag(self.ray(x, y), self.camera)
        elif self.mode == "orbit":
            self.camera.orbit(-(x - x0) * 0.01, (y - y0) * 0.01)
        elif self.mode == "cut":
            # Sample the segment since the last event so a fast swipe leaves no gaps.
            n = max(1, math.ceil(math.hypot(x - x0, y - y0) / STROKE_STEP_PX))
            s = np.arange(1, n + 1) / n
            rays = [self.ray(x0 + (x - x0) * k, y0 + (y - y0) * k) for k in s]
            self.interaction.cut(rays, self.camera)

    def release(self) -> None:
        if self.mode == "grab":
            self.interaction.release()
        self.mode = None


@dataclass
class ScriptPlayer:
    """Replays gestures from a list of events ``{"t": seconds, "action": ...}``:

    - ``grab``: press at a point; ``drag``: move there over ``duration`` seconds (default 0);
      ``release``; ``cut``: press at the first point of ``path``, sweep the rest over
      ``duration``, release; ``orbit``: ``{"yaw": rad, "pitch": rad}``.

    A point is ``"x"``/``"y"`` as fractions of the window, ``"particle"`` (an index, at its
    current place on screen) or ``"world"`` ([x, y, z]). Events advance with the frame clock,
    so the same script and frame rate give the same frames.
    """

    events: list[dict[str, Any]]
    _queue: list[dict[str, Any]] = field(init=False)
    _moves: list[tuple[float, float, list[tuple[float, float]], bool]] = field(init=False)

    def __post_init__(self) -> None:
        for k, e in enumerate(self.events):
            if "t" not in e or "action" not in e:
                raise ValueError(f"script event {k} needs 't' and 'action': {e!r}")
            if e["action"] not in ("grab", "drag", "release", "cut", "orbit"):
                raise ValueError(f"script event {k}: unknown action {e['action']!r}")
        self._queue = sorted(self.events, key=lambda e: float(e["t"]))
        self._moves = []

    @classmethod
    def load(cls, path: str | Path) -> ScriptPlayer:
        return cls(json.loads(Path(path).read_text(encoding="utf-8")))

    @property
    def done(self) -> bool:
        return not self._queue and not self._moves

    def _point(self, spec: Any, pointer: Pointer, positions: npt.NDArray[np.float32]
               ) -> tuple[float, float]:
        w, h = pointer.size
        if isinstance(spec, list | tuple):
            return float(spec[0]) * w, float(spec[1]) * h
        if "particle" in spec:
            px, py, _ = pointer.camera.project(positions[int(spec["particle"])], w, h)
            return px, py
        if "world" in spec:
            px, py, _ = pointer.camera.project(spec["world"], w, h)
            return px, py
        return float(spec["x"]) * w, float(spec["y"]) * h

    def update(self, t: float, pointer: Pointer, positions: npt.NDArray[np.float32]) -> None:
        """Apply everything due by time ``t`` (seconds since the script started)."""
        while self._queue and float(self._queue[0]["t"]) <= t + 1e-9:
            e = self._queue.pop(0)
            start, action = float(e["t"]), e["action"]
            duration = float(e.get("duration", 0.0))
            if action == "grab":
                pointer.press("grab", *self._point(e, pointer, positions))
            elif action == "drag":
                target = self._point(e, pointer, positions)
                self._moves.append((start, duration, [pointer.pos, target], False))
            elif action == "release":
                pointer.release()
            elif action == "orbit":
                pointer.camera.orbit(float(e.get("yaw", 0.0)), float(e.get("pitch", 0.0)))
            elif action == "cut":
                path = [self._point(p, pointer, positions) for p in e["path"]]
                pointer.press("cut", *path[0])
                self._moves.append((start, duration, path, True))
        still = []
        for start, duration, path, release in self._moves:
            # Progress along the path (a polyline) as a fraction of its duration.
            f = 1.0 if duration <= 0 else min(1.0, (t - start) / duration)
            pts = path if len(path) > 1 else [*path, *path]
            seg = f * (len(pts) - 1)
            k = min(int(seg), len(pts) - 2)
            a, b = pts[k], pts[k + 1]
            u = seg - k
            pointer.move(a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u)
            if f < 1.0:
                still.append((start, duration, path, release))
            elif release:
                pointer.release()
        self._moves = still


def default_script(sim: Any) -> list[dict[str, Any]]:
    """A cut, grab and drag that suit any built-in scene: once the cloth has settled a little,
    cut across it, then lift the particle at its middle and let go."""
    nx, ny = sim.nx, sim.ny
    scene = sim.scene.to_dict()
    size = float(max(scene["cloth"]["size"]))
    middle = (ny // 2) * nx + nx // 2
    p = sim.positions[middle]
    target = [float(p[0]), float(p[1]) + 0.12 * size, float(p[2])]
    row = (2 * ny) // 3
    return [
        {"t": 1.0, "action": "cut", "duration": 0.6,
         "path": [{"particle": row * nx + 1}, {"particle": row * nx + nx - 2}]},
        {"t": 2.0, "action": "grab", "particle": middle},
        {"t": 2.05, "action": "drag", "world": target, "duration": 0.6},
        {"t": 3.0, "action": "release"},
    ]
