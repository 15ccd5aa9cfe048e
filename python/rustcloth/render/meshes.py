"""Static meshes (floor, spheres, colliders of every shape) and the cloth's texture coordinates,
built with numpy. Vertices are interleaved (position, normal, uv), triangles counter-clockwise
seen from outside; a collider's mesh is in its own frame, placed by :func:`pose_matrix`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
U32 = npt.NDArray[np.uint32]
Mesh = tuple[F32, U32]

# Tessellation of the round colliders: fine enough that a 0.4 m disc filling half the view
# keeps a round outline, coarse enough that a dozen of them cost nothing to draw.
SEGMENTS = 48
RINGS = 24


def lathe(profile: npt.ArrayLike, segments: int) -> Mesh:
    """A surface of revolution about +y: ``profile`` rows ``(r, y, normal_r, normal_y)`` from
    top to bottom, turned through ``segments`` steps. A point repeated with another normal
    makes a hard edge (its band has no area); ``r = 0`` closes a pole."""
    prof = np.asarray(profile, dtype=np.float32)
    rows = len(prof)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1, dtype=np.float32)[None, :]
    c, s = np.cos(phi), np.sin(phi)
    r, y, nr, ny = (prof[:, k:k + 1] for k in range(4))
    p = np.stack([r * c, y * np.ones_like(phi), r * s], axis=-1).reshape(-1, 3)
    n = np.stack([nr * c, ny * np.ones_like(phi), nr * s], axis=-1).reshape(-1, 3)
    uv = np.stack(np.meshgrid(np.linspace(0, 1, segments + 1), np.linspace(0, 1, rows)), -1)
    vertices = np.hstack([p, n, uv.reshape(-1, 2)]).astype(np.float32)
    k, j = np.meshgrid(np.arange(rows - 1), np.arange(segments), indexing="ij")
    a = (k * (segments + 1) + j).ravel()
    b = a + segments + 1
    # Outward-facing counter-clockwise winding.
    indices = np.stack([a, a + 1, b, a + 1, b + 1, b], axis=-1).reshape(-1, 3)
    return vertices, indices.astype(np.uint32)


def _arc(theta: npt.NDArray[np.float64], radius: float, y0: float) -> npt.NDArray[np.float64]:
    """Profile rows of a circle's arc at polar angles ``theta`` (0: the top), centred at y0."""
    st, ct = np.sin(theta), np.cos(theta)
    return np.column_stack([radius * st, y0 + radius * ct, st, ct])


def uv_sphere(rings: int = 48, segments: int = 96, radius: float = 1.0) -> Mesh:
    """A sphere (fine enough at the default that its outline stays round at full-window size)."""
    return lathe(_arc(np.linspace(0.0, np.pi, rings + 1), radius, 0.0), segments)


def capsule(radius: float, half_height: float, rings: int = RINGS,
            segments: int = SEGMENTS) -> Mesh:
    """A capsule along y: two hemispheres of ``radius`` whose centres are ``half_height`` above
    and below the origin, joined by the cylinder between their equators."""
    half = max(2, rings // 2)
    top = _arc(np.linspace(0.0, 0.5 * np.pi, half + 1), radius, half_height)
    bottom = _arc(np.linspace(0.5 * np.pi, np.pi, half + 1), radius, -half_height)
    return lathe(np.vstack([top, bottom]), segments)


def cylinder(radius: float, half_height: float, segments: int = SEGMENTS) -> Mesh:
    """A solid cylinder along y, with flat caps and hard rims."""
    h, r = half_height, radius
    profile = [(0, h, 0, 1), (r, h, 0, 1), (r, h, 1, 0), (r, -h, 1, 0), (r, -h, 0, -1),
               (0, -h, 0, -1)]
    return lathe(profile, segments)


def box(half_extents: npt.ArrayLike) -> Mesh:
    """A box centred on the origin: six flat faces of four vertices each."""
    half = np.asarray(half_extents, dtype=np.float32)
    vertices = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3, dtype=np.float32)
            n[axis] = sign
            # Tangents with u x v = n, so the corners below run counter-clockwise about n.
            u = np.roll(np.eye(3, dtype=np.float32)[axis], 1) * sign
            v = np.cross(n, u)
            for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = (n + cu * u + cv * v) * half
                vertices.append(np.concatenate([p, n, [(cu + 1) / 2, (cv + 1) / 2]]))
    quads = np.arange(24, dtype=np.uint32).reshape(6, 4)
    indices = np.ascontiguousarray(np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
    return np.asarray(vertices, dtype=np.float32), indices


def floor_quad(center: tuple[float, float], height: float, half: float) -> Mesh:
    """A square at ``height`` facing +y."""
    cx, cz = center
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float32) * half
    p = np.column_stack([corners[:, 0] + cx, np.full(4, height), corners[:, 1] + cz])
    n = np.tile(np.array([0.0, 1.0, 0.0], dtype=np.float32), (4, 1))
    uv = (corners / (2.0 * half) + 0.5).astype(np.float32)
    vertices = np.hstack([p, n, uv]).astype(np.float32)
    return vertices, np.array([[0, 2, 1], [0, 3, 2]], dtype=np.uint32)


def floor_grid(center: tuple[float, float], height: float, half: float, fine: float,
               cells: int = 24) -> Mesh:
    """A square at ``height`` facing +y, as :func:`floor_quad`, cut into a grid whose lines
    are ``fine`` apart at the centre and spread out geometrically to the edge (``cells``
    each way from the centre): for light computed per vertex, which must resolve a pool of
    light near the scene but not one far away."""
    fine = min(fine, half / cells)
    # Offsets o_k = fine * (r^k - 1) / (r - 1), k = 0..cells, with o_cells = half.
    lo, hi = 1.0, 2.0
    while fine * (hi**cells - 1.0) / (hi - 1.0) < half:
        hi *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if mid == 1.0 or fine * (mid**cells - 1.0) / (mid - 1.0) < half:
            lo = mid
        else:
            hi = mid
    r = 0.5 * (lo + hi)
    k = np.arange(cells + 1, dtype=np.float64)
    side = fine * (r**k - 1.0) / (r - 1.0) if r > 1.0 else fine * k
    side *= half / side[-1]
    axis = np.concatenate([-side[:0:-1], side])
    m = len(axis)
    gx, gz = np.meshgrid(axis, axis, indexing="xy")
    p = np.column_stack([gx.ravel() + center[0], np.full(m * m, height), gz.ravel() + center[1]])
    n = np.tile(np.array([0.0, 1.0, 0.0]), (m * m, 1))
    uv = np.column_stack([gx.ravel(), gz.ravel()]) / (2.0 * half) + 0.5
    vertices = np.hstack([p, n, uv]).astype(np.float32)
    i, j = np.meshgrid(np.arange(m - 1), np.arange(m - 1), indexing="xy")
    a = (j * m + i).ravel()
    quads = np.stack([a, a + m + 1, a + 1, a, a + m, a + m + 1], axis=1)  # as floor_quad winds
    return vertices, quads.reshape(-1, 3).astype(np.uint32)


def flat_mesh(vertices: npt.ArrayLike, triangles: npt.ArrayLike) -> Mesh:
    """A triangle mesh as given, flat-shaded: three vertices of its own per triangle, with
    the triangle's normal (its winding's side), so hard edges stay hard."""
    p = np.asarray(vertices, dtype=np.float32)[np.asarray(triangles, dtype=np.int64)]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    corners = p.reshape(-1, 3)
    normals = np.repeat(n, 3, axis=0)
    uv = np.zeros((len(corners), 2), dtype=np.float32)
    out = np.hstack([corners, normals, uv]).astype(np.float32)
    return out, np.arange(len(corners), dtype=np.uint32).reshape(-1, 3)


def collider_mesh(collider: Mapping[str, Any], plane_half: float = 30.0) -> Mesh:
    """The mesh a collider is drawn (and picked) with, in its own frame, from what
    :meth:`rustcloth.Simulation.colliders` says of it: the shape at its size (without the
    contact ``thickness``); a plane is a square ``2 plane_half`` across in local y = 0."""
    shape = collider["shape"]
    if shape == "sphere":
        return uv_sphere(RINGS, SEGMENTS, float(collider["radius"]))
    if shape == "box":
        return box(collider["half_extents"])
    if shape == "capsule":
        return capsule(float(collider["radius"]), float(collider["half_height"]))
    if shape == "cylinder":
        return cylinder(float(collider["radius"]), float(collider["half_height"]))
    if shape == "plane":
        return floor_quad((0.0, 0.0), 0.0, plane_half)
    if shape == "mesh":
        return flat_mesh(collider["vertices"], collider["triangles"])
    raise ValueError(f"collider shape: no mesh for {shape!r}")


def bounding_radius(collider: Mapping[str, Any]) -> float:
    """Radius of a ball about the collider's origin that holds it (inf for a plane)."""
    shape = collider["shape"]
    if shape == "plane":
        return math.inf
    if shape == "mesh":
        return float(np.linalg.norm(np.asarray(collider["vertices"], dtype=np.float64),
                                    axis=1).max())
    if shape == "box":
        return float(np.linalg.norm(np.asarray(collider["half_extents"], dtype=np.float64)))
    r = float(collider["radius"])
    if shape == "sphere":
        return r
    h = float(collider["half_height"])
    return h + r if shape == "capsule" else math.hypot(h, r)


def rotation_matrix(quaternion: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The 3x3 rotation of a unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = np.asarray(quaternion, dtype=np.float64)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def pose_matrix(position: npt.ArrayLike, quaternion: npt.ArrayLike) -> F32:
    """A model matrix: turn by ``quaternion`` (x, y, z, w), then move to ``position``."""
    m = np.identity(4, dtype=np.float32)
    m[:3, :3] = rotation_matrix(quaternion)
    m[:3, 3] = np.asarray(position, dtype=np.float32)
    return m


def cloth_uv(nx: int, ny: int) -> F32:
    """Grid coordinates in [0, 1] per particle (index = j * nx + i)."""
    u, v = np.meshgrid(np.linspace(0.0, 1.0, nx), np.linspace(0.0, 1.0, ny))
    return np.column_stack([u.ravel(), v.ravel()]).astype(np.float32)


def translate_scale(center: npt.ArrayLike, scale: float) -> F32:
    """A model matrix: uniform ``scale``, then a move to ``center``."""
    m = np.identity(4, dtype=np.float32)
    m[:3, :3] *= scale
    m[:3, 3] = np.asarray(center, dtype=np.float32)
    return m
