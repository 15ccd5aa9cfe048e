#!/usr/bin/env python3
"""Lists the Rust modules of src/ that import each other in a circle, and each module's size.

    python3 scripts/module_cycles.py          # exits 1 if a module imports one that imports it

A module is a file under src/ (a `mod.rs` stands for its folder). An edge a -> b is a `use
crate::b...` or `crate::b::...` path written in a's file (tests and comments excluded); `super::`
paths count as edges to the parent module. Cycles are the strongly connected components of
more than one module.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def module_of(path: Path) -> str:
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    return "::".join(parts) or "crate"


def known(modules: set[str], path: str) -> str | None:
    """The longest module name that `path` (a::b::c) starts with."""
    parts = path.split("::")
    for n in range(len(parts), 0, -1):
        candidate = "::".join(parts[:n])
        if candidate in modules:
            return candidate
    return None


def code_of(text: str) -> str:
    text = re.sub(r"#\[cfg\(test\)\]\s*mod tests\s*\{.*", "", text, flags=re.S)
    return "\n".join(line.split("//")[0] for line in text.splitlines())


def main() -> int:
    files = sorted(SRC.rglob("*.rs"))
    modules = {module_of(f): f for f in files}
    edges: dict[str, set[str]] = {m: set() for m in modules}
    for m, f in modules.items():
        code = code_of(f.read_text())
        for path in re.findall(r"crate::((?:\w+::)*\w+)", code):
            target = known(set(modules), path)
            if target and target != m and not m.startswith(target + "::"):
                edges[m].add(target)
        if "super::" in code and "::" in m:
            parent = m.rsplit("::", 1)[0]
            for path in re.findall(r"super::((?:\w+::)*\w+)", code):
                target = known(set(modules), f"{parent}::{path}") or parent
                if target != m:
                    edges[m].add(target)
    # Tarjan's strongly connected components.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(modules):
        if v not in index:
            visit(v)
    sizes = sorted(((len(f.read_text().splitlines()), m) for m, f in modules.items()), reverse=True)
    print("largest files:", ", ".join(f"{m} {n}" for n, m in sizes[:6]))
    if not cycles:
        print(f"{len(modules)} modules, no import cycles")
        return 0
    for c in cycles:
        print("import cycle:", " <-> ".join(c))
    return 1


if __name__ == "__main__":
    sys.exit(main())
