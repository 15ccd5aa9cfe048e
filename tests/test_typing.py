"""The public API's types agree with what it returns at run time. `make lint` runs
`mypy --strict tests/typecheck`, a user's script over the whole API; here it runs for real, and
the literal and the TypedDicts are checked against the compiled module's lists and dicts."""

from __future__ import annotations

import ast
import inspect
import runpy
import sys
import textwrap
import typing
from pathlib import Path

import pytest
import rustcloth
from rustcloth import _core, settings

USER_SCRIPT = Path(__file__).parent / "typecheck" / "user_script.py"


def test_integrator_literal_lists_every_integrator_in_order():
    # The literal left projective_dynamics out, so `sim.integrator = "projective_dynamics"`
    # was a mypy --strict error in a user's script.
    assert typing.get_args(settings.IntegratorName) == tuple(_core.INTEGRATORS)
    assert rustcloth.INTEGRATORS == tuple(_core.INTEGRATORS)


@pytest.mark.parametrize("name", rustcloth.scenes())
def test_settings_typeddicts_have_the_keys_a_scene_answers(name):
    scene = rustcloth.load_scene(name)
    # `mesh` (NotRequired) is there only on a mesh cloth (the garments), which has no
    # `particle_mass`; tests/test_mesh_cloth.py checks it.
    mesh_only = {"particle_mass"} if "mesh" in scene.cloth else set()
    assert set(scene.cloth) | {"mesh"} | mesh_only == set(settings.ClothSettings.__annotations__)
    assert set(scene.watchdog) == set(settings.WatchdogSettings.__annotations__)
    for key, kind in (("floor", settings.FloorSettings),
                      ("strain_limit", settings.StrainLimitSettings),
                      ("self_collision", settings.SelfCollisionSettings),
                      ("tearing", settings.TearingSettings)):
        table = getattr(scene, key)
        assert table is None or set(table) == set(kind.__annotations__), key
    for sphere in scene.spheres:
        assert set(sphere) == set(settings.SphereSettings.__annotations__)


def test_scene_declares_every_key_it_answers():
    # Scene answers its keys through __getattr__ (Any to a type checker); the class declares
    # them under TYPE_CHECKING, and that list must not fall behind the schema.
    tree = ast.parse(textwrap.dedent(inspect.getsource(rustcloth.Scene)))
    declared = {node.target.id for node in ast.walk(tree)
                if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                and not node.target.id.startswith("_")}
    assert declared == set(rustcloth.load_scene("hanging").to_dict())


def test_the_typed_user_script_runs(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", [str(USER_SCRIPT)])
    runpy.run_path(str(USER_SCRIPT), run_name="__main__")
