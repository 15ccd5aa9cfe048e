"""Camera maths against hand-computed rays; no OpenGL needed."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rustcloth
from rustcloth.camera import Camera, gl_bytes


def _camera(aspect: float = 2.0) -> Camera:
    # Eye on +z looking at the origin: forward is -z, right +x, up +y.
    return Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), fov=60.0, aspect=aspect)


def test_centre_pixel_ray_is_the_forward_direction() -> None:
    cam = _camera()
    origin, d = cam.ray(320.0, 160.0, 640, 320)
    np.testing.assert_allclose(origin, [0.0, 0.0, 5.0])
    np.testing.assert_allclose(d, [0.0, 0.0, -1.0], atol=1e-6)
    assert abs(np.linalg.norm(d) - 1.0) < 1e-6


def test_edge_and_corner_rays_at_the_fov_angles() -> None:
    cam = _camera(aspect=2.0)
    w, h = 640, 320
    half_v = math.radians(30.0)
    half_h = math.atan(2.0 * math.tan(half_v))
    _, top = cam.ray(w / 2, 0.0, w, h)  # top edge: pixel rows grow downwards
    np.testing.assert_allclose(top, [0.0, math.sin(half_v), -math.cos(half_v)], atol=1e-6)
    _, right = cam.ray(w, h / 2, w, h)
    np.testing.assert_allclose(right, [math.sin(half_h), 0.0, -math.cos(half_h)], atol=1e-6)
    _, corner = cam.ray(0.0, h, w, h)  # bottom-left
    expected = np.array([-2.0 * math.tan(half_v), -math.tan(half_v), -1.0])
    np.testing.assert_allclose(corner, expected / np.linalg.norm(expected), atol=1e-6)


def test_project_unproject_round_trip() -> None:
    cam = Camera(eye=(1.3, 2.0, 3.1), target=(0.2, 0.4, -0.1), fov=45.0, aspect=4 / 3)
    rng = np.random.default_rng(1)
    for p in rng.uniform(-1.0, 1.0, size=(20, 3)):
        px, py, depth = cam.project(p, 800, 600)
        assert -1.0 < depth < 1.0
        origin, d = cam.ray(px, py, 800, 600)
        # The point lies on the ray through its own pixel.
        rel = p - origin
        assert np.linalg.norm(rel - (rel @ d) * d) < 1e-4


def test_view_projection_maps_target_to_screen_centre() -> None:
    cam = Camera(eye=(2.0, 1.0, 2.0), target=(0.0, 0.5, 0.0), aspect=1.5)
    px, py, _ = cam.project(cam.target, 300, 200)
    assert abs(px - 150.0) < 1e-3 and abs(py - 100.0) < 1e-3
    assert len(gl_bytes(cam.view_projection)) == 64


def test_drag_plane_point_faces_the_camera() -> None:
    cam = _camera()
    point = np.array([0.3, -0.2, 1.0], dtype=np.float32)
    ray = cam.ray(100.0, 50.0, 640, 320)
    hit = cam.drag_plane_point(ray, point)
    # Same depth along the view direction as the grabbed point, and on the ray.
    assert abs(float((hit - point) @ cam.forward)) < 1e-5
    rel = hit - ray[0]
    assert np.linalg.norm(rel - (rel @ ray[1]) * ray[1]) < 1e-5


def test_orbit_keeps_distance_and_clamps_pitch() -> None:
    cam = _camera()
    cam.orbit(0.7, 0.3)
    assert abs(np.linalg.norm(cam.eye - cam.target) - 5.0) < 1e-5
    cam.orbit(0.0, 10.0)
    assert cam.forward[1] > -1.0 + 1e-4  # never straight down, the basis stays defined
    assert np.isfinite(cam.view).all()


def test_zoom_scales_distance_and_rejects_bad_factors() -> None:
    cam = _camera()
    cam.zoom(0.5)
    assert abs(np.linalg.norm(cam.eye - cam.target) - 2.5) < 1e-5
    with pytest.raises(ValueError, match="zoom factor"):
        cam.zoom(0.0)


def test_fit_distance_puts_the_farthest_point_on_the_margin() -> None:
    from rustcloth.camera import fit_distance

    direction = np.array([0.0, 0.0, 1.0])  # eye on +z looking down -z
    points = np.array([[1.0, 0.0, 0.0], [-1.0, 0.5, 0.0]])
    d = fit_distance(points, (0.0, 0.0, 0.0), direction, 60.0, 2.0, margin=0.9)
    cam = Camera(eye=(0.0, 0.0, d), target=(0.0, 0.0, 0.0), fov=60.0, aspect=2.0)
    xs = [cam.project(p, 200, 100)[0] for p in points]
    # |x| = 1 at that distance lands at 90 % of the half-width: pixel 100 +- 90.
    assert max(abs(x - 100.0) for x in xs) == pytest.approx(90.0, abs=1e-3)


def test_light_view_projection_holds_every_point() -> None:
    from rustcloth.camera import light_view_projection

    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.0, 1.0, size=(50, 3)) * [2.0, 1.0, 0.5] + [0.3, 1.0, -0.2]
    m = light_view_projection([-0.3, -1.0, 0.2], pts)
    clip = np.c_[pts, np.ones(len(pts))] @ m.T
    ndc = clip[:, :3] / clip[:, 3:]
    assert (np.abs(ndc) <= 1.0 + 1e-5).all()
    assert (np.abs(ndc).max(axis=0) > 0.95).all()  # tight, not a loose box


# The garments are tubes round a body, half of them facing away from any eye: their front is
# the outside, tested in tests/test_garment.py.
BUILTIN_SCENES = [n for n in rustcloth.scenes() if n not in ("shirt", "skirt")]
WRAPS_ROUND_A_POLE = ("flag_hole",)
"""Scenes in still air whose hung cloth falls against a pole and wraps round it, showing both
sides once it has moved (only their opening view is the front)."""


@pytest.mark.parametrize("name", BUILTIN_SCENES)
def test_each_scene_opens_framed_with_its_front_towards_the_camera(name: str) -> None:
    """Every built-in scene (mesh cloths included: a mesh has no grid plane, and flag_hole,
    standing up, opened framed from the side on its plain back) opens on the cloth's front,
    all of it in frame, and a falling cloth stays in the window: the first view is what a
    person judges the demo by."""
    pytest.importorskip("moderngl")  # rustcloth.render needs the viewer extra
    import rustcloth
    from rustcloth.render.layout import box_corners
    from rustcloth.render.renderer import layout_of

    sim = rustcloth.Simulation(rustcloth.load_scene(name))
    layout = layout_of(sim)
    w, h = 1280, 720
    cam = layout.camera(w / h)
    p = sim.positions
    boxes = {"cloth": box_corners(p.min(axis=0), p.max(axis=0)),
             "reach": box_corners(layout.reach_min, layout.reach_max)}
    for s in layout.spheres:
        boxes["sphere"] = box_corners(s.center - s.radius, s.center + s.radius)
    for what, corners in boxes.items():
        for c in corners:
            x, y, depth = cam.project(c, w, h)
            assert 0.0 <= x <= w and 0.0 <= y <= h and -1.0 < depth < 1.0, (what, c, x, y)
    # The front side (the one the renderer gives the front material) faces the eye.
    front = sim.normals if layout.front_is_winding else -sim.normals
    facing = np.einsum("ij,ij->i", front, cam.eye - p) > 0.0
    assert facing.mean() > 0.95
    if abs(float(layout.front[1])) > 0.7 or name in WRAPS_ROUND_A_POLE:
        return  # lying or draped: its far slopes face away, as they should
    # A hanging cloth once it has moved (hanging swings down about its pins): still the front.
    sim.advance(1.5)
    front = sim.normals if layout.front_is_winding else -sim.normals
    facing = np.einsum("ij,ij->i", front, cam.eye - sim.positions) > 0.0
    assert facing[sim.alive].mean() > 0.7
