"""Mesh collider files read by ``rustcloth.meshes.read_mesh``: as written, and a bad triangle
reported with the file and the face."""

from __future__ import annotations

import numpy as np
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


# Two triangles under `g left` (and object `sheet`), two under `g right top` (two groups at
# once), a vertex no face uses between them; a quad under `o flap`.
GROUPED = """\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 9 9 9
v 2 0 0
v 2 1 0
v 3 0 0
o sheet
g left
f 1 2 3
f 1 3 4
g right top
f 2 6 7
f -8 -2 -6
o flap
g
f 6 8 7
"""


def test_an_obj_files_groups_are_the_vertices_of_their_faces(tmp_path):
    from rustcloth.meshes import mesh_arrays
    from rustcloth.vertex_groups import group_vertices

    path = tmp_path / "grouped.obj"
    path.write_text(GROUPED)
    vertices, _ = mesh_arrays(path, "p")
    assert len(vertices) == 8  # the file's own numbering
    groups = {name: v.tolist() for name, v in group_vertices(path, vertices, "p").items()}
    # `-8 -2 -6` counts back from the eighth vertex: vertices 1, 7 and 3 of the file.
    assert groups == {"left": [0, 1, 2, 3], "right": [0, 1, 2, 5, 6], "top": [0, 1, 2, 5, 6],
                      "sheet": [0, 1, 2, 3, 5, 6], "flap": [5, 6, 7]}


def test_obj_group_vertices_are_numbered_as_trimesh_numbers_them(tmp_path):
    # Two materials make trimesh load two meshes, each with every vertex of the file, and join
    # them: each group must name trimesh's vertices (both copies), found here by their
    # positions, which the file gives each vertex once.
    import trimesh
    from rustcloth.meshes import mesh_arrays
    from rustcloth.vertex_groups import group_vertices

    path = tmp_path / "seam.obj"
    path.write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
        "g a\nusemtl x\nf 1 2 3\nf 1 3 4\ng b\nusemtl y\nf 2 5 3\n"
    )
    vertices, triangles = mesh_arrays(path, "p")
    loaded = trimesh.load(path, force="mesh", process=False, maintain_order=True)
    assert np.array_equal(vertices, np.asarray(loaded.vertices))
    assert len(vertices) == 10  # renumbered: the general path is the one tested
    groups = group_vertices(path, vertices, "p")
    file_positions = {"a": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                      "b": [[1, 0, 0], [2, 0, 0], [1, 1, 0]]}
    for name, expected in file_positions.items():
        assert groups[name].tolist() == [
            j for j, v in enumerate(vertices.tolist()) if v in expected
        ]


def test_obj_groups_refuse_a_vertex_trimesh_renumbered_that_two_share(tmp_path):
    from rustcloth.meshes import mesh_arrays
    from rustcloth.vertex_groups import group_vertices

    path = tmp_path / "twin.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\n"
                    "g a\nusemtl x\nf 1 2 3\ng b\nusemtl y\nf 4 5 3\n")
    vertices, _ = mesh_arrays(path, "p")
    with pytest.raises(rustcloth.ParameterError, match=r"^p: .*twin.obj.* cannot be told"):
        group_vertices(path, vertices, "p")


def test_obj_groups_read_a_vertex_written_after_its_face_and_refuse_one_not_written(tmp_path):
    from rustcloth.vertex_groups import group_vertices

    path = tmp_path / "late.obj"
    path.write_text("v 0 0 0\nv 1 0 0\ng a\nf 1 2 3\nv 0 1 0\n")
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    assert group_vertices(path, vertices, "p")["a"].tolist() == [0, 1, 2]
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\ng a\nf 1 2 4\n")
    with pytest.raises(rustcloth.ParameterError, match=r"^p: .*late.obj' line 5: a face names "
                                                      r"vertex 4, and the file has 3 vertices"):
        group_vertices(path, vertices, "p")
