"""Mouse gestures on the cloth for the desktop demo and scripted runs alike: grab, drag, cut
and orbit, in window pixels, through the core's picking and grab API."""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..camera import Camera

F32 = npt.NDArray[np.float32]
Ray = tuple[F32, F32]
# Pixels between stroke samples: well under the on-screen particle spacing at demo sizes,
# so a fast swipe between two frames still cuts a continuous line.
STROKE_STEP_PX = 2.0


class Grabbable(Protocol):
    """The part of :class:`rustcloth.Simulation` the gestures use."""

    @property
    def positions(self) -> F32: ...
    def pick(self, origin: Any, direction: Any) -> tuple[int, float] | None: ...
    def grab(self, index: int) -> None: ...
    def drag_to(self, target: Any) -> None: ...
    def release(self) -> None: ...
    def grabbed(self) -> int | None: ...
    def sever_stroke(self, rays: Any) -> int: ...


class Interaction:
    """Grab, drag and cut on one simulation. The grab itself is the core's (``grab``,
    ``drag_to``, ``release``, ``grabbed()``); this keeps only what the cursor needs: the
    point whose camera-facing plane a drag moves on, and the stroke of the cut in progress
    (world-space segments, for the highlight pass)."""

    def __init__(self, sim: Grabbable) -> None:
        self.sim = sim
        self.drag_point: F32 | None = None
        self.segments: list[F32] = []
        self.stroke_version = 0
        self.cut_count = 0
        self._last_hit: F32 | None = None
        self._last_ray: Ray | None = None

    @property
    def grabbed(self) -> int | None:
        return self.sim.grabbed()

    def grab(self, ray: Ray) -> bool:
        """Grab the particle under the ray; False when the ray misses the cloth."""
        hit = self.sim.pick(ray[0], ray[1])
        if hit is None:
            return False
        self.sim.grab(hit[0])
        self.drag_point = self.sim.positions[hit[0]]
        return True

    def drag(self, ray: Ray, camera: Camera) -> None:
        """Move the grabbed particle's target to where the ray meets its drag plane."""
        if self.drag_point is None or self.sim.grabbed() is None:
            return
        self.sim.drag_to(camera.drag_plane_point(ray, self.drag_point))

    def release(self) -> None:
        self.sim.release()
        self.drag_point = None

    def cut(self, rays: list[Ray]) -> int:
        """Sever the cloth along one stroke sample: the surface swept from the previous
        sample's last ray (none at the start of a stroke) through these rays. Returns how many
        springs were severed. The stroke is drawn through the points where the rays meet the
        particles' pick boxes (the triangles along the cut are gone), joined to the previous
        sample's."""
        stroke = rays if self._last_ray is None else [self._last_ray, *rays]
        self._last_ray = rays[-1]
        severed = self.sim.sever_stroke(stroke) if len(stroke) >= 2 else 0
        hits: list[F32] = []
        for origin, direction in rays:
            hit = self.sim.pick(origin, direction)
            if hit is not None:
                d = np.asarray(direction, dtype=np.float64)
                point = np.asarray(origin, dtype=np.float64) + hit[1] * d / np.linalg.norm(d)
                hits.append(point.astype(np.float32))
        if hits:
            if self._last_hit is not None:
                hits.insert(0, self._last_hit)
            self._last_hit = hits[-1]
            if len(hits) >= 2:
                pts = np.asarray(hits, dtype=np.float32)
                self.segments.append(np.stack([pts[:-1], pts[1:]], axis=1).reshape(-1, 3))
                self.stroke_version += 1
        self.cut_count += severed
        return severed

    def end_stroke(self) -> None:
        """The cut gesture is over: its line goes away with it."""
        self._last_hit = None
        self._last_ray = None
        if self.segments:
            self.segments.clear()
            self.stroke_version += 1

    def stroke(self) -> F32:
        if not self.segments:
            return np.zeros((0, 3), dtype=np.float32)
        return np.concatenate(self.segments)

    def clear(self) -> None:
        self.release()
        self.end_stroke()


class Pointer:
    """Cursor gestures in window pixels, mapped to the interaction and the camera. The demo's
    glfw callbacks and scripted events both drive this, so they behave the same."""

    def __init__(self, interaction: Interaction, camera: Camera, size: tuple[int, int]) -> None:
        self.interaction = interaction
        self.camera = camera
        self.size = size
        self.mode: str | None = None
        self.pos = (0.0, 0.0)

    def ray(self, x: float, y: float) -> Ray:
        return self.camera.ray(x, y, *self.size)

    def press(self, mode: str, x: float, y: float) -> None:
        """``mode`` is "grab", "cut" or "orbit"."""
        self.mode, self.pos = mode, (x, y)
        if mode == "grab":
            self.interaction.grab(self.ray(x, y))
        elif mode == "cut":
            self.interaction.end_stroke()
            self.interaction.cut([self.ray(x, y)])

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
            rays = [self.ray(x0 + (x - x0) * k / n, y0 + (y - y0) * k / n)
                    for k in range(1, n + 1)]
            self.interaction.cut(rays)

    def release(self) -> None:
        if self.mode == "grab":
            self.interaction.release()
        elif self.mode == "cut":
            self.interaction.end_stroke()
        self.mode = None
