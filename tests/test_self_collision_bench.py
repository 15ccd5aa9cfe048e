"""benches/self_collision.py measures the scenes as they ship, and its frames without the pass
are the same frames as with it: what docs/contact.md's cost table rests on."""

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
    r = bench.measure(bench.shipped("pile", 12), None, 0.05, 2)
    assert (r["without_from"], r["without_to"]) == (r["from"], r["to"])
    assert r["to"] - r["from"] == pytest.approx(2 / 60)
    assert r["crossings"] == 0
    assert r["wall"] > 0 and r["without_wall"] > 0 and r["cpu"] >= 0
    assert r["ratio_wall"] == pytest.approx(r["wall"] / r["without_wall"])
