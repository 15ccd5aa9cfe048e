"""OpenGL context creation with one clear message when no 3.3 context can be had."""

from __future__ import annotations

from typing import Any

import moderngl

APT_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"


class GLUnavailable(RuntimeError):
    """No OpenGL 3.3 core context: the message names what is missing and what provides it."""


def create_standalone_context() -> moderngl.Context:
    """An offscreen OpenGL >= 3.3 context through EGL (Mesa llvmpipe when there is no GPU)."""
    try:
        settings: dict[str, Any] = {"backend": "egl"}  # (the stub types **settings oddly)
        ctx = moderngl.create_context(standalone=True, require=330, **settings)
    except Exception as err:  # moderngl/glcontext raise plain Exceptions with varied text
        raise GLUnavailable(
            f"no OpenGL 3.3 context through EGL ({str(err).strip().splitlines()[0]}); "
            f"install the Debian packages {APT_PACKAGES}"
        ) from None
    return ctx
