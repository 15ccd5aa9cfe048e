"""Mouse gestures for the desktop demo and scripted runs alike: grab, drag, cut and orbit, in
window pixels, through the core's picking and grab API; and moving a collider, picked by a ray
against the meshes the renderer draws it with and posed with ``set_collider_pose``."""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..camera import Camera
from ..render.meshes import bounding_radius, collider_mesh, rotation_matrix

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
    def sever_live_stroke(self, rays: Any) -> int: ...
    def end_live_stroke(self) -> None: ...
    def colliders(self) -> list[dict[str, Any]]: ...
    def collider_poses(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def set_collider_pose(self, index: int, position: Any, rotation: Any) -> None: ...


def ray_triangles(origin: npt.ArrayLike, direction: npt.ArrayLike,
                  corners: npt.NDArray[np.floating[Any]]) -> float | None:
    """Distance along ``direction`` (a unit vector) to the nearest of the triangles
    ``corners`` ``(M, 3, 3)`` that the ray meets from either side (Moeller-Trumbore), or None."""
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    a = corners[:, 0].astype(np.float64)
    e1, e2 = corners[:, 1] - a, corners[:, 2] - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)
    return float(t[hit].min()) if hit.any() else None


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
        self.collider: int | None = None
        """The collider a Ctrl drag holds."""
        self.collider_target: F32 | None = None
        """Where the held collider's origin goes: posed there each frame."""
        self.collider_point: F32 | None = None
        """The point of the held collider that was grabbed: its drag plane goes through it."""
        self._collider_offset = np.zeros(3, dtype=np.float32)
        self._collider_rotation = np.array([0.0, 0.0, 0.0, 1.0])
        self._collider_shapes: list[tuple[npt.NDArray[np.float32], float]] | None = None

    @property
    def grabbed(self) -> int | None:
        return self.sim.grabbed()

    def grab(self, ray: Ray) -> bool:
        """Grab the cloth under the ray (the core holds the patch within its ``grip_radius`` of
        the particle hit); False when the ray misses the cloth."""
        hit = self.sim.pick(ray[0], ray[1])
        if hit is None:
            return False
        self.sim.grab(hit[0])
        self.drag_point = self.sim.positions[hit[0]]
        return True

    def drag(self, ray: Ray, camera: Camera) -> None:
        """Move the grabbed particle's target to where the ray meets its drag plane (the rest
        of the grip follows it)."""
        if self.drag_point is None or self.sim.grabbed() is None:
            return
        self.sim.drag_to(camera.drag_plane_point(ray, self.drag_point))

    def release(self) -> None:
        self.sim.release()
        self.drag_point = None

    def cut(self, rays: list[Ray]) -> int:
        """Sever the cloth along one stroke sample (a frame's mouse moves), continuing the
        stroke in progress: the core joins these rays to the previous sample's in the cloth's
        own coordinates (``sever_live_stroke``), so a stroke across a cloth that swings
        between frames still cuts one line through it. Returns how many springs were severed.
        The stroke is drawn through the points where the rays meet the particles' pick boxes
        (the triangles along the cut are gone), joined to the previous sample's."""
        severed = self.sim.sever_live_stroke(rays)
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
        self.sim.end_live_stroke()
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
        self.release_collider()

    # -- colliders -------------------------------------------------------------------------
    def pick_collider(self, ray: Ray) -> tuple[int, float] | None:
        """The collider the ray meets first and the distance to it, or None: the ray is taken
        into each collider's frame and tested against its drawn triangles, after its
        bounding ball."""
        if self._collider_shapes is None:
            self._collider_shapes = []
            for c in self.sim.colliders():
                vertices, indices = collider_mesh(c)
                self._collider_shapes.append((vertices[:, :3][indices], bounding_radius(c)))
        positions, rotations = self.sim.collider_poses()
        origin = np.asarray(ray[0], dtype=np.float64)
        direction = np.asarray(ray[1], dtype=np.float64)
        direction = direction / np.linalg.norm(direction)
        best: tuple[int, float] | None = None
        for k, (corners, radius) in enumerate(self._collider_shapes):
            to_centre = positions[k] - origin
            along = float(to_centre @ direction)
            if float(to_centre @ to_centre) - along * along > radius * radius:
                continue  # misses the ball that holds it
            turn = rotation_matrix(rotations[k])
            t = ray_triangles(turn.T @ -to_centre, turn.T @ direction, corners)
            if t is not None and (best is None or t < best[1]):
                best = (k, t)
        return best

    def grab_collider(self, ray: Ray) -> bool:
        """Hold the collider under the ray; a drag then moves it on the camera-facing plane
        through the point grabbed. False when the ray meets no collider."""
        hit = self.pick_collider(ray)
        if hit is None:
            return False
        k, t = hit
        positions, rotations = self.sim.collider_poses()
        direction = np.asarray(ray[1], dtype=np.float64)
        point = np.asarray(ray[0], dtype=np.float64) + t * direction / np.linalg.norm(direction)
        self.collider = k
        self.collider_point = point.astype(np.float32)
        self._collider_offset = (positions[k] - point).astype(np.float32)
        self._collider_rotation = rotations[k].copy()
        self.collider_target = positions[k].astype(np.float32)
        return True

    def drag_collider(self, ray: Ray, camera: Camera) -> None:
        """Move the held collider's target so the grabbed point follows the ray."""
        if self.collider is None or self.collider_point is None:
            return
        self.collider_target = camera.drag_plane_point(ray, self.collider_point) \
            + self._collider_offset

    def pose_collider(self) -> None:
        """Pose the held collider at its target (once a frame, before the physics): it gets
        there over the next step, at the speed that takes, and pushes the cloth on the way.
        It keeps the orientation it had when grabbed."""
        if self.collider is not None and self.collider_target is not None:
            self.sim.set_collider_pose(self.collider, self.collider_target,
                                       self._collider_rotation)

    def release_collider(self) -> None:
        """Let go: the collider rests where it was last posed."""
        self.collider = None
        self.collider_target = None
        self.collider_point = None


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
        """``mode`` is "grab", "cut", "orbit" or "collider" (move a collider)."""
        self.mode, self.pos = mode, (x, y)
        if mode == "grab":
            self.interaction.grab(self.ray(x, y))
        elif mode == "collider":
            self.interaction.grab_collider(self.ray(x, y))
        elif mode == "cut":
            self.interaction.end_stroke()
            self.interaction.cut([self.ray(x, y)])

    def move(self, x: float, y: float) -> None:
        x0, y0 = self.pos
        self.pos = (x, y)
        if self.mode == "grab":
            self.interaction.drag(self.ray(x, y), self.camera)
        elif self.mode == "collider":
            self.interaction.drag_collider(self.ray(x, y), self.camera)
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
        elif self.mode == "collider":
            self.interaction.release_collider()
        self.mode = None
