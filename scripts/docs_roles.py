"""A griffe extension for the docs build (mkdocs.yml): turns the Sphinx roles the docstrings use
(:class:`Scene`, :meth:`~rustcloth.Simulation.render_mesh`, ...) into mkdocstrings
cross-references, so that the reference links them and `mkdocs build --strict` fails on one
that names nothing documented. A name resolves as Python would read it where it is written:
a member of the class, then of the module, then a path from the package root."""

from __future__ import annotations

import builtins
import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:class|func|meth|attr|mod|data|exc|obj):`(~?)([\w.]+)(\(\))?`")
logger = griffe.get_logger(__name__)


def _lookup(scope: griffe.Object | None, name: str) -> Any:
    while scope is not None:
        try:
            return scope[name]
        except (KeyError, ValueError):
            scope = scope.parent
    return None


def _resolve(obj: griffe.Object, name: str, package: griffe.Module) -> str | None:
    if name.startswith(package.name + "."):
        found = _lookup(package, name.removeprefix(package.name + "."))
    else:
        scope = obj if isinstance(obj, griffe.Class | griffe.Module) else obj.parent
        found = _lookup(scope, name)
    if found is None:
        return None
    # An imported name (an alias) links to where it is defined: the reference documents the
    # object there, and mkdocstrings registers that path for it too.
    return str(found.final_target.path if found.is_alias else found.path)


class SphinxRoles(griffe.Extension):
    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        self._walk(pkg, pkg, set())

    def _walk(self, obj: griffe.Object, package: griffe.Module, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(lambda m: self._link(obj, m, package),
                                           obj.docstring.value)
        for member in obj.members.values():
            if not member.is_alias:
                self._walk(member, package, seen)  # type: ignore[arg-type]

    def _link(self, obj: griffe.Object, match: re.Match[str], package: griffe.Module) -> str:
        tilde, name, call = match.groups()
        text = name.rsplit(".", 1)[-1] if tilde else name
        target = _resolve(obj, name, package)
        if target is None:
            foreign = "." in name and not name.startswith(package.name + ".")
            if foreign or hasattr(builtins, name):
                return f"`{text}{call or ''}`"  # a built-in or another library's name
            target = name  # a name of ours that names nothing: autorefs reports it
        return f"[`{text}{call or ''}`][{target}]"
