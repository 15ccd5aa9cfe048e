"""Colliders on screen: every shape drawn through the G-buffer at the pose the simulation
reports, in the built-in collider scenes and in a scene with a plane and a mesh."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import rustcloth
from rustcloth.render import Renderer, meshes
from rustcloth.render import constants as K

pytestmark = pytest.mark.render
SIZE = (160, 120)

# A ramp (a plane tilted 0.15 rad about z, above the floor) and a tetrahedron mesh above it,
# off to the side of a small falling cloth, so neither hides behind it at the start.
TETRA = {"vertices": [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.3]],
         "triangles": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}
PLANE_AND_MESH = {
    "cloth": {"nx": 12, "ny": 12, "size": [0.4, 0.4], "center": [0.0, 1.0, 0.0], "pins": []},
    "floor": {"height": 0.0},
    "colliders": [
        {"shape": "plane", "center": [-0.5, 0.2, 0.0], "rotation": [0.0, 0.0, 0.15]},
        {"shape": "mesh", "center": [0.6, 0.5, 0.1], **TETRA},
    ],
}


def _draw(ctx: Any, sim: rustcloth.Simulation, show: bool = True,
          renderer: Renderer | None = None) -> tuple[np.ndarray, dict[str, np.ndarray], Renderer]:
    r = renderer or Renderer(ctx, sim, SIZE, shadow_size=512)
    r.show_colliders = show
    camera = r.layout.camera(SIZE[0] / SIZE[1])
    fbo = ctx.simple_framebuffer(SIZE)
    r.update()
    r.render(fbo, camera)
    image = np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(SIZE[1], SIZE[0], 3)
    return image[::-1].astype(np.int16), {k: v[::-1] for k, v in r.read_gbuffer().items()}, r


def _near_a_collider(points: np.ndarray, sim: rustcloth.Simulation, tol: float) -> np.ndarray:
    """Whether each point is within ``tol`` of a collider's surface: inside the ball about its
    pose that holds it, and (for a plane) on the plane."""
    positions, rotations = sim.collider_poses()
    near = np.zeros(len(points), dtype=bool)
    for c, p, q in zip(sim.colliders(), positions, rotations, strict=True):
        if c["shape"] == "plane":
            up = meshes.rotation_matrix(q)[:, 1]
            near |= np.abs((points - p) @ up) < tol
        else:
            near |= np.linalg.norm(points - p, axis=1) < meshes.bounding_radius(c) + tol
    return near


def _off_the_ramp(point: np.ndarray, sim: rustcloth.Simulation) -> float:
    """Height of ``point`` above the plane and mesh scene's ramp (its collider 0)."""
    positions, rotations = sim.collider_poses()
    return float((point - positions[0]) @ meshes.rotation_matrix(rotations[0])[:, 1])


def _centre_pixel(r: Renderer, point: np.ndarray) -> tuple[int, int]:
    x, y, _ = r.layout.camera(SIZE[0] / SIZE[1]).project(point, *SIZE)
    return int(y), int(x)  # rows top to bottom, as the images here are


@pytest.mark.parametrize("scene", ["tablecloth", "mannequin", "spinner", "plane_and_mesh"])
def test_colliders_are_drawn_where_the_simulation_has_them(ctx: Any, scene: str) -> None:
    sim = rustcloth.Simulation(
        rustcloth.Scene(**PLANE_AND_MESH) if scene == "plane_and_mesh"
        else rustcloth.load_scene(scene))
    shown, g, r = _draw(ctx, sim)
    hidden, g_hidden, _ = _draw(ctx, sim, show=False, renderer=r)
    drawn = g["material"] == K.COLLIDER.id
    assert drawn.sum() > 0.005 * drawn.size, "the colliders cover almost no pixels"
    assert not (g_hidden["material"] == K.COLLIDER.id).any()
    # The picture changes where they are drawn: they are lit, not left as the sky or floor.
    assert np.abs(shown - hidden)[drawn].max(axis=1).mean() > 20
    # Every collider pixel lies on a collider at its pose.
    assert _near_a_collider(g["position"][drawn], sim, tol=0.01).all()
    # A collider whose centre is not behind the cloth shows there.
    positions, _ = sim.collider_poses()
    seen = [g["material"][_centre_pixel(r, p)] == K.COLLIDER.id for p in positions]
    assert any(seen)
    if scene == "plane_and_mesh":
        mesh_centre = positions[1] + np.mean(TETRA["vertices"], axis=0)
        assert seen[0] and g["material"][_centre_pixel(r, mesh_centre)] == K.COLLIDER.id


def test_a_posed_collider_is_drawn_at_its_new_pose(ctx: Any) -> None:
    sim = rustcloth.Simulation(rustcloth.Scene(**PLANE_AND_MESH))
    _, g, r = _draw(ctx, sim)
    mesh = sim.colliders()[1]
    reach = meshes.bounding_radius(mesh)
    start = sim.collider_poses()[0][1]
    before = _centre_pixel(r, start + np.mean(TETRA["vertices"], axis=0))
    assert np.linalg.norm(g["position"][before] - start) < reach
    assert _off_the_ramp(g["position"][before], sim) > 0.05
    # Move it 0.35 m to the camera's left and give it a quarter turn about y; one step gets
    # it there.
    shift = np.array([-0.32, 0.0, 0.14])
    turn = [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)]
    sim.set_collider_pose(1, start + shift, turn)
    sim.step()
    _, g, _ = _draw(ctx, sim, renderer=r)
    now = sim.collider_poses()[0][1]
    np.testing.assert_allclose(now, start + shift)
    after = _centre_pixel(r, now + meshes.rotation_matrix(turn) @ np.mean(TETRA["vertices"], 0))
    assert after != before
    # The mesh is drawn at the new pose, and no longer at the old one: the ramp shows there.
    assert g["material"][after] == K.COLLIDER.id
    assert np.linalg.norm(g["position"][after] - now) < reach
    assert _off_the_ramp(g["position"][before], sim) < 0.01
    drawn = g["material"] == K.COLLIDER.id
    assert _near_a_collider(g["position"][drawn], sim, tol=0.01).all()


@pytest.mark.parametrize("scene", ["tablecloth", "round_tablecloth"])
def test_a_table_does_not_show_through_the_tablecloth_on_it(ctx: Any, scene: str) -> None:
    # The cloth on a table is drawn as flat triangles between particles held `thickness` off
    # it; where it bends over the table's edge a triangle cuts the corner (by up to 2 cm on
    # round_tablecloth's coarser mesh), and the edge showed through the cloth as a dotted
    # line (tablecloth) or slivers (round_tablecloth). The solids' depth is now written
    # further from the eye, so a pixel the cloth covers stays cloth.
    sim = rustcloth.Simulation(scene)
    sim.advance(2.0)
    size = (640, 360)
    r = Renderer(ctx, sim, size, shadow_size=512)
    camera = r.layout.camera(size[0] / size[1])
    fbo = ctx.simple_framebuffer(size)
    g = {}
    for show in (False, True):
        r.show_colliders = show
        r.update()
        r.render(fbo, camera)
        g[show] = r.read_gbuffer()
    cloth = np.isin(g[False]["material"], (K.CLOTH_FRONT.id, K.CLOTH_BACK.id))
    table = g[True]["material"] == K.COLLIDER.id
    # Where the cloth leaves the table uncovered (its leg, a strip of its top) depends on the
    # drape, which any change of round-off moves: a few dozen pixels are enough to be on screen.
    assert table.sum() > 40, "the table is not on screen"
    # A leg in front of the cloth hanging behind it covers cloth legitimately, a metre away.
    gap = np.linalg.norm(g[True]["position"] - g[False]["position"], axis=-1)
    assert (cloth & table & (gap < 0.1)).sum() == 0
