"""Closed meshes generated with numpy, for tests and benchmarks of mesh colliders (nothing
read from disk)."""

from __future__ import annotations

import numpy as np


def torus(segments: int, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed torus (radii 0.4 and 0.15 m) of `2 * segments * rings` triangles, wound
    counter-clockwise seen from outside: float64 vertices and int64 triangles."""
    u = np.linspace(0, 2 * np.pi, segments, endpoint=False)[:, None]
    v = np.linspace(0, 2 * np.pi, rings, endpoint=False)[None, :]
    radius = 0.4 + 0.15 * np.cos(v)
    vertices = np.stack(
        np.broadcast_arrays(radius * np.cos(u), 0.15 * np.sin(v), radius * np.sin(u)), axis=-1
    ).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(segments), np.arange(rings), indexing="ij")
    a, d = i * rings + j, i * rings + (j + 1) % rings
    b, c = ((i + 1) % segments) * rings + j, ((i + 1) % segments) * rings + (j + 1) % rings
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([a, d, c], -1)]).reshape(-1, 3)
    p = vertices[faces]
    if np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() < 0:
        faces = faces[:, ::-1]
    return vertices, np.ascontiguousarray(faces)
