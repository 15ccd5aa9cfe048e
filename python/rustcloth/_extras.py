"""Optional dependencies: which extra of ``pip install rustcloth[...]`` brings each one, and the
error that says so when one is missing."""

from __future__ import annotations

import importlib.util

# Top-level module -> the extra (pyproject.toml's [project.optional-dependencies]) that installs it.
EXTRA_OF_MODULE: dict[str, str] = {
    "moderngl": "viewer",
    "glcontext": "viewer",
    "glfw": "viewer",
    "PIL": "viewer",
    "imageio": "viewer",
    "imageio_ffmpeg": "video",
    "matplotlib": "study",
    "pxr": "usd",
    "trimesh": "export",
    "ray": "ray",
}


class MissingExtra(ModuleNotFoundError):
    """An optional dependency is not installed; the message names the extra that installs it.

    A :class:`ModuleNotFoundError` (so an ``ImportError``), with ``name`` the missing module and
    ``extra`` the extra."""

    def __init__(self, module: str, what: str, extra: str | None = None) -> None:
        self.extra = extra or EXTRA_OF_MODULE.get(module.split(".")[0], "all")
        super().__init__(
            f"{what} needs {module!r}, which is not installed: "
            f"pip install 'rustcloth[{self.extra}]'",
            name=module,
        )


def require(what: str, *modules: str) -> None:
    """Raise :class:`MissingExtra` for the first of ``modules`` that cannot be imported."""
    for module in modules:
        if importlib.util.find_spec(module) is None:
            raise MissingExtra(module, what)


def as_missing_extra(err: ModuleNotFoundError, what: str) -> MissingExtra | None:
    """``err`` as a :class:`MissingExtra` when the module it names belongs to an extra, else
    None (a missing module of our own or of the standard library is a bug, not an extra)."""
    if isinstance(err, MissingExtra):
        return err
    top = (err.name or "").split(".")[0]
    return MissingExtra(top, what) if top in EXTRA_OF_MODULE else None
