"""The lit image: exposure, the cloth's shadow on the floor, point lights you can see, light
presets, SSAO at half size, the cached frame, and a golden image."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from rustcloth.camera import Camera
from rustcloth.render import Renderer
from rustcloth.render import constants as K
from rustcloth.render.lights import PRESET_NAMES, key_direction, preset

from .frames import camera, frame

pytestmark = pytest.mark.render
SIZE = (200, 150)
GOLDEN = Path(__file__).parent / "golden" / "standin_lit.png"


def _camera() -> Camera:
    return camera(SIZE)


def _frame(ctx: Any, r: Renderer, cam: Camera) -> np.ndarray:
    return frame(ctx, r, cam, SIZE)


def test_lit_frame_is_neither_black_nor_saturated(standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.08), SIZE, shadow_size=1024)
    img = _frame(ctx, r, _camera()).astype(np.float32)
    luma = img @ np.array([0.299, 0.587, 0.114])
    assert 50 < luma.mean() < 210
    assert (luma > 250).mean() < 0.05 and (luma < 5).mean() < 0.05
    assert luma.std() > 10  # shading, texture and shadow, not a flat fill


def _floor_hit(pos: np.ndarray, light_dir: np.ndarray, height: float) -> np.ndarray:
    """Where the ray from each floor point towards the light crosses y = ``height``."""
    s = (height - pos[..., 1]) / -light_dir[1]
    return pos + s[..., None] * -light_dir


def test_shadow_darkens_the_floor_under_the_cloth(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.0, height=1.0)
    r = Renderer(ctx, sim, SIZE, shadow_size=1024)
    r.point_lights = False
    cam = _camera()
    lit_on = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    g = r.read_gbuffer()
    r.shadows = False
    lit_off = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    # Floor pixels whose path to the light crosses the cloth square (sheet at y = 1, |x|,
    # |z| < 0.6), staying clear of its edges and of the sphere's own shadow.
    pos = g["position"]
    floor = g["material"] == K.FLOOR.id
    hit = _floor_hit(pos, r.light_dir, 1.0)
    under = floor & (np.abs(hit[..., 0]) < 0.5) & (np.abs(hit[..., 2]) < 0.5)
    clear = floor & ((np.abs(hit[..., 0]) > 0.8) | (np.abs(hit[..., 2]) > 0.8))
    sphere = _floor_hit(pos, r.light_dir, 0.4)  # the sphere's centre is at y = 0.4
    clear &= np.hypot(sphere[..., 0], sphere[..., 2]) > 0.6
    assert under.sum() > 100 and clear.sum() > 100
    assert lit_on[under].mean() < 0.75 * lit_off[under].mean()
    # Outside the shadow nothing changes.
    assert abs(lit_on[clear].mean() - lit_off[clear].mean()) < 2.0


def test_point_lights_light_coloured_pools_and_show_their_markers(
        standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.05), SIZE, shadow_size=512, lights="neon")
    cam = Camera(eye=(0.0, 4.5, 3.2), target=(0.0, 0.0, 0.0), aspect=SIZE[0] / SIZE[1])
    with_points = _frame(ctx, r, cam).astype(np.float32)
    g = r.read_gbuffer()
    r.point_lights = False
    without = _frame(ctx, r, cam).astype(np.float32)
    floor = g["material"] == K.FLOOR.id
    # Each light's pool: the floor right under it is brighter with the light, and tinted
    # towards the light's own colour.
    pools = 0
    for pos, color in zip(r.points.positions, r.points.marker_colors, strict=True):
        near = floor & (np.hypot(g["position"][..., 0] - pos[0],
                                 g["position"][..., 2] - pos[2]) < 0.25)
        if near.sum() < 10:
            continue  # out of view
        pools += 1
        added = (with_points[near] - without[near]).mean(axis=0)
        assert added.sum() > 30
        assert added @ color / (np.linalg.norm(added) * np.linalg.norm(color)) > 0.8
    assert pools >= 3
    markers = g["material"] == K.LIGHT.id
    assert markers.sum() >= 3
    assert (with_points[markers].mean(axis=1) > 150).mean() > 0.5


def test_light_presets_give_different_pictures(standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.05), SIZE, shadow_size=512)
    means = []
    for name in PRESET_NAMES:
        r.set_lights(name)
        assert r.lights.name == name
        means.append(_frame(ctx, r, _camera()).astype(np.float32).mean(axis=(0, 1)))
    assert len({tuple(np.round(m)) for m in means}) == len(PRESET_NAMES)
    assert r.cycle_lights() == PRESET_NAMES[0]


def test_ssao_at_half_size_darkens_covered_pixels_only(standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.1), SIZE, shadow_size=512)
    r.fxaa = False  # FXAA would blend the change into neighbouring pixels either way
    cam = _camera()
    plain = _frame(ctx, r, cam).astype(np.float32)
    r.ssao = True
    shaded = _frame(ctx, r, cam).astype(np.float32)
    assert r.fill.size == (SIZE[0] // 2, SIZE[1] // 2)
    fill = np.frombuffer(r.fill.read(), dtype=np.float16).reshape(SIZE[1] // 2, SIZE[0] // 2, 4)
    ao = fill[..., 3].astype(np.float32)
    covered = r.read_gbuffer()["material"] > 0
    blocks = covered.reshape(SIZE[1] // 2, 2, SIZE[0] // 2, 2).any(axis=(1, 3))
    assert (ao[~blocks] == 1.0).all() and ao[blocks].mean() < 1.0
    # AO only ever darkens (the dither may move a pixel by one step).
    assert (shaded <= plain + 2.0).all() and (shaded < plain - 2.0).any()


def test_unchanged_frame_reuses_the_lit_image_and_shadow_map(standin_cls: Any, ctx: Any) -> None:
    sim = standin_cls(amp=0.05)
    r = Renderer(ctx, sim, SIZE, shadow_size=512)
    passes: list[str] = []
    r.pass_timer = passes.append
    cam = _camera()
    first = _frame(ctx, r, cam)
    assert passes[:4] == ["shadow", "geometry", "fill", "lighting"]
    passes.clear()
    again = _frame(ctx, r, cam)  # nothing moved: only the last pass runs
    assert passes == ["fxaa"] and np.array_equal(first, again)
    passes.clear()
    cam.orbit(0.2, 0.0)  # the camera moved, the cloth did not: no new shadow map
    _frame(ctx, r, cam)
    assert "shadow" not in passes and "geometry" in passes
    passes.clear()
    sim.step(100)  # the cloth moved
    _frame(ctx, r, cam)
    assert passes[0] == "shadow"


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


def test_a_lower_render_scale_draws_fewer_pixels_and_fills_the_output(
        standin_cls: Any, ctx: Any) -> None:
    r = Renderer(ctx, standin_cls(amp=0.05), SIZE, shadow_size=512)
    full = _frame(ctx, r, _camera()).astype(np.float32)
    r.resize(SIZE, 0.5)
    assert r.size == SIZE and r.inner == (SIZE[0] // 2, SIZE[1] // 2)
    assert r.g_albedo.size == r.inner and r.fill.size == (SIZE[0] // 4, SIZE[1] // 4)
    half = _frame(ctx, r, _camera()).astype(np.float32)
    # The same picture, softer: close on average, and not a quarter-sized image in a corner.
    assert np.abs(half - full).mean() < 12.0
    quarter = (slice(SIZE[1] // 2, None), slice(SIZE[0] // 2, None))
    assert np.abs(half[quarter] - full[quarter]).mean() < 12.0


def test_a_scene_without_a_floor_still_shadows_its_ground(ctx: Any) -> None:
    """Regression: hanging's visual ground lay below the shadow map's box, so the cloth's
    shadow on it was cut off (220 darkened pixels here, against 604 with the whole shadow)."""
    import rustcloth

    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    sim.advance(1.5)
    r = Renderer(ctx, sim, SIZE, shadow_size=512)
    r.point_lights = False
    cam = r.layout.camera(SIZE[0] / SIZE[1])
    on = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    floor = r.read_gbuffer()["material"] == K.FLOOR.id
    r.shadows = False
    off = _frame(ctx, r, cam).astype(np.float32).mean(axis=2)
    assert ((off - on)[floor] > 20.0).sum() > 400



@pytest.mark.parametrize("lights", PRESET_NAMES)
def test_every_preset_casts_the_cloth_shadow_away_from_the_camera(lights: str) -> None:
    # Under `night` the blue moon shone from behind the scene, so the cloth's shadow came
    # towards the viewer across the floor the orange lamps light, and where it took the
    # moonlight away the floor turned a saturated orange: a shadow that looked like a spill.
    # The key light of every preset now travels away from the camera (its shadow falls
    # behind what casts it), whichever side the scene is framed from.
    for view_azimuth in (0.0, 90.0, 200.0):
        travel = key_direction(preset(lights), view_azimuth)
        a = np.radians(view_azimuth)
        camera_side = np.array([np.sin(a), 0.0, np.cos(a)])
        assert float(travel @ camera_side) < 0.0, (lights, view_azimuth, travel)


def test_the_night_shadow_darkens_the_floor_more_than_it_tints_it(standin_cls: Any,
                                                                  ctx: Any) -> None:
    # The moon is a cool white, not blue, so its shadow on the lamp-lit floor takes away
    # some of every channel rather than only the blue.
    p = preset("night")
    assert max(p.key_color) - min(p.key_color) < 0.2
    r = Renderer(ctx, standin_cls(amp=0.0, height=1.0), SIZE, shadow_size=1024, lights="night")
    cam = _camera()
    lit_on = _frame(ctx, r, cam).astype(np.float32)
    r.shadows = False
    lit_off = _frame(ctx, r, cam).astype(np.float32)
    shadowed = (lit_on.sum(axis=2) < lit_off.sum(axis=2) - 15.0)
    assert shadowed.sum() > 50
    on, off = lit_on[shadowed].mean(axis=0), lit_off[shadowed].mean(axis=0)
    assert (on < off - 1.0).all(), (on, off)  # every channel darker
