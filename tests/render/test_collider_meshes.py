"""The meshes the renderer draws colliders with (rustcloth.render.meshes), checked as solids
without OpenGL: closed once coincident vertices are merged, wound outwards (by the faces and
by the shading normals), the shape's volume and bounding box, the vertex count."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from rustcloth.render import meshes

SHAPES: list[tuple[dict[str, Any], np.ndarray, float]] = [
    # (collider, half extents of its bounding box, volume)
    ({"shape": "sphere", "radius": 0.3}, np.array([0.3, 0.3, 0.3]), 4 / 3 * math.pi * 0.3**3),
    ({"shape": "box", "half_extents": [0.6, 0.02, 0.4]}, np.array([0.6, 0.02, 0.4]),
     8 * 0.6 * 0.02 * 0.4),
    ({"shape": "capsule", "radius": 0.16, "half_height": 0.22}, np.array([0.16, 0.38, 0.16]),
     math.pi * 0.16**2 * 0.44 + 4 / 3 * math.pi * 0.16**3),
    ({"shape": "cylinder", "radius": 0.4, "half_height": 0.02}, np.array([0.4, 0.02, 0.4]),
     math.pi * 0.4**2 * 0.04),
]
# The tessellation's vertex counts: the lathe's (rows x (segments + 1)), six faces of four.
VERTEX_COUNTS = {"sphere": (meshes.RINGS + 1) * (meshes.SEGMENTS + 1), "box": 24,
                 "capsule": (2 * (meshes.RINGS // 2 + 1)) * (meshes.SEGMENTS + 1),
                 "cylinder": 6 * (meshes.SEGMENTS + 1)}


def _solid(vertices: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions merged where they coincide, and the triangles that keep an area."""
    p = vertices[:, :3].astype(np.float64)
    _, first, merged = np.unique(np.round(p, 6), axis=0, return_index=True,
                                 return_inverse=True)
    tris = merged.reshape(-1)[indices]
    q = p[first]
    area = np.linalg.norm(np.cross(q[tris[:, 1]] - q[tris[:, 0]], q[tris[:, 2]] - q[tris[:, 0]]),
                          axis=1)
    return q, tris[area > 1e-12]


def _directed_edges(tris: np.ndarray) -> list[tuple[int, int]]:
    return [(int(a), int(b)) for t in tris for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))]


@pytest.mark.parametrize(("collider", "half", "volume"), SHAPES,
                         ids=[c["shape"] for c, _, _ in SHAPES])
def test_round_and_box_colliders_are_closed_outward_solids_of_their_size(
        collider: dict[str, Any], half: np.ndarray, volume: float) -> None:
    vertices, indices = meshes.collider_mesh(collider)
    assert vertices.dtype == np.float32 and vertices.shape == (VERTEX_COUNTS[collider["shape"]], 8)
    assert indices.dtype == np.uint32 and indices.max() < len(vertices)
    assert vertices.flags.c_contiguous and indices.flags.c_contiguous  # as GL buffers take them
    # The bounding box is the shape's, centred on its origin.
    np.testing.assert_allclose(vertices[:, :3].min(axis=0), -half, atol=1e-6)
    np.testing.assert_allclose(vertices[:, :3].max(axis=0), half, atol=1e-6)
    assert meshes.bounding_radius(collider) >= np.linalg.norm(vertices[:, :3], axis=1).max() - 1e-6
    # Closed and consistently wound: each directed edge once, and its reverse once.
    q, tris = _solid(vertices, indices)
    edges = _directed_edges(tris)
    assert len(set(edges)) == len(edges)
    assert set(edges) == {(b, a) for a, b in edges}
    # Outwards: the enclosed volume (divergence theorem) is positive and the shape's (to the
    # tessellation's error for the round ones).
    signed = np.einsum("ij,ij->i", q[tris[:, 0]], np.cross(q[tris[:, 1]], q[tris[:, 2]])).sum() / 6
    assert signed == pytest.approx(volume, rel=0.02)
    # The shading normals are unit and agree with the faces' winding.
    n = vertices[:, 3:6]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    p = vertices[:, :3]
    face = np.cross(p[indices[:, 1]] - p[indices[:, 0]], p[indices[:, 2]] - p[indices[:, 0]])
    keep = np.linalg.norm(face, axis=1) > 1e-9
    mean_normal = n[indices].mean(axis=1)
    assert (np.einsum("ij,ij->i", face[keep], mean_normal[keep]) > 0).all()


def test_a_mesh_collider_is_drawn_with_its_own_triangles_flat_shaded() -> None:
    # A tetrahedron wound outwards.
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    vertices, indices = meshes.collider_mesh({"shape": "mesh", "vertices": v, "triangles": t})
    assert vertices.shape == (12, 8) and indices.shape == (4, 3)
    np.testing.assert_array_equal(vertices[:, :3].reshape(4, 3, 3), v[t])
    centroid = v.mean(axis=0)
    for k in range(4):
        n = vertices[3 * k, 3:6]
        assert (vertices[3 * k:3 * k + 3, 3:6] == n).all()  # one normal per face
        assert float(n @ (v[t[k]].mean(axis=0) - centroid)) > 0  # facing out
    assert meshes.bounding_radius({"shape": "mesh", "vertices": v}) == pytest.approx(1.0)


def test_a_plane_is_a_large_square_facing_local_up() -> None:
    vertices, indices = meshes.collider_mesh({"shape": "plane"}, plane_half=5.0)
    p = vertices[:, :3]
    np.testing.assert_array_equal(p[:, 1], 0.0)
    np.testing.assert_allclose(p[:, [0, 2]].min(axis=0), -5.0)
    np.testing.assert_allclose(p[:, [0, 2]].max(axis=0), 5.0)
    face = np.cross(p[indices[:, 1]] - p[indices[:, 0]], p[indices[:, 2]] - p[indices[:, 0]])
    assert (face[:, 1] > 0).all() and (vertices[:, 4] == 1.0).all()
    assert meshes.bounding_radius({"shape": "plane"}) == math.inf


def test_pose_matrix_turns_by_the_quaternion_then_moves() -> None:
    # A quarter turn about z takes local y (a capsule's axis) onto -x.
    s = math.sqrt(0.5)
    m = meshes.pose_matrix([1.0, 2.0, 3.0], [0.0, 0.0, s, s])
    np.testing.assert_allclose(m @ [0.0, 1.0, 0.0, 1.0], [0.0, 2.0, 3.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-6)
