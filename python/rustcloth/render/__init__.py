"""Deferred-shading renderer for rustcloth (moderngl): shadow map, G-buffer, lighting, debug
views and overlay panels; the viewer (``rustcloth.viewer``) drives it."""

from .constants import VIEWS
from .context import GLUnavailable, create_standalone_context
from .renderer import Renderer
from .shaders import ShaderError, load_program

__all__ = [
    "VIEWS",
    "GLUnavailable",
    "Renderer",
    "ShaderError",
    "create_standalone_context",
    "load_program",
]
