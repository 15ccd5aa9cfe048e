"""Deferred-shading renderer for rustcloth (moderngl): shadow map, G-buffer, lighting, debug
views and overlay panels; the viewer (``rustcloth.viewer``) drives it."""

import importlib
from typing import TYPE_CHECKING, Any

from .constants import VIEWS

if TYPE_CHECKING:
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

# Names whose modules import moderngl, loaded on first use: the light submodules (constants,
# lights) stay importable without the viewer extra, for the command lines' --help.
_LAZY = {"GLUnavailable": "context", "create_standalone_context": "context",
         "Renderer": "renderer", "ShaderError": "shaders", "load_program": "shaders"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
