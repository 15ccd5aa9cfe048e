"""Load GLSL programs from ``rustcloth/shaders`` with the shared constants prepended and their
``#include "file.glsl"`` lines expanded, and report compile errors by file and line."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import moderngl

from .constants import glsl_header

SHADER_DIR = Path(str(resources.files("rustcloth") / "shaders"))

# Mesa prints "0:12(5): error: ...", NVIDIA "0(12) : error ...": the source string (0 for the
# file itself, k for its k-th include, as the #line directives number them) and the line.
_LINE = re.compile(r"^\s*(\d+)[:(](\d+)[)(:]?[\d)]*\s*:?\s*(.*)$")
_INCLUDE = re.compile(r'^#include "([\w.]+)"\s*$')
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


def expand_includes(source: str, directory: Path) -> tuple[str, list[str]]:
    """``source`` with each ``#include "name"`` line replaced by that file (and its own
    includes), each numbered as its own source string by ``#line`` so errors name it; and the
    included files' paths, in that numbering (the first is source string 1)."""
    included: list[str] = []

    def expand(text: str, number: int, depth: int) -> list[str]:
        out: list[str] = []
        for line_no, line in enumerate(text.split("\n"), start=1):
            m = _INCLUDE.match(line)
            if m is None:
                out.append(line)
                continue
            if depth > 8:
                raise ShaderError(f"{m.group(1)}: includes nested more than 8 deep")
            path = directory / m.group(1)
            included.append(str(path))
            inner = path.read_text(encoding="utf-8").rstrip("\n")
            out += [f"#line 1 {len(included)}", *expand(inner, len(included), depth + 1),
                    f"#line {line_no + 1} {number}"]
        return out

    lines = expand(source, 0, 0)
    # A #line with no line after it, as an include on a file's last line leaves, is refused by
    # NVIDIA's compiler ("error C0115: #line source-string number invalid"); Mesa takes it.
    while lines and (not lines[-1].strip() or lines[-1].startswith("#line")):
        lines.pop()
    return "\n".join([*lines, ""]), included


def _locate(message: str, files: dict[str, list[str]]) -> str:
    """Rewrite the driver's log so each error names the shader file and line."""
    stage = None
    lines = []
    for raw in message.splitlines():
        key = raw.strip()
        if key in _STAGES:
            stage = key
            continue
        m = _LINE.match(raw)
        if m and stage in files and int(m.group(1)) < len(files[stage]):
            lines.append(f"{files[stage][int(m.group(1))]}:{m.group(2)}: {m.group(3)}")
        elif key and not set(key) <= {"="}:
            lines.append(key)
    return "\n".join(lines)


def load_program(
    ctx: moderngl.Context, vertex: str, fragment: str, directory: Path | None = None
) -> moderngl.Program:
    """Compile ``vertex`` and ``fragment`` (file names in the shader directory)."""
    directory = SHADER_DIR if directory is None else directory
    files: dict[str, list[str]] = {}
    sources: dict[str, str] = {}
    for stage, name in (("vertex_shader", vertex), ("fragment_shader", fragment)):
        path = directory / name
        text, included = expand_includes(path.read_text(encoding="utf-8"), directory)
        files[stage] = [str(path), *included]
        sources[stage] = with_constants(text)
    try:
        return ctx.program(vertex_shader=sources["vertex_shader"],
                           fragment_shader=sources["fragment_shader"])
    except moderngl.Error as err:
        raise ShaderError(_locate(str(err), files)) from None
