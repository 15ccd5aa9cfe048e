"""benches/self_collision.py measures the scenes as they ship, and its frames without the pass
are the same frames as with it: what docs/contact.md's cost table rests on. Its table of the
scenes, benches/scene_self_collision.py, tries a variant of them with ``--set`` without editing
their files: the same change in the runs without and with the pass, the ``self_collision`` keys
in the run with it only, and a change inside a table keeps the table's other keys."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import rustcloth

BENCHES = Path(__file__).resolve().parent.parent / "benches"
# The bench puts benches/ and benches/peers/ first on the path for its own imports; they are
# taken off again so that their module names cannot shadow another test's imports.
_path = list(sys.path)
sys.path.insert(0, str(BENCHES))
try:
    bench = pytest.importorskip("self_collision")
    scenes_bench = pytest.importorskip("scene_self_collision")
finally:
    sys.path[:] = _path


@pytest.mark.parametrize("name", ["twist", "pile"])
def test_the_cost_table_times_each_scene_at_its_shipped_integrator_and_step(name: str) -> None:
    base = rustcloth.load_scene(name)
    scene = bench.shipped(name, 64)
    assert (scene.integrator, scene.dt, scene.substeps) == (base.integrator, base.dt,
                                                            base.substeps)
    assert scene.self_collision["solve_stiffness"] == base.self_collision["solve_stiffness"]
    assert (scene.cloth["nx"], scene.cloth["ny"]) == (64, 64)


def test_the_contact_thickness_stays_under_half_the_grid_spacing_of_a_fine_cloth() -> None:
    scene = bench.shipped("twist", 256)
    spacing = scene.cloth["size"][0] / 255
    assert scene.self_collision["thickness"] == pytest.approx(0.4 * spacing)
    assert bench.shipped("twist", 64).self_collision["thickness"] == bench.THICKNESS


def test_the_frames_without_the_pass_cover_the_same_simulated_time_from_the_same_state() -> None:
    r = bench.measure(bench.shipped("pile", 12), None, 0.05, 2, rounds=2)
    assert (r["without_from"], r["without_to"]) == (r["from"], r["to"])
    assert r["to"] - r["from"] == pytest.approx(2 / 60)
    assert r["crossings"] == 0
    assert r["wall"] > 0 and r["without_wall"] > 0 and r["cpu"] >= 0
    assert r["ratio_wall"] == pytest.approx(r["wall"] / r["without_wall"])


def test_the_frames_with_and_without_the_pass_alternate_in_one_window(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # Timed one after the other, the two columns would take a shared machine's drift between
    # them: each round warms both from one state, then times them in turn, the side that goes
    # first swapping from round to round.
    order: list[bool] = []
    frame = bench.frame

    def logged(sim: rustcloth.Simulation, driver: object) -> tuple[float, float]:
        order.append(sim.self_collision is not None)
        return frame(sim, None)

    monkeypatch.setattr(bench, "frame", logged)
    sim = rustcloth.Simulation(bench.shipped("pile", 12))
    runs = bench.alternated(sim.get_state(), None, frames=2, rounds=2)
    warm = [True, False]
    assert order == [*warm, True, False, True, False, *warm, False, True, False, True]
    assert all(len(runs["best"][side][key]) == 2 for side in (True, False)
               for key in ("wall", "cpu"))


def test_set_reads_numbers_fractions_and_names_into_nested_tables() -> None:
    changes = scenes_bench.settings(["integrator=implicit_euler", "dt=1/120", "substeps=1",
                                     "cloth.damping=0.1", "self_collision.solve_stiffness=30"])
    assert changes == {"integrator": "implicit_euler", "dt": pytest.approx(1 / 120),
                       "substeps": 1, "cloth": {"damping": 0.1},
                       "self_collision": {"solve_stiffness": 30}}
    with pytest.raises(SystemExit, match="KEY=VALUE"):
        scenes_bench.settings(["dt"])


def test_a_variant_changes_both_runs_and_the_pass_only_in_the_run_with_it() -> None:
    changes = scenes_bench.settings(["integrator=implicit_euler", "dt=1/120", "cloth.damping=0.1",
                                     "self_collision.solve_stiffness=30"])
    base = rustcloth.load_scene("curtain")
    for with_pass in (False, True):
        scene = scenes_bench.variant("curtain", with_pass, changes)
        assert (scene.integrator, scene.dt) == ("implicit_euler", pytest.approx(1 / 120))
        assert scene.cloth["damping"] == 0.1 and scene.cloth["nx"] == base.cloth["nx"]
        assert scene.wind == base.wind
    assert scenes_bench.variant("curtain", False, changes).self_collision is None
    spec = scenes_bench.variant("curtain", True, changes).self_collision
    assert spec is not None and spec["solve_stiffness"] == 30.0
    assert spec["thickness"] == pytest.approx(scenes_bench.THICKNESS)
    # Without --set a scene runs as shipped, its own [self_collision] kept.
    assert scenes_bench.variant("fold", True) == rustcloth.load_scene("fold")


def test_a_change_inside_a_mesh_cloth_keeps_its_mesh() -> None:
    changes = scenes_bench.settings(["cloth.mesh.damping=0.2"])
    scene = scenes_bench.variant("flag_hole", False, changes)
    mesh, base = scene.cloth["mesh"], rustcloth.load_scene("flag_hole").cloth["mesh"]
    assert mesh["damping"] == 0.2 and len(mesh["vertices"]) == len(base["vertices"])
