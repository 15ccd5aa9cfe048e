"""The viewer: one frame loop (:class:`Viewer`) shared by the desktop demo (a glfw window)
and headless rendering (EGL), with their command lines :func:`main_demo` and
:func:`main_render`."""

from .cli import main_demo, main_render
from .loop import Viewer

__all__ = ["Viewer", "main_demo", "main_render"]
