"""Where ``python -m rustcloth demo`` and ``render`` find their entry points: the viewer's
command lines, kept importable here (``rustcloth.app.main_demo``) for the dispatcher."""

from .viewer.cli import main_demo, main_render

__all__ = ["main_demo", "main_render"]
