"""The viewer: one frame loop (:class:`Viewer`) shared by the desktop demo (a glfw window)
and headless rendering (EGL), with their command lines :func:`main_demo` and
:func:`main_render`."""

from typing import TYPE_CHECKING, Any

from .cli import main_demo, main_render

if TYPE_CHECKING:
    from .loop import Viewer

__all__ = ["Viewer", "main_demo", "main_render"]


def __getattr__(name: str) -> Any:
    # The loop needs OpenGL: loaded on first use, so that the command lines' --help (and
    # `import rustcloth.viewer.cli`) work without the viewer extra.
    if name == "Viewer":
        from .loop import Viewer

        return Viewer
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
