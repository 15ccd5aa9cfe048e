"""One frame of the cloth as a triangle mesh in plain numpy arrays (:class:`Mesh`): what
:meth:`rustcloth.Simulation.to_mesh` returns and the writers of :mod:`rustcloth.export` save.

It imports neither of them, so that both can use it and :mod:`rustcloth.export` alone depends
on :mod:`rustcloth.simulation`. (Mesh colliders read from files are :mod:`rustcloth.meshes`.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class Mesh:
    """One frame of the cloth as numpy arrays. ``V`` vertices (the ``N`` particles, then the
    cut vertices), ``T`` drawn triangles."""

    vertices: npt.NDArray[np.float32]
    """``(V, 3)`` float32 positions in m."""
    triangles: npt.NDArray[np.uint32]
    """``(T, 3)`` uint32 vertex indices of the drawn triangles, counter-clockwise seen from the
    side the normals point to."""
    normals: npt.NDArray[np.float32]
    """``(V, 3)`` float32 unit vertex normals."""
    uvs: npt.NDArray[np.float32]
    """``(V, 2)`` float32 texture coordinates: particle ``(i, j)`` at ``(i / (nx - 1),
    j / (ny - 1))``, a cut vertex where its edge was crossed."""

    @classmethod
    def from_arrays(cls, vertices: npt.ArrayLike, triangles: npt.ArrayLike,
                    normals: npt.ArrayLike, uvs: npt.ArrayLike) -> Mesh:
        """The mesh of these arrays, as contiguous copies in the dtypes above where they are
        not already."""
        return cls(
            vertices=np.ascontiguousarray(vertices, dtype=np.float32),
            triangles=np.ascontiguousarray(triangles, dtype=np.uint32),
            normals=np.ascontiguousarray(normals, dtype=np.float32),
            uvs=np.ascontiguousarray(uvs, dtype=np.float32),
        )


def grid_uvs(nx: int, ny: int) -> npt.NDArray[np.float32]:
    """``(nx * ny, 2)`` float32 texture coordinates of an ``nx`` x ``ny`` grid: row
    ``j * nx + i`` holds ``(i / (nx - 1), j / (ny - 1))``."""
    u, v = np.meshgrid(np.arange(nx) / (nx - 1), np.arange(ny) / (ny - 1))
    return np.column_stack([u.ravel(), v.ravel()]).astype(np.float32)
