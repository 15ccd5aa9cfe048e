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
from .vertex_groups import group_vertices

#: A triangle whose doubled area is at most this times its longest edge squared, in float32,
#: has zero area: the core's own test (src/scene/mesh.rs, DEGENERATE), made here too so that
#: the error can name the file and the face.
DEGENERATE = float(np.finfo(np.float32).eps)


def read_mesh(
    path: str | os.PathLike[str], parameter: str
) -> tuple[list[list[float]], list[list[int]]]:
    """:func:`mesh_arrays` as nested lists."""
    vertices, triangles = mesh_arrays(path, parameter)
    return vertices.tolist(), triangles.tolist()


def mesh_arrays(path: str | os.PathLike[str], parameter: str) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (float64) and triangles (int64), as ``(n, 3)`` arrays, of the mesh file
    ``path`` (any format trimesh reads: OBJ, STL, PLY, glTF, ...), read as written: nothing
    is merged or dropped here (not even a vertex no triangle uses), so the core's checks see
    the file's own triangles. Errors name ``parameter`` and the file: a missing file, one
    trimesh cannot read, one without triangles, a triangle with zero area (a repeated or
    collinear corner, with its index)."""
    vertices, faces, _ = mesh_file(path, parameter)
    return vertices, faces


def mesh_file(
    path: str | os.PathLike[str], parameter: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`mesh_arrays` and the per-vertex texture coordinates (float64, ``(n, 2)``, in the
    vertices' order) where the file has them, else None, from one reading of the file."""
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
        # process=False: no merging; maintain_order (OBJ): keep the vertices no face uses, which
        # trimesh otherwise drops, renumbering the rest.
        extra: dict[str, Any] = (
            {"maintain_order": True} if os.fspath(path).lower().endswith(".obj") else {}
        )
        mesh = trimesh.load(os.fspath(path), force="mesh", process=False, **extra)
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
    faces = faces.astype(np.int64)
    bad = _degenerate(vertices, faces)
    if bad.size:
        t = int(bad[0])
        raise ParameterError(
            f"{parameter}: {os.fspath(path)!r}: triangle {t} (face {t + 1} of the file, "
            f"corners {faces[t].tolist()}) has zero area (repeated or collinear corners)"
            + (f", and {bad.size - 1} more" if bad.size > 1 else "") + "; remove it",
            parameter,
        )
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    uvs = None if uv is None or len(uv) != len(vertices) else np.asarray(uv, dtype=np.float64)
    return vertices, faces, uvs


def _degenerate(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Indices of the triangles with zero area in float32, by the core's measure."""
    if faces.size == 0 or faces.min() < 0 or faces.max() >= len(vertices):
        return np.zeros(0, dtype=np.int64)  # out-of-range indices are the core's to report
    a, b, c = (vertices.astype(np.float32).astype(np.float64)[faces[:, k]] for k in range(3))
    doubled = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.sum((b - a) ** 2, axis=1), np.sum((c - b) ** 2, axis=1),
                      np.sum((a - c) ** 2, axis=1)], axis=0)
    with np.errstate(invalid="ignore"):
        return np.flatnonzero(~(doubled > DEGENERATE * longest))


def wants_file(data: Mapping[str, Any]) -> bool:
    """Whether scene ``data`` names a mesh file: a mesh collider's ``path``, or ``cloth.mesh``
    given as a path (``mesh = "flag.obj"`` or ``mesh = { path = "flag.obj", ... }``)."""
    colliders = data.get("colliders")
    cloth = data.get("cloth")
    mesh = cloth.get("mesh") if isinstance(cloth, Mapping) else None
    return (isinstance(colliders, list | tuple) and any(
        isinstance(c, Mapping) and "path" in c for c in colliders
    )) or isinstance(mesh, str | os.PathLike) or (isinstance(mesh, Mapping) and "path" in mesh) or (
        isinstance(cloth, Mapping) and "pin_group" in cloth  # refused here, by name, without one
    )


def _resolve_cloth_mesh(
    data: Mapping[str, Any], base: str | os.PathLike[str] | None
) -> dict[str, Any]:
    """``data`` with ``cloth.mesh``'s file (a path, or a table's ``path``) read into its
    ``vertices``, ``triangles`` and, where the file has them, ``uvs``; relative to ``base``.
    ``cloth.pin_group`` names the file's groups whose vertices join ``cloth.pins``."""
    cloth = data.get("cloth")
    mesh = cloth.get("mesh") if isinstance(cloth, Mapping) else None
    if isinstance(mesh, str | os.PathLike):
        mesh = {"path": mesh}
    if not (isinstance(cloth, Mapping) and isinstance(mesh, Mapping) and "path" in mesh):
        if isinstance(cloth, Mapping) and "pin_group" in cloth:
            raise ParameterError(
                f"{PIN_GROUP}: names vertex groups of the cloth's mesh file, and this cloth has "
                'none: give cloth.mesh as a file (mesh = "flag.obj")',
                PIN_GROUP,
            )
        return dict(data)
    both = [key for key in ("vertices", "triangles", "uvs") if key in mesh]
    if both:
        raise ParameterError(
            f"cloth.mesh.path: give a file or {' and '.join(both)}, not both", "cloth.mesh.path"
        )
    path = mesh["path"]
    if base is not None and isinstance(path, str) and not os.path.isabs(path):
        path = os.path.join(base, path)
    vertices, triangles, uvs = mesh_file(path, "cloth.mesh.path")
    resolved = {key: value for key, value in mesh.items() if key != "path"}
    resolved.update(vertices=vertices, triangles=triangles)
    if uvs is not None:
        resolved["uvs"] = uvs
    if "pin_group" in cloth:
        cloth = {key: value for key, value in cloth.items() if key != "pin_group"}
        cloth["pins"] = _with_group_pins(
            cloth.get("pins", []), data["cloth"]["pin_group"], path, vertices
        )
    return {**data, "cloth": {**cloth, "mesh": resolved}}


#: The scene key naming the mesh file's vertex groups to pin, as errors name it.
PIN_GROUP = "cloth.pin_group"


def _with_group_pins(
    pins: Any, names: Any, path: str | os.PathLike[str], vertices: np.ndarray
) -> Any:
    """``pins`` followed by the vertices of the groups ``names`` (a name or a list of names) of
    the mesh file ``path`` (:mod:`rustcloth.vertex_groups`), whose vertices trimesh read as
    ``vertices``."""
    listed = [names] if isinstance(names, str) else names
    if not (isinstance(listed, list | tuple) and listed
            and all(isinstance(n, str) for n in listed)):
        raise ParameterTypeError(
            f"{PIN_GROUP}: must be a group name or a non-empty list of names, got {names!r}",
            PIN_GROUP,
        )
    groups = group_vertices(path, vertices, PIN_GROUP)
    if not groups:
        raise ParameterError(
            f"{PIN_GROUP}: {os.fspath(path)!r} has no vertex groups (an OBJ file: no face "
            "under a `g` or `o` line; a scene file such as glTF: fewer than two named parts)",
            PIN_GROUP,
        )
    unknown = [n for n in listed if n not in groups]
    if unknown:
        raise ParameterError(
            f"{PIN_GROUP}: {os.fspath(path)!r} has no group {unknown[0]!r}; its groups: "
            + ", ".join(repr(g) for g in sorted(groups)),
            PIN_GROUP,
        )
    chosen = sorted({int(k) for n in listed for k in groups[n]})
    # A pins value that is not a list is the core's to refuse, by its own name.
    return [*pins, *chosen] if isinstance(pins, list | tuple) else pins


def resolve_paths(data: Mapping[str, Any], base: str | os.PathLike[str] | None) -> dict[str, Any]:
    """``data`` with each mesh collider's ``path`` replaced by the file's ``vertices`` and
    ``triangles`` (a collider that gives ``path`` and either of those is refused), and a mesh
    cloth's file read the same way."""
    data = _resolve_cloth_mesh(data, base)
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
            vertices, triangles = mesh_arrays(path, f"{at}.path")
            collider = {key: value for key, value in collider.items() if key != "path"}
            collider.update(vertices=vertices, triangles=triangles)
        resolved.append(collider)
    return {**data, "colliders": resolved}
