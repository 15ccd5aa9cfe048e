"""Named vertex groups of a mesh file, for pinning a mesh cloth by a group its author marked in
a modelling tool (``pin_group = "hem"``). trimesh reads the faces but, loading one mesh, drops
the names, so this reads them apart, in the numbering :func:`rustcloth.meshes.mesh_arrays`
gives the vertices (trimesh's order, which the cloth keeps):

- **OBJ**: a group is the vertices of its faces: a face belongs to the names of the ``g`` line
  above it (``g a b`` names two groups) and to the object of the ``o`` line above it. A name
  with no face under it holds no vertex and is not a group. Read from the file itself.
- **A scene file** (glTF/GLB, and any other format trimesh loads as a scene of several
  meshes): a group is the vertices of one named part, by its node's name and by its mesh's
  name (a mesh placed by two nodes is one group of both copies). A file of one part (STL, PLY,
  a glTF of one mesh) has no groups: the one part would pin the whole cloth.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import ParameterError


def group_vertices(
    path: str | os.PathLike[str], vertices: np.ndarray, parameter: str
) -> dict[str, np.ndarray]:
    """For each group of the mesh file ``path`` (module docstring), the sorted indices into
    ``vertices`` (the file's vertices as trimesh read them) of its vertices. Errors name
    ``parameter`` and the file: unreadable, a face that names a vertex the file does not have
    (OBJ), a vertex trimesh renumbered that cannot be told from another (OBJ), a scene whose
    parts do not make up the vertices read."""
    name = os.fspath(path)
    if not name.lower().endswith(".obj"):
        return _part_groups(name, vertices, parameter)
    try:
        with open(name, encoding="utf-8") as file:
            text = file.read()
    except (OSError, UnicodeDecodeError) as err:
        raise ParameterError(f"{parameter}: cannot read {name!r}: {err}", parameter) from err
    positions, groups = _parse(text, name, parameter)
    number = _trimesh_numbers(positions, vertices, name, parameter)
    out = {}
    for group, file_indices in groups.items():
        chosen = np.zeros(len(positions), dtype=bool)
        chosen[sorted(file_indices)] = True
        out[group] = np.flatnonzero(chosen[number]) if len(number) else np.zeros(0, np.int64)
    return out


def _parse(text: str, name: str, parameter: str) -> tuple[np.ndarray, dict[str, set[int]]]:
    """The file's ``v`` positions in order, and each name's set of (0-based) file vertices."""
    positions: list[list[float]] = []
    # (names, corners, vertices read so far, line) per face, resolved once every vertex is read:
    # a positive index may name a vertex written after the face, a negative one counts back.
    faces: list[tuple[tuple[str, ...], list[str], int, int]] = []
    names: list[str] = []
    obj: list[str] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        key, rest = tokens[0], tokens[1:]
        if key == "v":
            try:
                positions.append([float(x) for x in rest[:3]])
            except ValueError as err:
                raise ParameterError(
                    f"{parameter}: {name!r} line {number}: a vertex {raw.strip()!r} that is "
                    "not three numbers",
                    parameter,
                ) from err
        elif key == "g":
            names = rest
        elif key == "o":
            obj = rest[:1]
        elif key == "f" and (names or obj):
            faces.append(((*names, *obj), rest, len(positions), number))
    groups: dict[str, set[int]] = {}
    for members, corners, before, number in faces:
        indices = [_vertex_index(c, before, len(positions), name, number, parameter)
                   for c in corners]
        for group in members:
            groups.setdefault(group, set()).update(indices)
    return np.asarray(positions, dtype=np.float64).reshape(-1, 3), groups


def _vertex_index(
    token: str, before: int, count: int, name: str, line: int, parameter: str
) -> int:
    """The 0-based file vertex of a face corner ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``: a
    positive index counts from the file's first vertex, a negative one back from the last of
    the ``before`` vertices written above the face."""
    try:
        index = int(token.split("/", 1)[0])
    except ValueError as err:
        raise ParameterError(
            f"{parameter}: {name!r} line {line}: a face corner {token!r} that is not a vertex "
            "index",
            parameter,
        ) from err
    at = index - 1 if index > 0 else before + index
    if index == 0 or not 0 <= at < (count if index > 0 else before):
        raise ParameterError(
            f"{parameter}: {name!r} line {line}: a face names vertex {index}, and the file "
            f"has {count} vertices ({before} above the face)",
            parameter,
        )
    return at


def _trimesh_numbers(
    positions: np.ndarray, vertices: np.ndarray, name: str, parameter: str
) -> np.ndarray:
    """For each of trimesh's ``vertices``, the file vertex it is. The same list when trimesh
    kept the file's (no face carries texture or normal indices that split a vertex); else each
    is matched by its position, which must be that of exactly one file vertex."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.shape == positions.shape and np.array_equal(vertices, positions):
        return np.arange(len(positions))
    where: dict[tuple[float, ...], list[int]] = {}
    for k, p in enumerate(positions):
        where.setdefault(tuple(p), []).append(k)
    number = np.empty(len(vertices), dtype=np.int64)
    for j, p in enumerate(vertices):
        found = where.get(tuple(p), [])
        if len(found) != 1:
            raise ParameterError(
                f"{parameter}: {name!r}: trimesh numbers the vertices apart from the file (its "
                f"faces' texture or normal indices split some), and its vertex {j} at "
                f"{p.tolist()} is {len(found)} of the file's vertices, so its groups cannot be "
                "told; give each vertex one place",
                parameter,
            )
        number[j] = found[0]
    return number


def _part_groups(name: str, vertices: np.ndarray, parameter: str) -> dict[str, np.ndarray]:
    """The groups of a file trimesh loads as a scene: each part's vertex range in the mesh
    trimesh concatenates from the parts (``Scene.to_mesh``, the order of ``Scene.dump``), under
    its node's and its mesh's names. The parts' placed vertices must be ``vertices`` exactly,
    or the numbering is not the cloth's and the groups are refused."""
    import trimesh  # read_mesh has already needed it for the same file

    try:
        parts = [p for p in trimesh.load_scene(name, process=False).dump()
                 if isinstance(p, trimesh.Trimesh)]
    except Exception as err:  # trimesh raises many kinds on a malformed file
        raise ParameterError(f"{parameter}: cannot read {name!r}: {err}", parameter) from err
    if len(parts) < 2:
        return {}
    placed = np.concatenate([np.asarray(p.vertices, dtype=np.float64) for p in parts])
    if not np.array_equal(placed, np.asarray(vertices, dtype=np.float64)):
        raise ParameterError(
            f"{parameter}: {name!r}: its {len(parts)} parts do not make up the "
            f"{len(vertices)} vertices read from it in order, so its groups cannot be told",
            parameter,
        )
    ranges: dict[str, list[np.ndarray]] = {}
    start = 0
    for part in parts:
        span = np.arange(start, start + len(part.vertices))
        start += len(part.vertices)
        names = {part.metadata.get("node"), part.metadata.get("name")}
        for group in names - {None, ""}:
            ranges.setdefault(str(group), []).append(span)
    return {group: np.concatenate(spans) for group, spans in ranges.items()}
