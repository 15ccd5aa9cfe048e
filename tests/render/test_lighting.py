"""The lit image: exposure, the cloth's shadow on the floor, and a golden image."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from rustcloth.camera import Camera
from rustcloth.render import Renderer
from rustcloth.render.renderer import MAT_FLOOR

pytestmark = pytest.mark.render
SIZE = (200, 150)
GOLDEN = Path(__file__).parent / "golden" / "standin_lit.png"


def _camera() -> Camera:
    return Camera(eye=(0.9, 2.2, 2.4), target=(0.0, 0.5, 0.0), aspect=SIZE[0] / SIZE[1])


def _frame(ctx: Any, r: Renderer, cam: Camera) -> np.ndarray:
    fbo = ctx.simple_framebuffer(SIZE)
    r.update()
    r.render(fbo, cam)
    # Not released: moderngl would later rebind the deleted framebuffer (GL_INVALID_OPERATION).
    return np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(SIZE[1], SIZE[0], 3)


def test_lit_frame_is_neither_black_nor_saturated(standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.08), SIZE, shadow_size=1024)
    img = _frame(ctx, r, _camera()).astype(np.float32)
    luma = img @ np.array([0.299, 0.587, 0.114])
    assert 50 < luma.mean() < 210
    assert (luma > 250).mean() < 0.05 and (luma < 5).mean() < 0.05
    assert luma.std() > 10  # shading, texture and shadow, not a flat fill


def test_shadow_darkens_the_floor_under_the_cloth(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.0, height=1.0)
    r = Renderer(ctx, sim, SIZE, shadow_size=1024)
    cam = _camera()
    lit_on = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    g = r.read_gbuffer()
    r.shadows = False
    lit_off = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    # Floor pixels whose path to the light crosses the cloth square (sheet at y = 1, |x|,
    # |z| < 0.6), staying clear of its edges and of the sphere's own shadow.
    pos = g["position"][..., :3]
    floor = g["material"] == MAT_FLOOR
    s = (1.0 - pos[..., 1]) / -r.light_dir[1]
    hit = pos + s[..., None] * -r.light_dir
    under = floor & (np.abs(hit[..., 0]) < 0.5) & (np.abs(hit[..., 2]) < 0.5)
    clear = floor & ((np.abs(hit[..., 0]) > 0.8) | (np.abs(hit[..., 2]) > 0.8))
    clear &= np.hypot(pos[..., 0] - 0.4 * 0.45 / 1.0, pos[..., 2]) > 1.0
    assert under.sum() > 100 and clear.sum() > 100
    assert lit_on[under].mean() < 0.75 * lit_off[under].mean()
    # Outside the shadow nothing changes.
    assert abs(lit_on[clear].mean() - lit_off[clear].mean()) < 2.0


def test_ssao_darkens_some_covered_pixels_only(standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.1), SIZE, shadow_size=512)
    r.fxaa = False  # FXAA would blend the change into neighbouring pixels either way
    cam = _camera()
    plain = _frame(ctx, r, cam).astype(np.float32)
    r.ssao = True
    shaded = _frame(ctx, r, cam).astype(np.float32)
    ao = np.frombuffer(r.ao.read(), dtype=np.uint8).reshape(SIZE[1], SIZE[0]) / 255.0
    covered = r.read_gbuffer()["material"] > 0
    assert (ao[~covered] == 1.0).all() and ao[covered].mean() < 1.0
    assert (shaded <= plain + 1.0).all() and (shaded < plain - 1.0).any()


def test_golden_image(standin_cls: Any, ctx: Any) -> None:
    """One fixed scene and camera against a committed render; llvmpipe is deterministic, the
    tolerance allows for other Mesa versions. RUSTCLOTH_UPDATE_GOLDEN=1 rewrites it."""
    r = Renderer(ctx, standin_cls(amp=0.08), SIZE, shadow_size=1024)
    img = _frame(ctx, r, _camera())[::-1]
    if os.environ.get("RUSTCLOTH_UPDATE_GOLDEN") or not GOLDEN.exists():
        GOLDEN.parent.mkdir(exist_ok=True)
        Image.fromarray(img).save(GOLDEN)
        if not os.environ.get("RUSTCLOTH_UPDATE_GOLDEN"):
            pytest.fail(f"golden image was missing; wrote {GOLDEN}, commit it")
    golden = np.asarray(Image.open(GOLDEN).convert("RGB"), dtype=np.int16)
    diff = np.abs(img.astype(np.int16) - golden)
    assert diff.mean() < 1.5, f"mean difference {diff.mean():.2f} / 255"
    assert (diff.max(axis=2) > 40).mean() < 0.01
