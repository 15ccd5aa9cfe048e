"""One frame of the stand-in scene, as the renderer tests look at it."""

from __future__ import annotations

from typing import Any

import numpy as np
from rustcloth.camera import Camera
from rustcloth.render import Renderer


def camera(size: tuple[int, int]) -> Camera:
    """The view the renderer tests share: the cloth, its shadow and the floor around it."""
    return Camera(eye=(0.9, 2.2, 2.4), target=(0.0, 0.5, 0.0), aspect=size[0] / size[1])


def frame(ctx: Any, r: Renderer, cam: Camera, size: tuple[int, int]) -> np.ndarray:
    """`r`'s next frame from `cam`, `(height, width, 3)` uint8."""
    fbo = ctx.simple_framebuffer(size)
    r.update()
    r.render(fbo, cam)
    # Not released: moderngl would later rebind the deleted framebuffer (GL_INVALID_OPERATION).
    return np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(size[1], size[0], 3)
