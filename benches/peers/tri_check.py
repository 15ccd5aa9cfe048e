"""One independent triangle-triangle intersection checker, applied to every peer's positions.

A numpy port of the checker in ``tests/self_collision.rs`` (which it does not import: that one
is Rust, and tests/ is not a library): two triangles that share no particle and are not
coplanar intersect exactly when an edge of one properly crosses the other. A segment ``p q``
crosses triangle ``a b c`` when ``p`` and ``q`` lie strictly on opposite sides of its plane
and the line ``p q`` strictly on the same side of each of its edges (signed volumes, Segura
and Feito 1998), in float64. A sign within 1e-12 of the edge lengths' product counts as zero
(a touch, not a crossing). Pairs sharing a vertex are excluded. Candidate pairs are those whose
bounding boxes overlap, found in blocks so that memory stays bounded; it shares no code with
either solver.
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-12


def _orient_sign(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Sign (-1, 0, 1) of six times the signed volume of tetrahedra ``a b c d`` (rows)."""
    u, v, w = b - a, c - a, d - a
    vol = np.einsum("ij,ij->i", np.cross(u, v), w)
    scale = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1) * np.linalg.norm(w, axis=1)
    s = np.sign(vol)
    s[np.abs(vol) <= _EPS * scale] = 0
    return s


def _segment_hits_triangle(p, q, a, b, c) -> np.ndarray:
    """Whether each segment ``p q`` properly crosses triangle ``a b c`` (row-wise)."""
    sp, sq = _orient_sign(a, b, c, p), _orient_sign(a, b, c, q)
    e0 = _orient_sign(p, q, a, b)
    e1 = _orient_sign(p, q, b, c)
    e2 = _orient_sign(p, q, c, a)
    return (sp * sq < 0) & (e0 != 0) & (e0 == e1) & (e1 == e2)


def triangles_intersect(t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Whether triangles ``t[k]`` and ``u[k]`` ((m, 3, 3) corner arrays) intersect."""
    hit = np.zeros(len(t), dtype=bool)
    for s, o in ((t, u), (u, t)):
        for k in range(3):
            hit |= _segment_hits_triangle(s[:, k], s[:, (k + 1) % 3], o[:, 0], o[:, 1], o[:, 2])
    return hit


def intersecting_pairs(positions: np.ndarray, triangles: np.ndarray,
                       block: int = 256) -> np.ndarray:
    """The (k, 2) pairs ``(a < b)`` of triangles sharing no vertex that intersect."""
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = x[tris]  # (m, 3, 3)
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    found = []
    m = len(tris)
    for start in range(0, m, block):
        rows = np.arange(start, min(start + block, m))
        # Boxes overlap on every axis, and only pairs a < b.
        overlap = np.all((lo[rows, None, :] <= hi[None, :, :])
                         & (lo[None, :, :] <= hi[rows, None, :]), axis=2)
        overlap &= rows[:, None] < np.arange(m)[None, :]
        ia, ib = np.nonzero(overlap)
        ia = rows[ia]
        shared = (tris[ia][:, :, None] == tris[ib][:, None, :]).any(axis=(1, 2))
        ia, ib = ia[~shared], ib[~shared]
        if len(ia):
            hit = triangles_intersect(corners[ia], corners[ib])
            found.append(np.stack([ia[hit], ib[hit]], axis=1))
    return np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)


def count(positions: np.ndarray, triangles: np.ndarray) -> int:
    """How many pairs of triangles sharing no vertex intersect."""
    return len(intersecting_pairs(positions, triangles))


def self_test() -> None:
    """The checker finds a crossing and not a near miss (as the Rust test does)."""
    t = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 1]])
    through = np.array([[0.2, -0.5, 0.2], [0.2, 0.5, 0.2], [0.3, 0.5, 0.3]])
    above = through + [0.0, 0.51, 0.0]
    assert triangles_intersect(t[None], through[None])[0]
    assert not triangles_intersect(t[None], above[None])[0]
    x = np.concatenate([t, through])
    assert count(x, np.array([[0, 1, 2], [3, 4, 5]])) == 1
    assert count(np.concatenate([t, above]), np.array([[0, 1, 2], [3, 4, 5]])) == 0


if __name__ == "__main__":
    self_test()
    print("tri_check: self test passed")
