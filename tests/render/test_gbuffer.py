"""G-buffer contents against the analytic stand-in sheet (a flat square at a known height)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from rustcloth.camera import Camera
from rustcloth.render import Renderer, ShaderError, load_program
from rustcloth.render.renderer import (
    CLOTH_BACK,
    CLOTH_FRONT,
    FLOOR_COLOR,
    MAT_CLOTH,
    MAT_CLOTH_BACK,
    MAT_FLOOR,
    MAT_SPHERE,
)

pytestmark = pytest.mark.render
SIZE = (160, 120)


def _render(ctx: Any, sim: Any, camera: Camera, **opts: Any) -> tuple[Renderer, Any]:
    r = Renderer(ctx, sim, SIZE, shadow_size=512)
    for k, v in opts.items():
        setattr(r, k, v)
    fbo = ctx.simple_framebuffer(SIZE)
    r.update()
    r.render(fbo, camera)
    return r, fbo


def test_normals_are_unit_and_face_the_camera_on_both_sides(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.08)
    above = Camera(eye=(0.4, 2.6, 1.8), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    # From below the sheet the floor would hide it: put the eye between floor and cloth.
    below = Camera(eye=(0.3, 0.2, 1.9), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    seen = {}
    for name, cam in (("above", above), ("below", below)):
        r, _ = _render(ctx, sim, cam)
        g = r.read_gbuffer()
        cloth = np.isin(g["material"], (MAT_CLOTH, MAT_CLOTH_BACK))
        assert cloth.sum() > 200, f"cloth covers too few pixels from {name}"
        n = g["normal"][..., :3][cloth]
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=2e-3)
        to_eye = cam.eye - g["position"][..., :3][cloth]
        # Two-sided: the shading normal always points to the viewer's side of the sheet.
        assert (np.einsum("ij,ij->i", n, to_eye) > 0).mean() > 0.99
        seen[name] = np.bincount(g["material"][cloth].astype(int), minlength=3)
    # One side is the front, the other the back (with its own material id and colour).
    assert seen["above"].argmax() != seen["below"].argmax()


def test_position_albedo_and_depth_match_the_scene(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.0, height=1.0)
    # Low enough that the sky shows above the floor's far edge.
    cam = Camera(eye=(0.0, 1.7, 2.6), target=(0.0, 0.9, 0.0), aspect=SIZE[0] / SIZE[1])
    r, _ = _render(ctx, sim, cam)
    g = r.read_gbuffer()
    mat = g["material"]
    cloth = np.isin(mat, (MAT_CLOTH, MAT_CLOTH_BACK))
    floor = mat == MAT_FLOOR
    assert cloth.any() and floor.any() and (mat == MAT_SPHERE).any() and (mat == 0).any()
    # World positions: the flat sheet sits at y = 1 inside its square; the floor at y = 0.
    pos = g["position"][..., :3]
    np.testing.assert_allclose(pos[cloth][:, 1], 1.0, atol=1e-3)
    assert (np.abs(pos[cloth][:, [0, 2]]) <= 0.6 + 1e-3).all()
    np.testing.assert_allclose(pos[floor][:, 1], 0.0, atol=1e-3)
    # Depth: covered pixels in (0, 1), background cleared to 1; the cloth is nearer the eye
    # than the floor around it.
    depth = g["depth"]
    assert (depth[mat == 0] == 1.0).all()
    assert ((depth[cloth] > 0) & (depth[cloth] < 1)).all()
    dist_cloth = np.linalg.norm(pos[cloth] - cam.eye, axis=1)
    dist_floor = np.linalg.norm(pos[floor] - cam.eye, axis=1)
    assert np.median(dist_cloth) < np.median(dist_floor)
    # Albedo: the floor's checker is its base colour at 80% or 100%.
    ratio = g["albedo"][..., :3][floor] / np.array(FLOOR_COLOR)
    assert ((np.abs(ratio - 1.0) < 0.03) | (np.abs(ratio - 0.8) < 0.03)).all(axis=1).mean() > 0.99
    # Each side's woven albedo has the hue of that side's base colour.
    for material, base in ((MAT_CLOTH, CLOTH_FRONT), (MAT_CLOTH_BACK, CLOTH_BACK)):
        side = g["albedo"][..., :3][mat == material]
        if len(side):
            m, b = side.mean(axis=0), np.array(base)
            assert m @ b / (np.linalg.norm(m) * np.linalg.norm(b)) > 0.97


def test_debug_views_render_distinct_images(standin_cls: Any, ctx: Any) -> None:
    from rustcloth.render import VIEWS

    sim = standin_cls(amp=0.08)
    sim.pin(sim.nx * 3 + 3)  # the stand-in is at rest: pinned must differ from speed
    cam = Camera(eye=(0.4, 2.4, 2.0), target=(0.0, 0.8, 0.0), aspect=SIZE[0] / SIZE[1])
    r = Renderer(ctx, sim, SIZE, shadow_size=512)
    fbo = ctx.simple_framebuffer(SIZE)
    images = {}
    for view in VIEWS:
        r.view = view
        r.update()
        r.render(fbo, cam)
        images[view] = np.frombuffer(fbo.read(components=3), dtype=np.uint8)
    assert len({img.tobytes() for img in images.values()}) == len(VIEWS)


def test_index_buffer_rewritten_only_on_topology_change(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls()
    r = Renderer(ctx, sim, SIZE, shadow_size=256)
    pos_buffer, ibo, count = r.cloth_pos, r.cloth_ibo, r.index_count
    writes = []
    original = type(ibo).write

    def spy(self: Any, data: Any, offset: int = 0) -> None:
        writes.append(len(bytes(data)) if not hasattr(data, "nbytes") else data.nbytes)
        original(self, data, offset=offset)

    type(ibo).write = spy  # type: ignore[method-assign]
    try:
        r.update()
        r.update()
        n_before = len(writes)
        sim.cut(sim.nx * 5 + 5)
        r.update()
    finally:
        type(ibo).write = original  # type: ignore[method-assign]
    # Position/normal writes happen every update; the index buffer's only after the cut.
    ibo_writes = [w for w in writes if w % 12 == 0 and w == sim.triangles.nbytes]
    assert len(ibo_writes) == 1 and n_before == 4
    assert r.index_count < count
    assert r.cloth_pos is pos_buffer and r.cloth_ibo is ibo


def test_shader_compile_error_names_file_and_line(ctx: Any, tmp_path: Any) -> None:
    from rustcloth.render.shaders import SHADER_DIR

    (tmp_path / "fullscreen.vert").write_text((SHADER_DIR / "fullscreen.vert").read_text())
    (tmp_path / "broken.frag").write_text(
        "#version 330 core\nout vec4 f_color;\nvoid main() {\n    f_color = vec4(oops);\n}\n"
    )
    with pytest.raises(ShaderError, match=r"broken\.frag:4"):
        load_program(ctx, "fullscreen.vert", "broken.frag", directory=tmp_path)
