"""G-buffer contents against the analytic stand-in sheet (a flat square at a known height):
normals, positions rebuilt from depth, materials, the fabric's albedo, the debug views."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from rustcloth.camera import Camera
from rustcloth.render import Renderer, ShaderError, load_program
from rustcloth.render import constants as K
from rustcloth.render.shaders import with_constants

pytestmark = pytest.mark.render
SIZE = (160, 120)


def _render(ctx: Any, sim: Any, camera: Camera, size: tuple[int, int] = SIZE,
            **opts: Any) -> Renderer:
    r = Renderer(ctx, sim, size, shadow_size=512)
    for k, v in opts.items():
        setattr(r, k, v)
    fbo = ctx.simple_framebuffer(size)
    r.update()
    r.render(fbo, camera)
    return r


def test_normals_are_unit_and_face_the_camera_on_both_sides(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.08)
    above = Camera(eye=(0.4, 2.6, 1.8), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    # From below the sheet the floor would hide it: put the eye between floor and cloth.
    below = Camera(eye=(0.3, 0.2, 1.9), target=(0.0, 1.0, 0.0), aspect=SIZE[0] / SIZE[1])
    seen = {}
    for name, cam in (("above", above), ("below", below)):
        g = _render(ctx, sim, cam).read_gbuffer()
        cloth = np.isin(g["material"], (K.CLOTH_FRONT.id, K.CLOTH_BACK.id))
        assert cloth.sum() > 200, f"cloth covers too few pixels from {name}"
        n = g["normal"][..., :3][cloth]
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=2e-3)
        to_eye = cam.eye - g["position"][cloth]
        # Two-sided: the shading normal always points to the viewer's side of the sheet.
        assert (np.einsum("ij,ij->i", n, to_eye) > 0).mean() > 0.99
        seen[name] = np.bincount(g["material"][cloth].astype(int), minlength=3).argmax()
    # A sheet lying in xz shows its front from above and its back from below.
    assert seen == {"above": K.CLOTH_FRONT.id, "below": K.CLOTH_BACK.id}


def test_positions_from_depth_and_materials_match_the_scene(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.0, height=1.0)
    # Low enough that the sky shows above the floor's far edge.
    cam = Camera(eye=(0.0, 1.7, 2.6), target=(0.0, 0.9, 0.0), aspect=SIZE[0] / SIZE[1])
    g = _render(ctx, sim, cam).read_gbuffer()
    mat = g["material"]
    cloth = np.isin(mat, (K.CLOTH_FRONT.id, K.CLOTH_BACK.id))
    floor = mat == K.FLOOR.id
    assert cloth.any() and floor.any() and (mat == K.SPHERE.id).any() and (mat == 0).any()
    # World positions (rebuilt from the depth buffer): the flat sheet at y = 1 inside its
    # square, the floor at y = 0.
    pos = g["position"]
    np.testing.assert_allclose(pos[cloth][:, 1], 1.0, atol=2e-3)
    assert (np.abs(pos[cloth][:, [0, 2]]) <= 0.6 + 2e-3).all()
    np.testing.assert_allclose(pos[floor][:, 1], 0.0, atol=2e-3)
    depth = g["depth"]
    assert (depth[mat == 0] == 1.0).all()
    assert ((depth[cloth] > 0) & (depth[cloth] < 1)).all()
    # The floor's albedo is its colour, tile by tile a few per cent either way, darker in
    # the grout lines.
    ratio = g["albedo"][floor] / np.array(K.srgb_to_linear(K.FLOOR.color))
    assert np.median(ratio) == pytest.approx(1.0, abs=0.08)
    assert (ratio < 1.12).all() and (ratio > 0.4).all()


def test_fabric_front_is_a_tartan_back_is_plain_and_neither_follows_the_grid(
        standin_cls: Any, ctx: Any) -> None:
    cam = Camera(eye=(0.0, 2.6, 0.01), target=(0.0, 1.0, 0.0), aspect=1.0)
    albedo = {}
    for n in (24, 48):
        g = _render(ctx, standin_cls(nx=n, ny=n), cam, size=(128, 128)).read_gbuffer()
        front = g["material"] == K.CLOTH_FRONT.id
        assert front.sum() > 3000
        albedo[n] = np.sqrt(g["albedo"])  # near sRGB: differences as the eye sees them
        side = albedo[n][front]
        mean = (side ** 2).mean(axis=0)
        want = np.array(K.srgb_to_linear(K.tartan_mean()))
        assert mean @ want / (np.linalg.norm(mean) * np.linalg.norm(want)) > 0.97
        assert side.std(axis=0).max() > 0.08  # stripes, not a flat colour
    # The pattern lives in metres of cloth: twice the particles, the same picture.
    assert np.abs(albedo[24] - albedo[48]).mean() < 0.02

    below = Camera(eye=(0.3, 0.2, 1.9), target=(0.0, 1.0, 0.0), aspect=1.0)
    g = _render(ctx, standin_cls(), below, size=(128, 128)).read_gbuffer()
    back = np.sqrt(g["albedo"][g["material"] == K.CLOTH_BACK.id])
    assert len(back) > 500
    np.testing.assert_allclose(back.mean(axis=0), K.CLOTH_BACK.color, atol=0.06)
    assert back.std(axis=0).max() < 0.05


def _views(ctx: Any, sim: Any) -> tuple[dict[str, np.ndarray], Renderer]:
    cam = Camera(eye=(0.4, 2.4, 2.0), target=(0.0, 0.8, 0.0), aspect=SIZE[0] / SIZE[1])
    r = Renderer(ctx, sim, SIZE, shadow_size=512)
    fbo = ctx.simple_framebuffer(SIZE)
    images = {}
    for view in K.VIEWS:
        r.view = view
        r.update()
        r.render(fbo, cam)
        images[view] = np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(
            SIZE[1], SIZE[0], 3)
    return images, r


def test_debug_views_render_distinct_images(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.08)
    sim.pin(sim.nx * 3 + 3)
    images, _ = _views(ctx, sim)
    assert len({img.tobytes() for img in images.values()}) == len(K.VIEWS)
    # The shadow map is square: letterboxed in the middle of a wide view, not stretched.
    side = SIZE[1]
    bars = images["shadow map"][:, : (SIZE[0] - side) // 2 - 1]
    assert len(np.unique(bars.reshape(-1, 3), axis=0)) == 1
    middle = images["shadow map"][:, (SIZE[0] - side) // 2 + 1: (SIZE[0] + side) // 2 - 1]
    assert len(np.unique(middle.reshape(-1, 3), axis=0)) > 1


def test_scalar_views_show_the_sheet_even_at_rest(standin_cls: Any, ctx: Any) -> None:
    # At rest every speed is zero and nothing is pinned: one value everywhere. The particle
    # grid's lines and the key light keep the sheet from reading as one flat colour.
    images, r = _views(ctx, standin_cls(amp=0.0))
    cloth = np.isin(r.read_gbuffer()["material"], (K.CLOTH_FRONT.id, K.CLOTH_BACK.id))
    for view in ("speed", "pinned"):
        colors = images[view][cloth].astype(float)
        assert colors.std(axis=0).max() > 4.0, view  # a flat colour: below 1


def test_index_buffer_rewritten_only_on_topology_change(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls()
    r = Renderer(ctx, sim, SIZE, shadow_size=256)
    pos_buffer, ibo, count = r.cloth_pos, r.cloth_ibo, r.index_count
    writes = []
    original = type(ibo).write

    def spy(self: Any, data: Any, offset: int = 0) -> None:
        if self is ibo:
            writes.append(data.nbytes)
        original(self, data, offset=offset)

    type(ibo).write = spy  # type: ignore[method-assign]
    try:
        r.update()
        r.update()
        assert writes == []
        sim.cut(sim.nx * 5 + 5)
        r.update()
    finally:
        type(ibo).write = original  # type: ignore[method-assign]
    assert writes == [sim.triangles.nbytes]
    assert r.index_count < count
    assert r.cloth_pos is pos_buffer and r.cloth_ibo is ibo


def test_shader_constants_come_from_python(ctx: Any) -> None:
    header = K.glsl_header()
    for m in K.MATERIALS:
        assert f"#define MAT_{m.name} {m.id}\n" in header
    assert f"#define VIEW_SHADOW_MAP {K.VIEWS.index('shadow map')}\n" in header
    # The header goes after #version, and #line keeps the file's own line numbers.
    src = with_constants("#version 330 core\nout vec4 f;\n")
    assert src.startswith("#version 330 core\n") and "\n#line 2\nout vec4 f;\n" in src
    # No shader spells a material id as a number of its own.
    from rustcloth.render.shaders import SHADER_DIR

    for path in SHADER_DIR.glob("*.frag"):
        assert "const int MAT_" not in path.read_text(), path.name


def test_shader_compile_error_names_file_and_line(ctx: Any, tmp_path: Any) -> None:
    from rustcloth.render.shaders import SHADER_DIR

    (tmp_path / "fullscreen.vert").write_text((SHADER_DIR / "fullscreen.vert").read_text())
    (tmp_path / "broken.frag").write_text(
        "#version 330 core\nout vec4 f_color;\nvoid main() {\n    f_color = vec4(oops);\n}\n"
    )
    with pytest.raises(ShaderError, match=r"broken\.frag:4"):
        load_program(ctx, "fullscreen.vert", "broken.frag", directory=tmp_path)


def test_an_error_in_an_included_file_names_that_file_and_line(ctx: Any, tmp_path: Any) -> None:
    from rustcloth.render.shaders import SHADER_DIR

    (tmp_path / "fullscreen.vert").write_text((SHADER_DIR / "fullscreen.vert").read_text())
    (tmp_path / "outer.glsl").write_text('// outer\n#include "inner.glsl"\n')
    (tmp_path / "inner.glsl").write_text("// inner\n\nvec3 broken() { return oops; }\n")
    (tmp_path / "main.frag").write_text(
        '#version 330 core\nout vec4 f_color;\n#include "outer.glsl"\n'
        "void main() {\n    f_color = vec4(broken(), 1.0);\n}\n"
    )
    with pytest.raises(ShaderError, match=r"inner\.glsl:3"):
        load_program(ctx, "fullscreen.vert", "main.frag", directory=tmp_path)


def test_no_expanded_shader_ends_with_a_line_directive() -> None:
    # NVIDIA's GLSL compiler refuses a #line with no source line after it (error C0115), which
    # an #include on a shader's last line left, so no program of the renderer compiled on an
    # NVIDIA GPU; Mesa takes it.
    from rustcloth.render.shaders import SHADER_DIR, expand_includes

    programs = [*SHADER_DIR.glob("*.vert"), *SHADER_DIR.glob("*.frag")]
    last_line_includes = [p for p in programs
                          if p.read_text().rstrip().split("\n")[-1].startswith("#include")]
    assert last_line_includes, "no shader ends with an #include: the case tests nothing"
    for path in programs:
        text, _ = expand_includes(path.read_text(), SHADER_DIR)
        assert not text.rstrip().split("\n")[-1].startswith("#line"), path.name


def test_a_severed_cloth_grows_its_buffers_once_and_then_uploads_positions_only(
        ctx: Any) -> None:
    import rustcloth

    sim = rustcloth.Simulation("hanging")
    r = Renderer(ctx, sim, SIZE, shadow_size=256)
    ibo = r.cloth_ibo
    writes: list[int] = []
    original = type(ibo).write

    def spy(self: Any, data: Any, offset: int = 0) -> None:
        if self is ibo:
            writes.append(data.nbytes)
        original(self, data, offset=offset)

    z = float(sim.positions[:, 2].mean()) + 0.01  # the hanging sheet lies in the xz plane
    assert sim.sever_stroke([([-2.0, 5.0, z], [0, -1, 0]), ([2.0, 5.0, z], [0, -1, 0])]) > 0
    type(ibo).write = spy  # type: ignore[method-assign]
    try:
        r.update()
        sim.step(5)
        r.update()
    finally:
        type(ibo).write = original  # type: ignore[method-assign]
    tris, uvs, _ = sim.render_topology()
    assert writes == [tris.nbytes]
    assert r.index_count == tris.size and tris.max() >= sim.num_particles
    assert r.cloth_pos.size >= len(uvs) * 12 and r.cloth_uv.size >= uvs.nbytes
    assert np.array_equal(r.positions, sim.render_positions()[0])
