"""Static meshes (floor, spheres) and the cloth's texture coordinates, built with numpy."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
U32 = npt.NDArray[np.uint32]


def uv_sphere(rings: int = 48, segments: int = 96) -> tuple[F32, U32]:
    """Unit sphere: interleaved (position, normal, uv) vertices and triangle indices (fine
    enough that its outline stays round at full-window size)."""
    theta = np.linspace(0.0, np.pi, rings + 1, dtype=np.float32)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1, dtype=np.float32)[None, :]
    st, ct = np.sin(theta), np.cos(theta)
    p = np.stack([st * np.cos(phi), ct * np.ones_like(phi), st * np.sin(phi)], axis=-1)
    p = p.reshape(-1, 3)
    uv = np.stack(np.meshgrid(np.linspace(0, 1, segments + 1), np.linspace(0, 1, rings + 1)), -1)
    vertices = np.hstack([p, p, uv.reshape(-1, 2)]).astype(np.float32)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = (r * (segments + 1) + s).ravel()
    b = a + segments + 1
    # Outward-facing counter-clockwise winding.
    indices = np.stack([a, a + 1, b, a + 1, b + 1, b], axis=-1).reshape(-1, 3)
    return vertices, indices.astype(np.uint32)


def floor_quad(center: tuple[float, float], height: float, half: float) -> tuple[F32, U32]:
    """A square at ``height`` facing +y."""
    cx, cz = center
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float32) * half
    p = np.column_stack([corners[:, 0] + cx, np.full(4, height), corners[:, 1] + cz])
    n = np.tile(np.array([0.0, 1.0, 0.0], dtype=np.float32), (4, 1))
    uv = (corners / (2.0 * half) + 0.5).astype(np.float32)
    vertices = np.hstack([p, n, uv]).astype(np.float32)
    return vertices, np.array([[0, 2, 1], [0, 3, 2]], dtype=np.uint32)


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
