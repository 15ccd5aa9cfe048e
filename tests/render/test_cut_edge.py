"""The drawn edge of a cut, rendered: no dark specks along it.

The story: cut across ``hanging`` and let it swing, and dark specks showed along the cut. Where
a stroke passes near a triangle's corner, the quad left beyond the corner is drawn as two
triangles, one a sliver whose two cut vertices follow two particles' frames; as the cloth bends
the frames disagree, the vertices cross, and the sliver winds against its vertex normals (the
particles', which agree with the cloth round it). Two-sided shading turned the normal by the
winding, so the sliver shaded as the far side of the cloth, its normal facing away from the
eye and the lights: a dark speck. The side a triangle shows is now the one its vertex normals
say wherever its winding disagrees with them."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import rustcloth
from rustcloth.camera import Camera
from rustcloth.render import Renderer
from rustcloth.render import constants as K

pytestmark = pytest.mark.render
SIZE = (160, 120)
CLOTH = (K.CLOTH_FRONT.id, K.CLOTH_BACK.id)


def _gbuffer(ctx: Any, sim: Any, camera: Camera,
             size: tuple[int, int] = SIZE) -> dict[str, np.ndarray]:
    r = Renderer(ctx, sim, size, shadow_size=512)
    r.update()
    r.render(ctx.simple_framebuffer(size), camera)
    return r.read_gbuffer()


def _facing_away(g: dict[str, np.ndarray], camera: Camera) -> np.ndarray:
    """Cloth pixels whose shading normal faces away from the eye: shaded dark."""
    cloth = np.isin(g["material"], CLOTH)
    to_eye = np.asarray(camera.eye) - g["position"]
    return cloth & (np.einsum("hwi,hwi->hw", g["normal"][..., :3], to_eye) < 0.0)


def test_triangles_wound_against_their_normals_shade_as_the_cloth_round_them(
        standin_cls: Any, ctx: Any) -> None:
    camera = Camera(eye=(0.4, 2.6, 1.8), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    sim = standin_cls(amp=0.05)
    plain = _gbuffer(ctx, sim, camera)
    # A band of the sheet's triangles drawn wound the other way, their vertex normals as
    # before: what a crossed sliver is.
    band = np.abs(sim.positions[sim._tris].mean(axis=1)[:, 0]) < 0.15
    assert 0 < band.sum() < len(band) // 2
    sim._tris[band] = sim._tris[band][:, ::-1]
    sim.topology_version += 1
    flipped = _gbuffer(ctx, sim, camera)
    cloth = np.isin(plain["material"], CLOTH)
    assert cloth.sum() > 500
    assert _facing_away(plain, camera).sum() == 0
    assert _facing_away(flipped, camera).sum() == 0, (
        f"{_facing_away(flipped, camera).sum()} of {cloth.sum()} cloth pixels dark")
    # The band shows the side and the normals the sheet shows there unflipped.
    np.testing.assert_array_equal(flipped["material"], plain["material"])
    np.testing.assert_allclose(flipped["normal"][cloth][:, :3], plain["normal"][cloth][:, :3],
                               atol=2e-3)


def flipped_cut_triangles(sim: rustcloth.Simulation) -> int:
    """Drawn triangles with a cut vertex that wind against the sum of their vertex normals."""
    mesh = sim.render_mesh()
    tris = mesh.triangles.astype(np.int64)
    tris = tris[(tris >= sim.num_particles).any(axis=1)]
    x = mesh.positions.astype(np.float64)[tris]
    face = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    facing = mesh.normals.astype(np.float64)[tris].sum(axis=1)
    return int(np.count_nonzero(np.einsum("ij,ij->i", face, facing) < 0.0))


def test_a_cut_swinging_cloth_has_slivers_wound_backwards_and_draws_them_lit(ctx: Any) -> None:
    # Three strokes from above across hanging as it lies flat, each from off an edge to past
    # the middle, at angles to the grid (so near triangles' corners); then it swings down.
    sim = rustcloth.Simulation("hanging")
    for (x0, z0), (x1, z1) in [((-0.6, 0.35), (0.15, -0.1)), ((0.6, -0.3), (-0.1, 0.2)),
                               ((-0.2, -0.6), (0.1, 0.1))]:
        rays = [((x0 + (x1 - x0) * t, 2.5, z0 + (z1 - z0) * t), (0.0, -1.0, 0.0))
                for t in np.linspace(0.0, 1.0, 60)]
        assert sim.sever_stroke(rays) > 0
    camera = Camera(eye=(0.9, 1.3, 1.8), target=(0.0, 1.1, 0.5), aspect=SIZE[0] / SIZE[1])
    flipped = 0
    for _ in range(90):
        sim.advance(1 / 60)
        flipped += flipped_cut_triangles(sim)
    # The drawn mesh has backwards triangles to draw (else this checks nothing) ...
    assert flipped > 0
    # ... and no cloth pixel of the frame is shaded against the side it shows, bar grazing
    # silhouettes, where a smooth normal tilts past the eye.
    g = _gbuffer(ctx, sim, camera)
    cloth = np.isin(g["material"], CLOTH)
    assert _facing_away(g, camera).sum() < 0.02 * cloth.sum(), (_facing_away(g, camera).sum(),
                                                                 cloth.sum())


def test_the_software_tier_draws_triangles_wound_against_their_normals_as_the_sheet(
        standin_cls: Any, ctx: Any) -> None:
    camera = Camera(eye=(0.4, 2.6, 1.8), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    sim = standin_cls(amp=0.05)

    def image() -> np.ndarray:
        r = Renderer(ctx, sim, SIZE, shadow_size=512, tier="software")
        fbo = ctx.simple_framebuffer(SIZE)
        r.update()
        r.render(fbo, camera)
        return np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(-1, 3)

    plain = image()
    band = np.abs(sim.positions[sim._tris].mean(axis=1)[:, 0]) < 0.15
    sim._tris[band] = sim._tris[band][:, ::-1]
    sim.topology_version += 1
    flipped = image()
    differ = np.abs(flipped.astype(int) - plain.astype(int)).max(axis=1) > 2
    assert differ.sum() == 0, f"{differ.sum()} of {len(differ)} pixels differ"


def _with_crossed_sliver(sim: Any) -> None:
    """Give the stand-in sheet a sliver as a cut leaves it once its cut vertices have crossed:
    one of its triangles ends on a cut vertex (index past the particles) raised 10 cm and
    pulled back across the triangle's edge, so that the sliver stands steeply across the
    sheet; the cut vertex's normal (its particle's, on a bending cloth) tips back from the
    sheet's, so it lies behind the sliver's face while the other two lie in front of it. All
    three normals face the eye, as the sheet round it does."""
    nx, n = sim.nx, sim.num_particles
    a = (sim.ny // 2) * nx + nx // 2
    tri = np.array([a, a + 1, a + nx], dtype=np.uint32)
    x = sim.positions
    lifted = (x[a] + x[a + 1]) / 2 + np.array([0.0, 0.1, -0.02], dtype=np.float32)
    face = np.cross(x[a + 1] - x[a], lifted - x[a])
    tipped = np.array([0.0, 1.0, -0.5 * np.sign(face[2])], dtype=np.float32)
    tipped /= np.linalg.norm(tipped)
    plain_positions, plain_topology = sim.render_positions, sim.render_topology

    def render_positions() -> tuple[np.ndarray, np.ndarray]:
        positions, normals = plain_positions()
        return np.vstack([positions, lifted]), np.vstack([normals, tipped])

    def render_topology() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tris, uvs, sources = plain_topology()
        row = np.flatnonzero((np.sort(tris, axis=1) == np.sort(tri)).all(axis=1))[0]
        tris = tris.copy()
        tris[row] = np.where(tris[row] == a + nx, n, tris[row])
        return tris, np.vstack([uvs, uvs[a]]), np.append(sources, np.uint32(a))

    sim.render_positions, sim.render_topology = render_positions, render_topology
    sim.topology_version += 1
    # The sliver's normals are on both sides of its face.
    assert face[1] * np.dot(tipped, face) < 0.0


def test_a_crossed_sliver_whose_normals_straddle_its_face_shows_one_side(
        standin_cls: Any, ctx: Any) -> None:
    # The story: cut hanging and let it swing, and along the cut, with the dark specks gone,
    # lining-coloured specks remained in the fabric. A sliver whose cut vertices crossed
    # stands at any angle to the cloth round it, and some of its vertex normals then lie on
    # one side of its face and some on the other; choosing the side per pixel by its face
    # showed the far side, the lining, on part of it.
    camera = Camera(eye=(0.4, 2.6, 1.8), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    size = (SIZE[0] * 4, SIZE[1] * 4)  # for the sliver to cover more than a few pixels
    sim = standin_cls()
    plain = _gbuffer(ctx, sim, camera, size)
    sides = np.unique(plain["material"][np.isin(plain["material"], CLOTH)])
    assert len(sides) == 1
    _with_crossed_sliver(sim)
    g = _gbuffer(ctx, sim, camera, size)
    cloth = np.isin(g["material"], CLOTH)
    other = cloth & (g["material"] != sides[0])
    assert other.sum() == 0, f"{other.sum()} of {cloth.sum()} cloth pixels show the other side"
    assert _facing_away(g, camera).sum() == 0
