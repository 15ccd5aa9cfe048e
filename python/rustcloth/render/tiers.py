"""Rendering quality tiers, and which one a GL context calls for. No OpenGL import here, so
the command lines can list the tiers before the viewer extra is installed."""

from __future__ import annotations

from typing import Any

TIERS = ("full", "software")
"""``full``: deferred, for a GPU. ``software``: one forward pass lit per vertex, no SSAO or
FXAA, a smaller shadow map, for a CPU rasteriser (Mesa llvmpipe)."""
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")
"""Words in ``GL_RENDERER`` that name Mesa's CPU rasterisers."""
SOFTWARE_SHADOW_SIZE = 512
"""The software tier's shadow map, pixels each way (the full tier's is 1024)."""


def is_software(gl_renderer: str) -> bool:
    """Whether a ``GL_RENDERER`` string names a CPU rasteriser (:data:`SOFTWARE_RENDERERS`)."""
    name = gl_renderer.lower()
    return any(word in name for word in SOFTWARE_RENDERERS)


def auto_tier(ctx: Any) -> str:
    """The tier a moderngl context should start in: ``software`` on a CPU rasteriser, else
    ``full``."""
    return "software" if is_software(str(ctx.info.get("GL_RENDERER", ""))) else "full"
