"""Light presets (key L in the demo): a shadowed key light, a sky and up to eight point lights
placed around the scene, in linear units the lighting pass uses as they are."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .constants import MAX_POINT_LIGHTS, RGB, srgb_to_linear

F32 = npt.NDArray[np.float32]


@dataclass(frozen=True)
class PointRing:
    """Point lights evenly spaced on a horizontal ring around the scene's focus."""

    colors: tuple[RGB, ...]
    """One sRGB colour per light (also its marker's colour)."""
    intensity: float
    """Radiant intensity of each light, in the lighting pass's units (W/sr at 1 m)."""
    radius: float
    """Ring radius as a multiple of the scene's span (plus 0.3 m)."""
    height: float
    """Height above the ground in m (every other light 40 % higher)."""
    reach: float
    """Distance in m at which a light's falloff window reaches zero."""
    phase: float = 0.3
    """Angle of the first light, radians."""


@dataclass(frozen=True)
class LightPreset:
    name: str
    key_elevation: float
    """Degrees above the horizon the key light comes from."""
    key_azimuth: float
    """Degrees about +y the key light comes from, from the side the scene's camera looks
    from (0: from behind the camera, 90: from its left, 180: from behind the scene), so
    every scene is lit the same way as it is framed."""
    key_color: RGB
    """sRGB colour of the key light."""
    key_intensity: float
    """Irradiance of the key light on a surface facing it."""
    sky_zenith: RGB
    sky_horizon: RGB
    """sRGB colours of the sky straight up and at the horizon (also the fog's colour)."""
    ground: RGB
    """sRGB colour of the ambient light from below."""
    ambient: float
    """Scale of the sky and ground ambient light."""
    exposure: float
    """Multiplies the linear image before tone mapping."""
    points: PointRing


PRESETS = (
    LightPreset(
        "studio", 48.0, 50.0, (1.0, 0.93, 0.84), 2.4,
        (0.36, 0.50, 0.70), (0.80, 0.83, 0.86), (0.42, 0.38, 0.33), 0.55, 1.0,
        PointRing(((1.0, 0.62, 0.28), (0.30, 0.62, 1.0)) * 3, 0.9, 0.75, 0.30, 2.6),
    ),
    LightPreset(
        "neon", 60.0, -30.0, (0.75, 0.80, 1.0), 0.55,
        (0.06, 0.07, 0.16), (0.20, 0.17, 0.30), (0.10, 0.08, 0.12), 0.35, 1.1,
        PointRing(((1.0, 0.15, 0.55), (0.10, 0.85, 1.0), (0.55, 1.0, 0.15), (1.0, 0.50, 0.05),
                   (0.55, 0.25, 1.0), (0.05, 1.0, 0.60), (1.0, 0.90, 0.15), (0.20, 0.35, 1.0)),
                  1.8, 0.65, 0.25, 2.4),
    ),
    LightPreset(
        "sunset", 16.0, -75.0, (1.0, 0.58, 0.30), 2.6,
        (0.24, 0.30, 0.52), (0.95, 0.62, 0.45), (0.30, 0.22, 0.22), 0.50, 1.0,
        PointRing(((0.45, 0.55, 1.0), (0.70, 0.45, 1.0)) * 2, 0.7, 0.8, 0.6, 2.8, phase=2.4),
    ),
    LightPreset(
        "night", 62.0, -35.0, (0.78, 0.80, 0.92), 0.35,
        (0.015, 0.02, 0.05), (0.06, 0.07, 0.12), (0.04, 0.035, 0.03), 0.30, 1.25,
        PointRing(((1.0, 0.70, 0.38),) * 4, 2.2, 0.55, 0.45, 2.6, phase=0.8),
    ),
)
PRESET_NAMES = tuple(p.name for p in PRESETS)


def preset(name: str) -> LightPreset:
    for p in PRESETS:
        if p.name == name:
            return p
    raise ValueError(f"unknown light preset {name!r}; presets: {', '.join(PRESET_NAMES)}")


def key_direction(p: LightPreset, view_azimuth: float = 0.0) -> F32:
    """Unit direction the key light travels (from the sky towards the ground), for a camera
    on the side ``view_azimuth`` (degrees about +y, 0: +z, 90: +x) of the scene."""
    el, az = math.radians(p.key_elevation), math.radians(p.key_azimuth + view_azimuth)
    towards_light = np.array([math.cos(el) * math.sin(az), math.sin(el),
                              math.cos(el) * math.cos(az)], dtype=np.float32)
    return -towards_light


@dataclass(frozen=True)
class PointLights:
    """Positions (m), linear colours times intensity, and reaches of a preset's point lights
    for one scene; ``marker_colors`` are the linear colours of their markers (unit peak)."""

    positions: F32
    colors: F32
    reaches: F32
    marker_colors: F32

    def __len__(self) -> int:
        return len(self.positions)


def place_points(p: LightPreset, focus: F32, span: float, ground: float) -> PointLights:
    """The preset's ring around ``focus`` (its centre at ground level) for a scene ``span`` m
    across whose ground is at ``ground``."""
    ring = p.points
    n = min(len(ring.colors), MAX_POINT_LIGHTS)
    k = np.arange(n, dtype=np.float32)
    angle = ring.phase + k * (2.0 * math.pi / max(n, 1))
    radius = ring.radius * span + 0.3
    height = ground + ring.height * (1.0 + 0.4 * (k % 2))
    positions = np.column_stack([focus[0] + radius * np.cos(angle), height,
                                 focus[2] + radius * np.sin(angle)]).astype(np.float32)
    linear = np.array([srgb_to_linear(c) for c in ring.colors[:n]], dtype=np.float32)
    peak = np.maximum(linear.max(axis=1, keepdims=True), 1e-6)
    return PointLights(
        positions=positions,
        colors=(linear * ring.intensity).astype(np.float32),
        reaches=np.full(n, ring.reach, dtype=np.float32),
        marker_colors=(linear / peak).astype(np.float32),
    )
