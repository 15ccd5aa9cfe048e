"""Overlay panels rasterised with Pillow (core GL has no text): the status text, and a legend
for each debug view that says how to read its colours."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

from . import constants as K

_FONTS: dict[int, ImageFont.ImageFont | ImageFont.FreeTypeFont] = {}
Line = str | tuple[str, tuple[int, int, int]]
"""A line of text, or (text, RGB colour) for one that must stand out."""


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    if size not in _FONTS:
        try:
            _FONTS[size] = ImageFont.load_default(size=size)
        except TypeError:  # Pillow < 10.1 has only the fixed bitmap font
            _FONTS[size] = ImageFont.load_default()
    return _FONTS[size]


def _wrap(text: str, font: ImageFont.ImageFont | ImageFont.FreeTypeFont,
          width: float) -> list[str]:
    """``text`` broken at spaces into lines no wider than ``width`` pixels."""
    out: list[str] = []
    for word in text.split(" "):
        if out and font.getlength(f"{out[-1]} {word}") <= width:
            out[-1] = f"{out[-1]} {word}"
        else:
            out.append(word if not out else f"    {word}")
    return out or [""]


def text_panel(lines: list[Line], scale: int = 13,
               max_width: int | None = None) -> npt.NDArray[np.uint8]:
    """RGBA8 image (rows top to bottom) of the lines on a dim panel; lines wider than
    ``max_width`` pixels are wrapped."""
    font = _font(scale)
    items = [(s, (255, 255, 255)) if isinstance(s, str) else s for s in lines]
    if max_width is not None:
        items = [(part, color) for s, color in items for part in _wrap(s, font, max_width - 12)]
    line_h = scale + 4
    width = 12 + max((int(font.getlength(s)) for s, _ in items), default=0)
    img = Image.new("RGBA", (max(width, 1), 8 + line_h * len(items)), (0, 0, 0, 150))
    draw = ImageDraw.Draw(img)
    for k, (s, color) in enumerate(items):
        draw.text((6, 4 + k * line_h), s, fill=(*color, 255), font=font)
    return np.asarray(img, dtype=np.uint8).copy()


def _rgb(c: K.RGB) -> tuple[int, int, int]:
    return (round(255 * c[0]), round(255 * c[1]), round(255 * c[2]))


def _colormap(t: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The shaders' colour map (constants.COLORMAP), sRGB, for values in 0..1."""
    stops = np.asarray(K.COLORMAP)
    s = np.clip(t, 0.0, 1.0) * (len(stops) - 1)
    k = np.minimum(s.astype(int), len(stops) - 2)
    u = (s - k)[..., None]
    result: npt.NDArray[np.float64] = stops[k] * (1 - u) + stops[k + 1] * u
    return result


def _bar(title: str, ticks: list[tuple[float, str]], scale: int) -> npt.NDArray[np.uint8]:
    """A colour-map bar with labelled ticks at positions 0..1."""
    font = _font(scale)
    w, bar_h, pad = 260, 14, 8
    width = max(w, int(font.getlength(title))) + 2 * pad
    img = Image.new("RGBA", (width, 3 * scale + bar_h + 16), (0, 0, 0, 150))
    draw = ImageDraw.Draw(img)
    draw.text((pad, 4), title, fill=(255, 255, 255, 255), font=font)
    y0 = 8 + scale
    colors = _colormap(np.linspace(0.0, 1.0, w))
    for x in range(w):
        draw.line([(pad + x, y0), (pad + x, y0 + bar_h)], fill=(*_rgb(tuple(colors[x])), 255))
    for t, label in ticks:
        x = pad + round(t * (w - 1))
        draw.line([(x, y0 + bar_h), (x, y0 + bar_h + 3)], fill=(255, 255, 255, 255))
        lw = font.getlength(label)
        lx = min(max(x - lw / 2, 2), pad + w - lw)
        draw.text((lx, y0 + bar_h + 4), label, fill=(255, 255, 255, 255), font=font)
    return np.asarray(img, dtype=np.uint8).copy()


def _swatches(title: str, items: list[tuple[str, K.RGB]], scale: int) -> npt.NDArray[np.uint8]:
    font = _font(scale)
    line_h = scale + 6
    width = 34 + max([int(font.getlength(s)) for s, _ in items] + [int(font.getlength(title))])
    img = Image.new("RGBA", (width, 12 + line_h * (len(items) + 1)), (0, 0, 0, 150))
    draw = ImageDraw.Draw(img)
    draw.text((6, 4), title, fill=(255, 255, 255, 255), font=font)
    for k, (name, color) in enumerate(items):
        y = 4 + line_h * (k + 1)
        draw.rectangle([6, y + 1, 6 + scale, y + 1 + scale], fill=(*_rgb(color), 255))
        draw.text((12 + scale + 6, y), name, fill=(255, 255, 255, 255), font=font)
    return np.asarray(img, dtype=np.uint8).copy()


def legend(view: str, scale: int = 13) -> npt.NDArray[np.uint8] | None:
    """The legend of a debug view (RGBA8, rows top to bottom), or None for the lit view."""
    if view == "strain":
        top = K.STRAIN_MAX
        ticks = [(f / top, f"{100 * f:.0f} %") for f in np.linspace(0.0, top, 5)]
        return _bar("spring strain, l / L - 1 (largest at each particle); lines: the "
                    "particle grid", ticks, scale)
    if view == "speed":
        labels = [(0.001, "1 mm/s"), (0.01, "1 cm/s"), (0.1, "10 cm/s"),
                  (K.SPEED_RANGE[1], f"{K.SPEED_RANGE[1]:g} m/s")]
        return _bar("speed (log scale); lines: the particle grid",
                    [(K.speed_to_unit(v), s) for v, s in labels], scale)
    if view == "pinned":
        return _swatches("pins; lines: the particle grid",
                         [("free", K.PIN_COLORS["free"]), ("pinned", K.PIN_COLORS["pinned"]),
                          ("grabbed", K.PIN_COLORS["grabbed"])], scale)
    if view == "material":
        return _swatches("material id", [("sky (0)", (0.0, 0.0, 0.0))] + [
            (f"{m.name.lower().replace('_', ' ')} ({m.id})", m.debug) for m in K.MATERIALS],
            scale)
    text = {
        "position": "world position: 0.5 + sin(2 pi (x, y, z) / 1 m) / 2 -> red, green, blue",
        "normal": "unit normal, facing the viewer: x, y, z -> red, green, blue (0.5 + n / 2)",
        "albedo": "albedo before lighting (stored as the square root of linear, near sRGB)",
        "depth": "distance from the eye: white at 0, black at twice the distance to the target",
        "shadow map": "the key light's depth map (square): dark near the light, light far",
    }.get(view)
    return None if text is None else text_panel([text], scale)
