"""Mesh collider files read by ``rustcloth.meshes.read_mesh``: as written, and a bad triangle
reported with the file and the face."""

from __future__ import annotations

import pytest
import rustcloth
from rustcloth.meshes import read_mesh

pytest.importorskip("trimesh")  # the export extra reads the files

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def test_a_repeated_corner_names_the_file_and_the_triangle(tmp_path):
    # A face that repeats a corner is refused by name, the file's and the triangle's: left to
    # trimesh, the vertex no face uses any more would be dropped and the error would be about
    # a vertex count, far from the cause.
    path = tmp_path / "body.obj"
    path.write_text(TRIANGLE + "f 1 2 3\nf 1 2 2\n")
    with pytest.raises(rustcloth.ParameterError) as info:
        read_mesh(path, "colliders[0].path")
    message = str(info.value)
    assert message.startswith("colliders[0].path: ") and "body.obj" in message
    assert "triangle 1 (face 2 of the file, corners [0, 1, 1]) has zero area" in message
    with pytest.raises(rustcloth.ParameterError, match="body.obj"):
        rustcloth.Scene(colliders=[{"shape": "mesh", "path": str(path)}])


def test_collinear_corners_are_refused_as_the_core_would(tmp_path):
    path = tmp_path / "flat.obj"
    path.write_text(TRIANGLE + "v 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 4 2\n")
    with pytest.raises(rustcloth.ParameterError, match=r"triangle 1 .* and 1 more; remove it"):
        read_mesh(path, "p")


def test_nothing_is_dropped_or_merged(tmp_path):
    # A vertex no face uses and two vertices at the same place stay, in the file's order.
    path = tmp_path / "loose.obj"
    path.write_text("v 9 9 9\n" + TRIANGLE + "v 1 0 0\nv 1 1 0\nf 2 3 4\nf 5 6 4\n")
    vertices, triangles = read_mesh(path, "p")
    assert vertices == [[9, 9, 9], [0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]]
    assert triangles == [[1, 2, 3], [4, 5, 3]]
