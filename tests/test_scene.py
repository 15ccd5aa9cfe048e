"""Scenes: construction from keywords, dicts and TOML, round trips, built-ins."""

from __future__ import annotations

import pytest
import rustcloth
from rustcloth import Scene
from rustcloth.errors import ParameterTypeError


def test_defaults_are_filled_in_and_documented_keys_exist():
    d = Scene().to_dict()
    assert set(d) == {
        "integrator", "dt", "substeps", "gravity", "air_drag", "cloth", "floor", "spheres",
        "cg_tolerance", "cg_max_iterations", "preconditioner", "pd_iterations", "pd_tolerance",
        "pd_chebyshev_rho", "watchdog", "strain_limit", "self_collision", "tearing",
        "colliders", "wind",
    }
    assert d["preconditioner"] == "multigrid" and d["pd_iterations"] == 20
    assert set(d["cloth"]) >= {
        "nx", "ny", "size", "center", "plane", "k_structural", "k_shear", "k_bend",
        "damping", "pins",
    }
    assert d["floor"] is None and d["spheres"] == [] and d["colliders"] == []
    assert d["strain_limit"] is None and d["tearing"] is None and d["wind"] is None
    assert d["watchdog"] == {
        "max_stretch": None, "on_trouble": "raise", "max_substeps": 64, "hold_steps": 100,
    }
    assert d["integrator"] == "symplectic_euler"


def test_keywords_dict_and_toml_agree_and_round_trip(tmp_path):
    kwargs = dict(
        dt=0.0005,
        substeps=2,
        gravity=[0, -9.81, 0],
        cloth={"nx": 10, "ny": 12, "plane": "xy", "mass": 0.3, "pins": ["left_edge", [3, 4]]},
        floor={"height": -0.5, "friction": 0.4},
        spheres=[{"center": [0, 0.2, 0], "radius": 0.25}],
    )
    a = Scene(**kwargs)
    b = Scene.from_dict(kwargs)
    path = tmp_path / "scene.toml"
    path.write_text(a.to_toml())
    c = Scene.from_toml(path)
    assert a == b == c
    assert Scene.from_dict(a.to_dict()) == a
    assert a.cloth["mass"] == pytest.approx(0.3) and "particle_mass" not in a.cloth
    assert a.floor["thickness"] == pytest.approx(0.002)  # default filled in


def test_replace_merges_tables():
    scene = Scene(cloth={"nx": 10, "k_bend": 3.0})
    changed = scene.replace(cloth={"nx": 20}, dt=0.002)
    assert changed.cloth["nx"] == 20 and changed.cloth["k_bend"] == 3.0 and changed.dt == 0.002
    assert scene.cloth["nx"] == 10  # the original is untouched


def test_builtin_scenes_load_and_list():
    names = rustcloth.scenes()
    assert {"hanging", "drape", "freefall"} <= set(names)
    for name in names:
        assert isinstance(rustcloth.load_scene(name), Scene)
    drape = rustcloth.load_scene("drape")
    assert drape.floor is not None and len(drape.spheres) == 1


def test_unknown_builtin_scene_lists_the_available_ones():
    with pytest.raises(ValueError, match="hanging"):
        rustcloth.load_scene("nope")


def test_numpy_values_are_accepted():
    import numpy as np

    scene = Scene(gravity=np.array([0.0, -3.0, 0.0]), dt=np.float32(0.002))
    assert scene.gravity == [0.0, -3.0, 0.0]
    assert scene.dt == pytest.approx(0.002)


def test_from_toml_str_of_something_not_text_names_the_parameter():
    # The text is read for mesh collider paths before the core sees it: that reading must
    # refuse what is not text as the core does, with ParameterTypeError naming it.
    for value in (None, 3, b"dt = 0.01"):
        with pytest.raises(ParameterTypeError, match="text"):
            Scene.from_toml_str(value)  # type: ignore[arg-type]


@pytest.mark.parametrize(("particle", "vertex"), [(16, 4), (-1, -1), (2**40, 2**40)])
def test_a_pin_index_outside_the_cloth_is_refused_in_one_wording_for_grid_and_mesh(
    particle, vertex
):
    # The grid's particles and a mesh cloth's vertices are refused by one check in one
    # sentence, which gives the valid range (the mesh's other refusal once ran 18 spaces into
    # its sentence).
    with pytest.raises(rustcloth.ParameterError) as grid:
        Scene(cloth={"nx": 4, "ny": 4, "pins": [particle]})
    assert grid.value.parameter == "cloth.pins[0]"
    assert str(grid.value) == (
        f"cloth.pins[0]: particle {particle} is outside the 4 x 4 grid (0 to 15)")
    vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]
    triangles = [[0, 1, 2], [1, 3, 2]]
    with pytest.raises(rustcloth.ParameterError) as mesh:
        Scene().with_cloth_mesh(vertices, triangles, pins=[vertex])
    assert mesh.value.parameter == "cloth.pins[0]"
    assert str(mesh.value) == (
        f"cloth.pins[0]: vertex {vertex} is outside the mesh's 4 vertices (0 to 3)")
    with pytest.raises(rustcloth.ParameterError, match=r"vertex index \(3\), box") as named:
        Scene().with_cloth_mesh(vertices, triangles, pins=["top_edge"])
    assert "  " not in str(named.value)
