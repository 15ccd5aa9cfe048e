"""The type stub `_core.pyi` lists exactly what the compiled module exposes."""

from __future__ import annotations

import ast
from pathlib import Path

import rustcloth._core as core

STUB = Path(core.__file__).with_name("_core.pyi")


def stub_names() -> tuple[set[str], set[str]]:
    tree = ast.parse(STUB.read_text())
    module, methods = set(), set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            module.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            module.add(node.target.id)
        elif isinstance(node, ast.ClassDef):
            module.add(node.name)
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    methods.add(item.name)
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    methods.add(item.target.id)
    return module, methods


def test_stub_matches_the_compiled_module():
    module, methods = stub_names()
    public = {n for n in dir(core) if not n.startswith("_")}
    assert module == public
    compiled = {n for n in dir(core.Simulation) if not n.startswith("_")} | {"__new__"}
    assert {m for m in methods if not m.startswith("_") or m == "__new__"} == compiled
