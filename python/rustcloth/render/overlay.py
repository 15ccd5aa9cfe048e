"""Text panels for the overlay, rasterised with Pillow (core GL has no text)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

_FONT: ImageFont.ImageFont | ImageFont.FreeTypeFont | None = None


def text_panel(lines: list[str], scale: int = 13) -> npt.NDArray[np.uint8]:
    """RGBA8 image (rows top to bottom, flipped for GL upload) of the lines on a dim panel."""
    global _FONT
    if _FONT is None:
        try:
            _FONT = ImageFont.load_default(size=scale)
        except TypeError:  # Pillow < 10.1 has only the fixed bitmap font
            _FONT = ImageFont.load_default()
    line_h = scale + 4
    width = 12 + max((int(_FONT.getlength(s)) for s in lines), default=0)
    img = Image.new("RGBA", (max(width, 1), 8 + line_h * len(lines)), (0, 0, 0, 140))
    draw = ImageDraw.Draw(img)
    for k, s in enumerate(lines):
        draw.text((6, 4 + k * line_h), s, fill=(255, 255, 255, 255), font=_FONT)
    # GL textures start at the bottom row.
    return np.ascontiguousarray(np.asarray(img, dtype=np.uint8)[::-1])
