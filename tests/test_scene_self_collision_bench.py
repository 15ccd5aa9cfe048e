"""benches/scene_self_collision.py's ``--set`` tries a variant of the scenes without editing
their files: the same change in the runs without and with the pass, the ``self_collision``
keys in the run with it only, and a change inside a table keeps the table's other keys."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import rustcloth

BENCHES = Path(__file__).resolve().parent.parent / "benches"
# The bench puts benches/peers/ first on the path for its own imports; the path is restored
# so that its module names cannot shadow another test's imports.
_path = list(sys.path)
sys.path.insert(0, str(BENCHES))
try:
    bench = pytest.importorskip("scene_self_collision")
finally:
    sys.path[:] = _path


def test_set_reads_numbers_fractions_and_names_into_nested_tables() -> None:
    changes = bench.settings(["integrator=implicit_euler", "dt=1/120", "substeps=1",
                              "cloth.damping=0.1", "self_collision.solve_stiffness=30"])
    assert changes == {"integrator": "implicit_euler", "dt": pytest.approx(1 / 120),
                       "substeps": 1, "cloth": {"damping": 0.1},
                       "self_collision": {"solve_stiffness": 30}}
    with pytest.raises(SystemExit, match="KEY=VALUE"):
        bench.settings(["dt"])


def test_a_variant_changes_both_runs_and_the_pass_only_in_the_run_with_it() -> None:
    changes = bench.settings(["integrator=implicit_euler", "dt=1/120", "cloth.damping=0.1",
                              "self_collision.solve_stiffness=30"])
    base = rustcloth.load_scene("curtain")
    for with_pass in (False, True):
        scene = bench.variant("curtain", with_pass, changes)
        assert (scene.integrator, scene.dt) == ("implicit_euler", pytest.approx(1 / 120))
        assert scene.cloth["damping"] == 0.1 and scene.cloth["nx"] == base.cloth["nx"]
        assert scene.wind == base.wind
    assert bench.variant("curtain", False, changes).self_collision is None
    spec = bench.variant("curtain", True, changes).self_collision
    assert spec is not None and spec["solve_stiffness"] == 30.0
    assert spec["thickness"] == pytest.approx(bench.THICKNESS)
    # Without --set a scene runs as shipped, its own [self_collision] kept.
    assert bench.variant("fold", True) == rustcloth.load_scene("fold")


def test_a_change_inside_a_mesh_cloth_keeps_its_mesh() -> None:
    scene = bench.variant("flag_hole", False, bench.settings(["cloth.mesh.damping=0.2"]))
    mesh, base = scene.cloth["mesh"], rustcloth.load_scene("flag_hole").cloth["mesh"]
    assert mesh["damping"] == 0.2 and len(mesh["vertices"]) == len(base["vertices"])
