"""Deferred-shading renderer for rustcloth (moderngl): G-buffer, shadow map, lighting, debug
views, plus the interaction and headless-rendering helpers the demo shares."""

from .context import GLUnavailable, create_standalone_context
from .renderer import VIEWS, Renderer, default_camera
from .shaders import ShaderError, load_program

__all__ = [
    "VIEWS",
    "GLUnavailable",
    "Renderer",
    "ShaderError",
    "create_standalone_context",
    "default_camera",
    "load_program",
]
