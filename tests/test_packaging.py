"""What the installed package declares and ships. The tests that read the repository's own files
(Cargo.toml, README.md) skip when the suite runs against an installed wheel from elsewhere."""

from __future__ import annotations

import re
import tomllib
from importlib import metadata, resources
from pathlib import Path

import pytest
import rustcloth

REPO = Path(__file__).resolve().parents[1]
IN_REPO = (REPO / "Cargo.toml").is_file() and (REPO / "pyproject.toml").is_file()
in_repo = pytest.mark.skipif(not IN_REPO, reason="needs the repository's files")


def test_version_comes_from_the_installed_metadata():
    assert rustcloth.__version__ == metadata.version("rustcloth")
    assert re.fullmatch(r"\d+\.\d+\.\d+([.-]?\w+)*", rustcloth.__version__)


@in_repo
def test_version_has_one_source_cargo_toml():
    cargo = tomllib.loads((REPO / "Cargo.toml").read_text())
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"]
    assert pyproject["project"]["dynamic"] == ["version"]
    assert rustcloth.__version__ == cargo["package"]["version"]


def test_core_needs_only_numpy_and_tqdm():
    requires = metadata.requires("rustcloth") or []
    core = {re.split(r"[<>=!~ ;\[]", r, maxsplit=1)[0].lower() for r in requires
            if "extra ==" not in r}
    assert core == {"numpy", "tqdm"}


def test_extras_are_declared():
    extras = set(metadata.metadata("rustcloth").get_all("Provides-Extra") or [])
    assert extras == {"viewer", "video", "study", "usd", "export", "ray", "all"}


# The distribution that installs each module a writer of rustcloth.export imports.
DISTRIBUTION_OF_MODULE = {"trimesh": "trimesh", "PIL": "pillow", "pxr": "usd-core"}


@pytest.mark.parametrize(("path", "extra"), [("a.glb", "export"), ("a.obj", "export"),
                                             ("a_##.obj", "export"), ("a.usd", "usd")])
def test_an_extra_alone_brings_every_module_its_files_need(path, extra):
    # With only rustcloth[export], .glb export failed for want of Pillow, which trimesh imports
    # lazily; the extras were only ever tested installed together.
    from rustcloth import export

    requires = metadata.requires("rustcloth") or []
    in_extra = {re.split(r"[<>=!~ ;\[]", r, maxsplit=1)[0].lower() for r in requires
                if re.search(rf"extra\s*==\s*['\"]{extra}['\"]", r)}
    needed = {DISTRIBUTION_OF_MODULE[m] for m in export.required_modules(path)}
    assert needed <= in_extra, f"rustcloth[{extra}] lacks {needed - in_extra}"


@in_repo
def test_development_tools_are_dependency_groups_not_extras():
    groups = tomllib.loads((REPO / "pyproject.toml").read_text())["dependency-groups"]
    assert {"include-group": "test"} in groups["dev"]
    tools = " ".join(str(r) for name in ("test", "lint", "docs") for r in groups[name])
    for tool in ("pytest", "ruff", "mypy", "mkdocs", "nbclient"):
        assert tool in tools
    assert "--group dev" in (REPO / "Makefile").read_text()


def test_license_and_classifiers():
    meta = metadata.metadata("rustcloth")
    assert meta["License-Expression"] == "MIT"
    assert "Programming Language :: Rust" in meta.get_all("Classifier")
    assert any(url.startswith("Repository, https://") for url in meta.get_all("Project-URL"))


def test_package_data_is_installed():
    # The renderer's shaders, the type stub and the py.typed marker ship with the package.
    root = resources.files("rustcloth")
    assert (root / "py.typed").is_file()
    assert (root / "_core.pyi").is_file()
    shaders = [p.name for p in (root / "shaders").iterdir()]
    assert "geometry.vert" in shaders and "lighting.frag" in shaders


@in_repo
def test_readme_links_work_on_a_package_index_page():
    # A package index shows README.md without the repository around it: every link to a file
    # of the repository must be absolute, under pyproject's Repository URL.
    repository = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["urls"][
        "Repository"]
    readme = (REPO / "README.md").read_text()
    targets = re.findall(r"\]\(([^)\s]+)\)", readme)
    assert targets, "README.md has links"
    for target in targets:
        if target.startswith("#"):
            continue
        assert target.startswith("https://"), f"relative link {target!r} in README.md"
        if "github.com" in target:
            assert target.startswith(repository + "/"), target
            path = target.removeprefix(repository + "/blob/main/").split("?")[0].split("#")[0]
            assert (REPO / path).exists(), f"README.md links to a missing file: {target}"


@in_repo
def test_changelog_opens_with_the_current_version():
    cargo = tomllib.loads((REPO / "Cargo.toml").read_text())["package"]["version"]
    changelog = (REPO / "CHANGELOG.md").read_text()
    versions = re.findall(r"^## \[(\d+\.\d+\.\d+[^\]]*)\]", changelog, flags=re.M)
    assert versions and versions[0] == cargo, versions[:1]
    assert f"[{cargo}]: " in changelog  # the link to the release's tag


@in_repo
def test_citation_has_the_version_and_repository_of_the_package():
    yaml = pytest.importorskip("yaml")
    citation = yaml.safe_load((REPO / "CITATION.cff").read_text())
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    cargo = tomllib.loads((REPO / "Cargo.toml").read_text())["package"]["version"]
    assert citation["cff-version"] == "1.2.0"
    assert citation["version"] == cargo
    assert citation["repository-code"] == pyproject["project"]["urls"]["Repository"]
    assert citation["license"] == pyproject["project"]["license"]
    assert citation["title"] and citation["authors"]
