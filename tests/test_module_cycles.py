"""scripts/module_cycles.py (`make lint`) on small made-up trees: what it counts as a cycle,
in Rust and in Python, and what it leaves out."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "module_cycles.py"
if not SCRIPT.exists():  # the copy of the suite that scripts/test-wheel.sh runs has no scripts/
    pytest.skip("needs the repository's scripts/", allow_module_level=True)
spec = importlib.util.spec_from_file_location("module_cycles", SCRIPT)
assert spec is not None and spec.loader is not None
module_cycles = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module_cycles)


def write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


RUST = {
    "src/lib.rs": "mod snapshot;\npub mod stepper;\nmod solver;\n",
    # snapshot uses the stepper's parent file, the stepper's child uses snapshot: a cycle.
    "src/snapshot.rs": "use crate::stepper::Stepper;\npub struct WatchdogSnapshot;\n",
    "src/stepper/mod.rs": "mod recovery;\npub struct Stepper;\nfn private() {}\n",
    "src/stepper/recovery.rs": "use super::private;\nuse crate::snapshot::WatchdogSnapshot;\n",
    # A parent using its child and the child its parent's private items: no cycle.
    "src/solver/mod.rs": "mod kernel;\nuse self::kernel::run;\npub(crate) fn shared() {}\n",
    "src/solver/kernel.rs": (
        "use super::shared;\n// crate::snapshot::WatchdogSnapshot in a comment\n"
        "pub fn run() { crate::solver::shared() }\n"
        "#[cfg(test)]\nmod tests {\n    use crate::stepper::Stepper;\n}\n"
    ),
}

PYTHON = {
    "python/rustcloth/__init__.py": "from .simulation import Simulation\n",
    "python/rustcloth/_core.pyi": "",
    "python/rustcloth/simulation.py": (
        "from typing import TYPE_CHECKING\nfrom . import _core\n"
        "if TYPE_CHECKING:\n    from .export import Mesh\n"
        "class Simulation:\n    def export(self):\n        from .export import export\n"
    ),
    "python/rustcloth/export.py": "from .simulation import Simulation\n",
}


def test_rust_cycles_are_between_sibling_subsystems_not_parents_and_children(tmp_path, capsys):
    write(tmp_path, RUST | PYTHON)
    assert module_cycles.main(["--root", str(tmp_path), "--rust"]) == 1
    out = capsys.readouterr().out
    assert "rust: import cycle: snapshot <-> stepper\n" in out
    assert "stepper::recovery uses snapshot (crate::snapshot::WatchdogSnapshot)" in out
    assert out.count("import cycle") == 1  # solver and its kernel are not one


def test_python_imports_in_functions_and_for_type_checking_are_not_cycles(tmp_path, capsys):
    write(tmp_path, RUST | PYTHON)
    assert module_cycles.main(["--root", str(tmp_path), "--python"]) == 0
    assert "python: 4 modules, no import cycles" in capsys.readouterr().out


def test_a_python_import_at_module_level_closes_a_cycle(tmp_path, capsys):
    write(tmp_path, RUST | PYTHON)
    write(tmp_path, {"python/rustcloth/simulation.py": "import rustcloth.export\n"})
    assert module_cycles.main(["--root", str(tmp_path), "--python"]) == 1
    out = capsys.readouterr().out
    assert "python: import cycle: rustcloth.export <-> rustcloth.simulation" in out


def test_this_checkout_has_no_python_cycle(capsys):
    assert module_cycles.main(["--python"]) == 0
