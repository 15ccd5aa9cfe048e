"""The documentation still runs: every example in the public modules' docstrings, and the site
(mkdocs.yml: docs/ and the API reference) builds with --strict, which fails on a broken link,
a cross-reference to nothing, a page left out of the navigation or a docstring it cannot read."""

from __future__ import annotations

import doctest
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

PUBLIC_MODULES = ["rustcloth", "rustcloth.scene", "rustcloth.simulation", "rustcloth.export",
                  "rustcloth.settings", "rustcloth.sweep", "rustcloth.drivers",
                  "rustcloth.errors", "rustcloth.reference", "rustcloth.garment"]


@pytest.mark.parametrize("name", PUBLIC_MODULES)
def test_docstring_examples_run(name, tmp_path, monkeypatch):
    # An example nothing runs goes stale: each module's examples run as written.
    monkeypatch.chdir(tmp_path)
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS,
                             report=True, verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) of {name} failed"


@pytest.mark.skipif(not (REPO / "mkdocs.yml").is_file(), reason="needs the repository's files")
def test_docs_site_builds_without_warnings(tmp_path):
    pytest.importorskip("mkdocstrings_handlers.python")
    env = {**os.environ, "PYTHONPATH": str(REPO / "python")}
    # Not -q: it hides the warnings that --strict counts, and the build passes with them.
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d",
                           str(tmp_path / "site")], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "WARNING" not in done.stderr, done.stderr
    api = (tmp_path / "site" / "api" / "simulation" / "index.html").read_text()
    assert 'id="rustcloth.Simulation.to_mesh"' in api
    assert 'href="#rustcloth.Simulation.render_mesh"' in api  # a :meth: role, linked
