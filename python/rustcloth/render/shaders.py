"""Load GLSL programs from ``rustcloth/shaders`` and report compile errors by file and line."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import moderngl

SHADER_DIR = Path(str(resources.files("rustcloth") / "shaders"))

# Mesa prints "0:12(5): error: ...", NVIDIA "0(12) : error ...": capture the line number.
_LINE = re.compile(r"^\s*\d+[:(](\d+)[)(:]?[\d)]*\s*:?\s*(.*)$")
_STAGES = {"vertex_shader": "vertex_shader", "fragment_shader": "fragment_shader"}


class ShaderError(RuntimeError):
    """A shader failed to compile or link; the message starts with ``file:line``."""


def _source(name: str, directory: Path) -> str:
    return (directory / name).read_text(encoding="utf-8")


def _locate(message: str, files: dict[str, str]) -> str:
    """Rewrite the driver's log so each error names the shader file and line."""
    stage = None
    lines = []
    for raw in message.splitlines():
        key = raw.strip()
        if key in _STAGES:
            stage = key
            continue
        m = _LINE.match(raw)
        if m and stage in files:
            lines.append(f"{files[stage]}:{m.group(1)}: {m.group(2)}")
        elif key and not set(key) <= {"="}:
            lines.append(key)
    return "\n".join(lines)


def load_program(
    ctx: moderngl.Context, vertex: str, fragment: str, directory: Path | None = None
) -> moderngl.Program:
    """Compile ``vertex`` and ``fragment`` (file names in the shader directory)."""
    directory = SHADER_DIR if directory is None else directory
    files = {"vertex_shader": str(directory / vertex), "fragment_shader": str(directory / fragment)}
    try:
        return ctx.program(
            vertex_shader=_source(vertex, directory), fragment_shader=_source(fragment, directory)
        )
    except moderngl.Error as err:
        raise ShaderError(_locate(str(err), files)) from None
