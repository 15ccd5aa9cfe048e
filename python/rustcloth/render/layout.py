"""What the renderer and the viewer need from a scene, read once per load: where the cloth can
go, the colliders, the ground, which side of the cloth is its front, and the camera that
frames it all."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..camera import Camera, fit_distance
from .meshes import bounding_radius

F32 = npt.NDArray[np.float32]

# A hanging cloth stretches under its weight: allow this much beyond its rest lengths.
STRETCH_ALLOWANCE = 1.15


@dataclass(frozen=True)
class Sphere:
    center: F32
    radius: float


@dataclass(frozen=True)
class SceneLayout:
    """Geometry of one scene, from its dict and the cloth's rest state."""

    cloth_size: tuple[float, float]
    """m, extent along i and along j."""
    grid: tuple[int, int]
    """nx, ny."""
    spacing: float
    """m between neighbouring particles (the smaller of the two directions)."""
    ground: float
    """Height of the floor, or for scenes without one a visual ground below the cloth's
    reach (scenery, not a collider)."""
    has_floor: bool
    spheres: tuple[Sphere, ...]
    reach_min: F32
    reach_max: F32
    """A box the cloth stays inside (at rest, falling, hanging) plus the spheres and the
    colliders where the scene starts them (planes, which have no end, left out)."""
    front: F32
    """Unit normal of the cloth's front side as it will be seen: up for a sheet lying in
    xz, towards -z for one in xy; towards where it swings for a sheet hung by one side."""
    front_is_winding: bool
    """Whether the front side is the one the triangles' winding (and ``normals``) face."""

    @property
    def center(self) -> F32:
        return ((self.reach_min + self.reach_max) * 0.5).astype(np.float32)

    @property
    def span(self) -> float:
        """The largest extent of the reach box, m."""
        return float(np.max(self.reach_max - self.reach_min))

    @classmethod
    def from_scene(cls, scene: dict[str, Any], rest_positions: F32, rest_normals: F32,
                   pinned: npt.NDArray[np.bool_]) -> SceneLayout:
        cloth = scene["cloth"]
        nx, ny = int(cloth["nx"]), int(cloth["ny"])
        size = (float(cloth["size"][0]), float(cloth["size"][1]))
        spacing = min(size[0] / max(nx - 1, 1), size[1] / max(ny - 1, 1))
        spheres = tuple(Sphere(np.asarray(s["center"], dtype=np.float32), float(s["radius"]))
                        for s in scene.get("spheres") or [])
        lo = rest_positions.min(axis=0).astype(np.float32)
        hi = rest_positions.max(axis=0).astype(np.float32)
        pins = rest_positions[pinned]
        floor = scene.get("floor")
        if len(pins):
            # Every particle stays within its rest distance (stretched) of the nearest pin.
            d = np.linalg.norm(rest_positions[:, None, :] - pins[None, :, :], axis=2)
            hang = STRETCH_ALLOWANCE * float(d.min(axis=1).max())
            bottom = float(pins[:, 1].min()) - hang
        else:
            hang = 0.0
            bottom = float(lo[1]) - max(size)  # falls: to the floor, or out of sight
        ground = float(floor["height"]) if floor else bottom - 0.1
        lo[1] = min(float(lo[1]), max(bottom, ground))
        balls = [(s.center, s.radius) for s in spheres] + [
            (np.asarray(c["center"], dtype=np.float32), bounding_radius(c))
            for c in scene.get("colliders") or [] if c["shape"] != "plane"]
        for center, radius in balls:
            lo = np.minimum(lo, center - radius)
            hi = np.maximum(hi, center + radius)
        plane = _mesh_plane(rest_normals) if "mesh" in cloth else cloth.get("plane", "xz")
        front = _front(plane, rest_positions, pins, hang)
        facing = float(np.mean(rest_normals @ _rest_front(plane)))
        if abs(facing) < 0.5:
            # Neither up nor down (a garment wrapped round a body): the front is the outside,
            # the side facing away from the cloth's centre.
            outward = rest_positions - rest_positions.mean(axis=0)
            facing = float(np.mean(np.sum(rest_normals * outward, axis=1)))
        winding = facing > 0.0
        return cls(size, (nx, ny), spacing, ground, bool(floor), spheres,
                   lo.astype(np.float32), hi.astype(np.float32), front, winding)

    def camera(self, aspect: float, fov: float = 40.0) -> Camera:
        """A three-quarter view from the front side, slightly above, whose distance makes the
        whole reach box fit the view with a margin."""
        direction = self.view_direction()
        target = self.center
        corners = box_corners(self.reach_min, self.reach_max)
        distance = fit_distance(corners, target, direction, fov, aspect, margin=0.88)
        return Camera(eye=target + direction * distance, target=target, fov=fov, aspect=aspect,
                      near=0.05, far=80.0)

    @property
    def view_azimuth(self) -> float:
        """Degrees about +y of the side the camera looks from (0: +z, 90: +x)."""
        d = self.view_direction()
        return math.degrees(math.atan2(float(d[0]), float(d[2])))

    def view_direction(self) -> F32:
        """Unit vector from the scene's centre towards the camera."""
        up = np.array([0.0, 1.0, 0.0], dtype=np.float32)
        if abs(float(self.front[1])) > 0.7:
            # A sheet seen from above: look down at 32 degrees from the +z, +x quarter.
            direction = np.array([0.45, 0.0, 1.0], dtype=np.float32)
            direction /= np.linalg.norm(direction)
            direction = direction * math.cos(math.radians(32.0)) + up * math.sin(
                math.radians(32.0))
        else:
            # A hanging sheet: from its front, 25 degrees to the side and 28 above (so a sheet
            # that starts flat and swings down shows its front side all along).
            side = np.cross(up, self.front)
            yaw, pitch = math.radians(25.0), math.radians(28.0)
            flat = self.front * math.cos(yaw) + side * math.sin(yaw)
            direction = flat * math.cos(pitch) + up * math.sin(pitch)
        unit: F32 = (direction / np.linalg.norm(direction)).astype(np.float32)
        return unit


def box_corners(lo: npt.ArrayLike, hi: npt.ArrayLike) -> F32:
    """The eight corners of an axis-aligned box, (8, 3)."""
    lo_a, hi_a = np.asarray(lo, dtype=np.float32), np.asarray(hi, dtype=np.float32)
    pick = np.array([[(k >> b) & 1 for b in range(3)] for k in range(8)], dtype=bool)
    return np.where(pick, hi_a, lo_a).astype(np.float32)


def _mesh_plane(rest_normals: F32) -> str:
    """The grid plane a mesh cloth's rest shape stands for: a mesh has no ``plane`` of its own
    (its scene dict carries the grid default, ``xz``), so a flat sheet standing up facing +-z
    (a flag) would otherwise be framed from the side and open showing its back. ``xy`` when
    the mean rest normal is mostly along z, else ``xz`` (lying flat, or wrapped round a body,
    which the winding test in :meth:`SceneLayout.from_scene` handles)."""
    mean = rest_normals.mean(axis=0)
    return "xy" if abs(float(mean[2])) > 0.7 else "xz"


def _rest_front(plane: str) -> F32:
    """The side called the front at rest: up for a sheet in xz, -z for one in xy."""
    return np.array([0.0, 1.0, 0.0] if plane == "xz" else [0.0, 0.0, -1.0], dtype=np.float32)


def _front(plane: str, rest: F32, pins: F32, hang: float) -> F32:
    """The front side's normal once the cloth has settled. A sheet in xz pinned off-centre
    swings down about its pins: its top side turns to face away from them, horizontally."""
    front = _rest_front(plane)
    if plane != "xz" or not len(pins):
        return front
    away = rest.mean(axis=0) - pins.mean(axis=0)
    away[1] = 0.0
    if float(np.linalg.norm(away)) < 0.25 * hang:
        return front  # pinned near its middle: it drapes like an umbrella, top still up
    unit: F32 = (away / np.linalg.norm(away)).astype(np.float32)
    return unit
