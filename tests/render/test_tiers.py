"""The software quality tier: chosen for a CPU rasteriser, switchable, and drawing the same
scene as the full tier (same place, similar colours, a shadow where the full tier has one),
only cheaper. Nothing here is timed: benches/render_times.py measures the cost."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import rustcloth
from rustcloth.camera import Camera
from rustcloth.render import Renderer
from rustcloth.render import constants as K
from rustcloth.render.tiers import SOFTWARE_SHADOW_SIZE, TIERS, auto_tier, is_software
from rustcloth.viewer.loop import Viewer

from .frames import camera, frame

pytestmark = pytest.mark.render
SIZE = (240, 180)
CLOTH = (K.CLOTH_FRONT.id, K.CLOTH_BACK.id)


def _camera() -> Camera:
    return camera(SIZE)


def _frame(ctx: Any, r: Renderer, cam: Camera) -> np.ndarray:
    return frame(ctx, r, cam, SIZE).astype(np.float32)


@pytest.mark.parametrize(("name", "software"), [
    ("llvmpipe (LLVM 15.0.6, 256 bits)", True),
    ("softpipe", True),
    ("Mesa DRI swrast", True),
    ("NVIDIA H200/PCIe/SSE2", False),
    ("AMD Radeon Graphics (radeonsi, renoir, LLVM 15.0.7, DRM 3.49)", False),
    ("Mesa Intel(R) UHD Graphics 620 (KBL GT2)", False),
])
def test_a_cpu_rasteriser_is_told_from_a_gpu_by_its_gl_renderer(name: str,
                                                                software: bool) -> None:
    assert is_software(name) is software
    fake = SimpleNamespace(info={"GL_RENDERER": name})
    assert auto_tier(fake) == ("software" if software else "full")


def test_the_demo_starts_in_the_tier_its_context_calls_for_and_q_switches(ctx: Any) -> None:
    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    viewer = Viewer(ctx, sim, SIZE, realtime=False, tier=None)
    expected = "software" if is_software(ctx.info["GL_RENDERER"]) else "full"
    assert viewer.renderer.tier == expected
    # Headless rendering and the tests keep the full tier unless asked.
    assert Viewer(ctx, sim, SIZE, realtime=False).renderer.tier == "full"
    fbo = ctx.simple_framebuffer(SIZE)
    seen = []
    for _ in TIERS:
        viewer.key("Q")
        viewer.frame(fbo, 1 / 30)
        seen.append(viewer.renderer.tier)
        on_overlay = "software tier" in viewer.status_lines()[0]
        assert on_overlay is (viewer.renderer.tier == "software")
    assert sorted(seen) == sorted(TIERS)
    with pytest.raises(ValueError, match="tier"):
        viewer.renderer.tier = "ultra"


def test_the_software_tier_draws_the_same_scene_as_the_full_tier(standin_cls: Any,
                                                                 ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.08), SIZE)
    cam = _camera()
    full = _frame(ctx, r, cam)
    cloth = np.isin(r.read_gbuffer()["material"], CLOTH)  # rows bottom to top, as the image
    r.tier = "software"
    soft = _frame(ctx, r, cam)
    assert r.shadow_size == SOFTWARE_SHADOW_SIZE
    luma = soft @ np.array([0.299, 0.587, 0.114])
    assert 50 < luma.mean() < 210 and luma.std() > 10  # not blank, not flat
    assert (luma > 250).mean() < 0.05 and (luma < 5).mean() < 0.05
    # The same colours on the whole and on the cloth and off it, loosely: lit per vertex,
    # with a cheaper sheen and highlights, but the same light.
    assert 0.05 < cloth.mean() < 0.9
    for region in (np.ones_like(cloth), cloth, ~cloth):
        diff = np.abs(soft[region].mean(axis=0) - full[region].mean(axis=0))
        assert (diff < 10.0).all(), (diff, region.mean())
    # The cloth's outline in the same place: the cloth colour (red tartan) where the full
    # tier has cloth, within a pixel of its silhouette.
    redness_soft = soft[..., 0] - soft[..., 1:].mean(axis=2)
    redness_full = full[..., 0] - full[..., 1:].mean(axis=2)
    inner = cloth & np.roll(cloth, 1, 0) & np.roll(cloth, -1, 0) & np.roll(cloth, 1, 1) & \
        np.roll(cloth, -1, 1)
    assert redness_soft[inner].mean() > redness_soft[~cloth].mean() + 30.0
    assert abs(redness_soft[inner].mean() - redness_full[inner].mean()) < 12.0
    assert ctx.error == "GL_NO_ERROR"


def test_the_software_tier_shadows_the_floor_and_skips_ssao_and_fxaa(standin_cls: Any,
                                                                     ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.0, height=1.0), SIZE, tier="software")
    r.point_lights = False
    cam = _camera()
    passes: list[str] = []
    r.pass_timer = passes.append
    shadowed = _frame(ctx, r, cam)
    assert passes == ["shadow", "forward", "copy"]
    passes.clear()
    assert np.array_equal(_frame(ctx, r, cam), shadowed) and passes == ["copy"]
    r.ssao = True
    assert np.array_equal(_frame(ctx, r, cam), shadowed)  # SSAO is drawn in full only
    r.ssao = False
    r.shadows = False
    plain = _frame(ctx, r, cam)
    # Without shadows nothing gets darker, and with them the floor under the sheet does.
    luma_on, luma_off = shadowed.mean(axis=2), plain.mean(axis=2)
    assert (luma_on <= luma_off + 2.0).all()
    assert (luma_on < luma_off - 20.0).mean() > 0.02
    r.shadows = True
    r.view = "normal"  # the debug views draw as in the full tier
    passes.clear()
    _frame(ctx, r, cam)
    assert "geometry" in passes and "forward" not in passes


def test_only_the_full_tier_trades_resolution_for_frame_rate(ctx: Any) -> None:
    # On llvmpipe the software tier's 70 % frame cost more than its full one (the scale-up
    # is a textured pass over every output pixel), so slow frames lower the resolution in
    # the full tier only, and the software tier draws at full resolution.
    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    viewer = Viewer(ctx, sim, SIZE, realtime=True, tier="full")
    fbo = ctx.simple_framebuffer(SIZE)

    def slow_frame() -> None:
        viewer.render_s = 1.0  # the last frame took a second to render
        viewer._scaled_at = float("-inf")
        viewer.frame(fbo, 1 / 30)

    viewer.frame(fbo, 1 / 30)  # the first frame's time replaces render_s; later ones blend
    slow_frame()
    assert viewer.renderer.scale < 1.0
    viewer.key("Q")
    assert viewer.renderer.tier == "software"
    slow_frame()
    assert viewer.renderer.scale == 1.0
    slow_frame()
    assert viewer.renderer.scale == 1.0 and viewer.renderer.inner == viewer.renderer.size
