#!/usr/bin/env python3
"""Lists the modules that depend on each other in a circle: the Rust modules of src/ and the
Python modules of python/rustcloth/. Exits 1 if there is such a circle, 0 if there is none.

    python3 scripts/module_cycles.py            # both languages, this checkout
    python3 scripts/module_cycles.py --rust     # one of them
    python3 scripts/module_cycles.py --root DIR # another checkout

A cycle is a strongly connected component of more than one node; each is printed with the uses
that close it, so that one can see which to move.

Rust. A module is a file under src/ (a `mod.rs` stands for its folder, `lib.rs` for the crate),
and its parent the module whose `mod name;` declares it: the declarations make a tree, and a
module with its descendants is a subsystem (`stepper` is stepper/mod.rs, stepper/recovery.rs,
...). A module uses another where its code, outside comments and the `#[cfg(test)] mod tests`
block, names a path into it: `crate::b::...`, `super::...` or `self::...` (a path names the
longest module it starts with, so an item of a parent's file, or one the parent re-exports with
`pub use`, names the parent).

Cycles are looked for between siblings: a use of module b by module a is an arrow between the
two subsystems, children of the same parent, that hold them (snapshot's use of
`stepper::Stepper` and stepper::recovery's use of `snapshot::WatchdogSnapshot` are
snapshot -> stepper and stepper -> snapshot, a cycle among the children of the crate). Uses
between a module and its ancestors are not arrows in either direction: a parent is made of its
children (`mod child;`) and uses them, and a child reaching its parent's items (`super::item`,
private ones included) is how Rust shares them; counted, they would make every parent and child
a cycle. So a cycle is always between sibling subsystems, at any depth.

Python. A module is a file under python/rustcloth/ (an `__init__.py` stands for its package, a
`.pyi` stub for a compiled module). An edge a -> b is an import of b that runs when a is
imported: a statement of a's module body, also inside a module-level `try:`, `if:` or class
body. Imports inside functions and methods run later, when called, and imports under
`if TYPE_CHECKING:` never run: neither counts. `from . import x` imports the submodule x where
there is one, else the package's `__init__`; that importing a submodule first loads its
packages is not counted. Unlike Rust's, these edges are not lifted to subsystems: a package's
`__init__` and a module it imports that imports the `__init__` back are a real circle at import
time.
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "rustcloth"

Edges = dict[str, dict[str, str]]
"""module -> {module it depends on: how (the first use found)}."""


# ----- Rust ----------------------------------------------------------------------------------

def rust_module_of(src: Path, path: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    return "::".join(parts) or "crate"


def longest_module(modules: set[str], path: str) -> str | None:
    """The longest module name that `path` (a::b::c) starts with."""
    parts = path.split("::")
    for n in range(len(parts), 0, -1):
        candidate = "::".join(parts[:n])
        if candidate in modules:
            return candidate
    return None


def rust_code_of(text: str) -> str:
    text = re.sub(r"#\[cfg\(test\)\]\s*mod tests\s*\{.*", "", text, flags=re.S)
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return "\n".join(line.split("//")[0] for line in text.splitlines())


def child(module: str, name: str) -> str:
    return name if module == "crate" else f"{module}::{name}"


def rust_uses(src: Path) -> tuple[dict[str, Path], dict[str, str], list[tuple[str, str, str]]]:
    """The modules' files, each module's parent, and every use ``(module, used, how)``."""
    files = {rust_module_of(src, f): f for f in sorted(src.rglob("*.rs"))}
    modules = set(files)
    codes = {m: rust_code_of(f.read_text()) for m, f in files.items()}
    parent_of: dict[str, str] = {}
    for m, code in codes.items():
        for name in re.findall(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;", code, re.M):
            if child(m, name) in modules:
                parent_of[child(m, name)] = m
    for m in modules - set(parent_of) - {"crate"}:  # a file no `mod` declares: by its folder
        parent_of[m] = m.rsplit("::", 1)[0] if "::" in m else "crate"
    uses: list[tuple[str, str, str]] = []
    for m, code in codes.items():
        found: list[tuple[str | None, str]] = []
        for path in re.findall(r"\bcrate::((?:\w+::)*\w+)", code):
            found.append((longest_module(modules, path), f"crate::{path}"))
        for path in re.findall(r"\bsuper::((?:\w+::)*\w+)", code):
            found.append((longest_module(modules, child(parent_of.get(m, "crate"), path)),
                          f"super::{path}"))
        for path in re.findall(r"\bself::((?:\w+::)*\w+)", code):
            found.append((longest_module(modules, child(m, path)), f"self::{path}"))
        seen: set[str] = set()
        for used, how in found:
            if used is not None and used != m and used not in seen:
                seen.add(used)
                uses.append((m, used, how))
    return files, parent_of, uses


def lineage(module: str, parent_of: dict[str, str]) -> list[str]:
    """``crate``, then each ancestor of ``module`` down to ``module`` itself."""
    chain = [module]
    while chain[-1] != "crate":
        chain.append(parent_of[chain[-1]])
    return chain[::-1]


def sibling_edges(parent_of: dict[str, str], uses: list[tuple[str, str, str]]) -> Edges:
    """The uses lifted to arrows between sibling subsystems; a node is named by its module path
    (a child of the crate by its name), an arrow's value lists the uses it stands for."""
    edges: Edges = {}
    for a, b, how in uses:
        la, lb = lineage(a, parent_of), lineage(b, parent_of)
        if a in lb or b in la:
            continue  # a module and one of its ancestors
        depth = next(i for i, (x, y) in enumerate(zip(la, lb, strict=False)) if x != y)
        sa, sb = la[depth], lb[depth]
        edges.setdefault(sa, {})
        edges.setdefault(sb, {})
        why = f"{a} uses {b} ({how})"
        edges[sa][sb] = f"{edges[sa][sb]}; {why}" if sb in edges[sa] else why
    return edges


# ----- Python --------------------------------------------------------------------------------

def python_module_of(package_dir: Path, path: Path) -> str:
    parts = [PACKAGE, *path.relative_to(package_dir).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def run_at_import(body: Iterable[ast.stmt]) -> Iterator[ast.Import | ast.ImportFrom]:
    """The import statements among ``body`` and the blocks it runs at import time."""
    for node in body:
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        elif isinstance(node, ast.If):
            if not is_type_checking(node.test):
                yield from run_at_import(node.body)
            yield from run_at_import(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody,
                          *(handler.body for handler in node.handlers)):
                yield from run_at_import(block)
        elif isinstance(node, ast.With):
            yield from run_at_import(node.body)
        elif isinstance(node, ast.ClassDef):
            yield from run_at_import(node.body)


def python_edges(package_dir: Path) -> Edges:
    files = {python_module_of(package_dir, f): f for f in sorted(package_dir.rglob("*.py"))}
    stubs = {python_module_of(package_dir, f) for f in package_dir.rglob("*.pyi")}
    modules = set(files) | stubs
    edges: Edges = {m: {} for m in modules}
    for m, f in files.items():
        package = m if f.name == "__init__.py" else m.rsplit(".", 1)[0]
        for node in run_at_import(ast.parse(f.read_text(), str(f)).body):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join([*anchor, *([base] if base else [])])
                # `from pkg import name`: the submodule pkg.name where there is one.
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                           for alias in node.names]
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != m:
                    edges[m].setdefault(target, f"line {node.lineno}")
    return edges


# ----- cycles --------------------------------------------------------------------------------

def cycles_of(edges: Edges) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, {})):
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
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def report(language: str, edges: Edges, modules: int) -> bool:
    """Prints the cycles of ``edges``; True if there is none."""
    cycles = cycles_of(edges)
    if not cycles:
        print(f"{language}: {modules} modules, no import cycles")
        return True
    for component in cycles:
        print(f"{language}: import cycle: " + " <-> ".join(component))
        inside = set(component)
        for a in component:
            for b, how in sorted(edges[a].items()):
                if b in inside:
                    print(f"    {a} -> {b}  ({how})")
    return False


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout (default: this)")
    parser.add_argument("--rust", action="store_true", help="only the Rust modules")
    parser.add_argument("--python", action="store_true", help="only the Python modules")
    args = parser.parse_args(argv)
    both = args.rust == args.python
    clean = True
    if args.rust or both:
        files, parent_of, uses = rust_uses(args.root / "src")
        sizes = sorted(((len(f.read_text().splitlines()), m) for m, f in files.items()),
                       reverse=True)
        print("rust: largest files:", ", ".join(f"{m} {n}" for n, m in sizes[:6]))
        clean &= report("rust", sibling_edges(parent_of, uses), len(files))
    if args.python or both:
        edges = python_edges(args.root / "python" / PACKAGE)
        clean &= report("python", edges, len(edges))
    return 0 if clean else 1


if __name__ == "__main__":
    sys.exit(main())
