"""Load GLSL programs from ``rustcloth/shaders`` with the shared constants prepended, and report
compile errors by file and line."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import moderngl

from .constants import glsl_header

SHADER_DIR = Path(str(resources.files("rustcloth") / "shaders"))

# Mesa prints "0:12(5): error: ...", NVIDIA "0(12) : error ...": capture the line number.
_LINE = re.compile(r"^\s*\d+[:(](\d+)[)(:]?[\d)]*\s*:?\s*(.*)$")
_STAGES = {"vertex_shader": "vertex_shader", "fragment_shader": "fragment_shader"}


class ShaderError(RuntimeError):
    """A shader failed to compile or link; the message starts with ``file:line``."""


def with_constants(source: str) -> str:
    """``source`` with :func:`~.constants.glsl_header` after its ``#version`` line, and a
    ``#line`` directive so the driver's line numbers still match the file."""
    first, newline, rest = source.partition("\n")
    if not first.startswith("#version"):
        return f"{glsl_header()}#line 1\n{source}"
    return f"{first}{newline}{glsl_header()}#line 2\n{rest}"


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
    vs, fs = (with_constants(Path(files[stage]).read_text(encoding="utf-8"))
              for stage in ("vertex_shader", "fragment_shader"))
    try:
        return ctx.program(vertex_shader=vs, fragment_shader=fs)
    except moderngl.Error as err:
        raise ShaderError(_locate(str(err), files)) from None
