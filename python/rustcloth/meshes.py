"""Mesh colliders from files: a collider ``{"shape": "mesh", "path": "body.obj"}`` is read with
trimesh (the ``export`` extra) into the ``vertices`` and ``triangles`` the core takes, here in
the Python layer, before the scene reaches the core; the core never reads files. A relative
path is taken from ``base`` (the TOML file's folder, or the working directory)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._extras import MissingExtra
from .errors import ParameterError, ParameterTypeError


def read_mesh(
    path: str | os.PathLike[str], parameter: str
) -> tuple[list[list[float]], list[list[int]]]:
    """The vertices and triangles of the mesh file ``path`` (any format trimesh reads: OBJ,
    STL, PLY, glTF, ...), read as written: nothing is merged or dropped here, so the core's
    checks (degenerate triangles, winding) see the file's own triangles. Errors name
    ``parameter``: a missing file, one trimesh cannot read, one without triangles."""
    if not isinstance(path, str | os.PathLike):
        raise ParameterTypeError(
            f"{parameter}: must be a str or os.PathLike, got {type(path).__name__} {path!r}",
            parameter,
        )
    if not os.path.isfile(path):
        raise ParameterError(f"{parameter}: no such file: {os.fspath(path)!r}", parameter)
    try:
        import trimesh
    except ModuleNotFoundError as err:
        raise MissingExtra("trimesh", "reading a mesh collider's file") from err
    try:
        mesh = trimesh.load(os.fspath(path), force="mesh", process=False)
    except Exception as err:  # trimesh raises many kinds on a malformed file
        raise ParameterError(
            f"{parameter}: cannot read {os.fspath(path)!r} as a mesh: {err}", parameter
        ) from err
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))))
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise ParameterError(
            f"{parameter}: {os.fspath(path)!r} holds no triangles", parameter
        )
    return vertices.tolist(), faces.astype(np.int64).tolist()


def resolve_paths(data: Mapping[str, Any], base: str | os.PathLike[str] | None) -> dict[str, Any]:
    """``data`` with each mesh collider's ``path`` replaced by the file's ``vertices`` and
    ``triangles`` (a collider that gives ``path`` and either of those is refused)."""
    colliders = data.get("colliders")
    if not isinstance(colliders, list | tuple) or not any(
        isinstance(c, Mapping) and "path" in c for c in colliders
    ):
        return dict(data)
    resolved = []
    for c, collider in enumerate(colliders):
        if isinstance(collider, Mapping) and "path" in collider:
            at = f"colliders[{c}]"
            both = [key for key in ("vertices", "triangles") if key in collider]
            if both:
                raise ParameterError(
                    f"{at}.path: give a file or {' and '.join(both)}, not both", f"{at}.path"
                )
            path = collider["path"]
            if base is not None and isinstance(path, str) and not os.path.isabs(path):
                path = os.path.join(base, path)
            vertices, triangles = read_mesh(path, f"{at}.path")
            collider = {key: value for key, value in collider.items() if key != "path"}
            collider.update(vertices=vertices, triangles=triangles)
        resolved.append(collider)
    return {**data, "colliders": resolved}
