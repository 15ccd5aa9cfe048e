"""Constants the Python renderer and the GLSL shaders share, in one place: material ids and
parameters, debug views, colour maps. :func:`glsl_header` turns them into ``#define`` lines
that :mod:`.shaders` puts at the top of every shader when it loads it."""

from __future__ import annotations

import math
from dataclasses import dataclass

RGB = tuple[float, float, float]


def srgb_to_linear(c: RGB) -> RGB:
    """The sRGB transfer curve, undone: what a colour picker shows to linear light."""

    def one(v: float) -> float:
        return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4

    return (one(c[0]), one(c[1]), one(c[2]))


# The tartan of the cloth's front: (colour as sRGB, width as a fraction of one repeat).
TARTAN = (
    ((0.46, 0.06, 0.07), 0.24),  # red
    ((0.06, 0.07, 0.17), 0.05),  # navy
    ((0.46, 0.06, 0.07), 0.05),
    ((0.08, 0.22, 0.13), 0.25),  # green
    ((0.62, 0.48, 0.14), 0.02),  # ochre
    ((0.06, 0.07, 0.17), 0.22),
    ((0.46, 0.06, 0.07), 0.17),
)
TARTAN_REPEAT_M = 0.27
"""One repeat of the tartan, in metres of cloth (unrelated to the particle spacing)."""
THREAD_PITCH_M = 0.0025
"""Thread spacing of the twill weave, in metres (shown only when a thread covers pixels)."""



def linear_to_srgb(c: RGB) -> RGB:
    """The sRGB transfer curve: linear light to what a colour picker shows."""

    def one(v: float) -> float:
        return 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1.0 / 2.4) - 0.055

    return (one(c[0]), one(c[1]), one(c[2]))


def tartan_mean() -> RGB:
    """The tartan's mean colour (sRGB), averaged in linear light over one repeat."""
    lin = [srgb_to_linear(c) for c, _ in TARTAN]
    total = sum(w for _, w in TARTAN)
    mean = [sum(c[k] * w for c, (_, w) in zip(lin, TARTAN, strict=True)) / total
            for k in range(3)]
    return linear_to_srgb((mean[0], mean[1], mean[2]))


@dataclass(frozen=True)
class Material:
    """One surface kind. ``id`` goes into the G-buffer's albedo alpha (0 is the sky)."""

    id: int
    name: str
    color: RGB
    """Base colour as sRGB (0..1), what a colour picker shows; the shaders get it linear."""
    roughness: float
    """Perceptual roughness: of the GGX lobe (floor, sphere, collider) or the sheen lobe
    (cloth)."""
    debug: RGB
    """Its colour in the material debug view and legend (sRGB)."""
    sheen: RGB = (0.0, 0.0, 0.0)
    """KHR_materials_sheen ``sheenColor`` (sRGB); black: no sheen lobe."""
    emissive: float = 0.0
    """Emitted radiance per unit of linear base colour (markers); 0: lit normally."""


CLOTH_FRONT = Material(1, "CLOTH_FRONT", tartan_mean(), 0.55, (0.95, 0.35, 0.30),
                       sheen=(0.55, 0.50, 0.46))
"""The front: a red, green and navy tartan; ``color`` is its mean."""
CLOTH_BACK = Material(2, "CLOTH_BACK", (0.10, 0.36, 0.40), 0.45, (0.25, 0.70, 0.75),
                      sheen=(0.40, 0.62, 0.64))
"""The back: a plain deep-teal lining."""
FLOOR = Material(3, "FLOOR", (0.42, 0.41, 0.39), 0.55, (0.55, 0.55, 0.55))
SPHERE = Material(4, "SPHERE", (0.22, 0.30, 0.42), 0.3, (0.30, 0.45, 0.95))
MARKER = Material(5, "MARKER", (1.0, 0.80, 0.12), 1.0, (1.0, 0.85, 0.10), emissive=1.6)
"""The grabbed particle."""
LIGHT = Material(6, "LIGHT", (1.0, 1.0, 1.0), 1.0, (1.0, 1.0, 1.0), emissive=2.2)
"""The point lights' markers (coloured per light)."""
COLLIDER = Material(7, "COLLIDER", (0.55, 0.42, 0.30), 0.45, (0.85, 0.55, 0.25))
"""The scene's ``colliders`` of every shape: a warm wood, apart from the spheres' blue."""
MATERIALS = (CLOTH_FRONT, CLOTH_BACK, FLOOR, SPHERE, MARKER, LIGHT, COLLIDER)

# Debug views, in the order V cycles through them. Each id is its branch in the shaders.
VIEWS = ("lit", "position", "normal", "albedo", "material", "depth", "shadow map",
         "strain", "speed", "pinned")
VIEW_IDS = {name: k for k, name in enumerate(VIEWS)}
GBUFFER_VIEWS = ("position", "normal", "albedo", "material", "depth", "shadow map")
"""Views that show a raw buffer instead of the lit image."""
SCALAR_VIEWS = ("strain", "speed", "pinned")
"""Views that colour the cloth by a per-particle value (lit, without tone mapping)."""

# The colour map of the strain and speed views (viridis, five stops, sRGB).
COLORMAP = ((0.267, 0.005, 0.329), (0.229, 0.322, 0.546), (0.128, 0.567, 0.551),
            (0.369, 0.789, 0.383), (0.993, 0.906, 0.144))
STRAIN_MAX = 0.20
"""Strain (l / L - 1) at the top of the strain view's scale; zero at the bottom."""
SPEED_RANGE = (0.001, 3.0)
"""m/s at the bottom and top of the speed view's logarithmic scale."""
PIN_COLORS = {"free": (0.30, 0.36, 0.48), "pinned": (0.90, 0.20, 0.16),
              "grabbed": (1.0, 0.85, 0.10)}
"""The pinned view's colours (sRGB), by the value it gets: 0 free, 1 pinned, 2 grabbed."""

MAX_POINT_LIGHTS = 8
SSAO_SAMPLES = 12


def speed_to_unit(speed: float) -> float:
    """Where a speed in m/s sits on the speed view's scale, 0..1 (what the shader computes)."""
    lo, hi = SPEED_RANGE
    return min(1.0, max(0.0, math.log(max(speed, lo) / lo) / math.log(hi / lo)))


def _vec3(c: RGB) -> str:
    return f"vec3({c[0]:.6f}, {c[1]:.6f}, {c[2]:.6f})"


def glsl_header() -> str:
    """The constants as GLSL: ``#define MAT_FLOOR 3``, ``#define VIEW_DEPTH 5``, colours as
    linear ``vec3``, the tartan and colour map as arrays."""
    lines = ["// Generated from rustcloth/render/constants.py when the shader was loaded."]
    for m in MATERIALS:
        lines += [
            f"#define MAT_{m.name} {m.id}",
            f"#define MAT_{m.name}_COLOR {_vec3(srgb_to_linear(m.color))}",
            f"#define MAT_{m.name}_ROUGHNESS {m.roughness:.6f}",
            f"#define MAT_{m.name}_SHEEN {_vec3(srgb_to_linear(m.sheen))}",
            f"#define MAT_{m.name}_EMISSIVE {m.emissive:.6f}",
        ]
    lines.append(f"#define MAT_COUNT {len(MATERIALS) + 1}")
    debug = [(0.0, 0.0, 0.0)] * (len(MATERIALS) + 1)
    for m in MATERIALS:
        debug[m.id] = m.debug
    lines.append(f"#define MAT_DEBUG_COLORS vec3[{len(debug)}]("
                 + ", ".join(_vec3(c) for c in debug) + ")")
    for name, k in VIEW_IDS.items():
        lines.append(f"#define VIEW_{name.upper().replace(' ', '_')} {k}")
    n = len(TARTAN)
    starts = [sum(w for _, w in TARTAN[:k]) for k in range(n)]
    lines += [
        f"#define TARTAN_STRIPES {n}",
        f"#define TARTAN_COLORS vec3[{n}]("
        + ", ".join(_vec3(srgb_to_linear(c)) for c, _ in TARTAN) + ")",
        f"#define TARTAN_STARTS float[{n}](" + ", ".join(f"{s:.6f}" for s in starts) + ")",
        f"#define TARTAN_WIDTHS float[{n}](" + ", ".join(f"{w:.6f}" for _, w in TARTAN) + ")",
        f"#define TARTAN_MEAN {_vec3(srgb_to_linear(tartan_mean()))}",
        f"#define TARTAN_REPEAT_M {TARTAN_REPEAT_M:.6f}",
        f"#define THREAD_PITCH_M {THREAD_PITCH_M:.6f}",
        f"#define COLORMAP_STOPS {len(COLORMAP)}",
        f"#define COLORMAP vec3[{len(COLORMAP)}](" + ", ".join(_vec3(c) for c in COLORMAP) + ")",
        f"#define STRAIN_MAX {STRAIN_MAX:.6f}",
        f"#define SPEED_MIN {SPEED_RANGE[0]:.6f}",
        f"#define SPEED_MAX {SPEED_RANGE[1]:.6f}",
        f"#define PIN_FREE_COLOR {_vec3(PIN_COLORS['free'])}",
        f"#define PIN_PINNED_COLOR {_vec3(PIN_COLORS['pinned'])}",
        f"#define PIN_GRABBED_COLOR {_vec3(PIN_COLORS['grabbed'])}",
        f"#define MAX_POINT_LIGHTS {MAX_POINT_LIGHTS}",
        f"#define SSAO_SAMPLES {SSAO_SAMPLES}",
    ]
    return "\n".join(lines) + "\n"
