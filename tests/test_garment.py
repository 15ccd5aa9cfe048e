"""rustcloth.garment: the panels and seams it builds are the built-in scenes', bad panels are
refused naming them, and a sewn garment survives the scene's round trips."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth
from rustcloth import garment
from rustcloth.errors import ParameterError


@pytest.mark.parametrize("name", ["shirt", "skirt"])
def test_the_builtin_garments_are_what_the_module_builds(name):
    built = getattr(garment, name)()
    assert built == rustcloth.load_scene(name)


def test_a_garment_scene_round_trips_as_its_compiled_mesh():
    scene = garment.skirt()
    assert "garment" not in scene.cloth
    assert rustcloth.Scene.from_toml_str(scene.to_toml()) == scene
    assert rustcloth.Scene.from_dict(scene.to_dict()) == scene


def test_a_garment_takes_the_mesh_cloths_membrane_and_names_its_material_keys():
    square = garment.panel("a", [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]])
    scene = garment.scene([square], membrane="triangle", poisson=0.25)
    assert (scene.cloth["mesh"]["membrane"], scene.cloth["mesh"]["poisson"]) == ("triangle", 0.25)
    with pytest.raises(ParameterError, match=r"^cloth\.garment\.density"):
        garment.scene([square], density=0.0)
    with pytest.raises(ParameterError, match=r"^cloth\.garment\.poisson"):
        garment.scene([square], poisson=0.25)


def test_a_self_intersecting_panel_is_refused_naming_it():
    bow = garment.panel("bow", [[0, 0], [0.3, 0.3], [0.3, 0], [0, 0.3]])
    with pytest.raises(ParameterError, match=r"cloth\.garment\.panels\[0\]\.outline.*itself"):
        garment.scene([bow])


def test_seams_of_very_different_lengths_are_refused_naming_the_seam():
    a = garment.panel("a", [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]], edges={"r": [1, 2]})
    b = garment.panel("b", [[0, 0], [0.3, 0], [0.3, 0.9], [0, 0.9]], edges={"l": [3, 0]},
                      origin=[0.4, 0, 0])
    with pytest.raises(ParameterError, match=r"cloth\.garment\.seams\[0\].*differ too much"):
        garment.scene([a, b], [garment.seam("a.r", "b.l")])


def test_sewing_closes_the_gap_between_two_hanging_panels():
    # Two panels side by side, weightless, 5 cm apart: after the sewing time the seam is shut
    # and the panels' sides meet, each pair within a millimetre.
    a = garment.panel("a", [[0, 0], [0.2, 0], [0.2, 0.2], [0, 0.2]], edges={"r": [1, 2]})
    b = garment.panel("b", [[0, 0], [0.2, 0], [0.2, 0.2], [0, 0.2]], edges={"l": [3, 0]},
                      origin=[0.25, 0, 0])
    scene = garment.scene([a, b], [garment.seam("a.r", "b.l")], sew_time=0.2).replace(
        gravity=[0.0, 0.0, 0.0], substeps=6)
    sim = rustcloth.Simulation(scene)
    pairs = np.array(scene.cloth["mesh"]["seams"]["pairs"])
    x = sim.positions
    assert np.allclose(np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1), 0.05)
    sim.advance(0.5)
    x = sim.positions
    gaps = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    assert np.isfinite(gaps).all() and (gaps < 1e-3).all(), gaps.max()
    # The simulation's own measure of how far the sewing has come, in float32.
    assert sim.seam_gap() == pytest.approx(gaps.max(), abs=1e-7)
    # No outside force: the centre of mass has not moved.
    m = sim.masses
    centre = (m[:, None] * x).sum(0) / m.sum()
    assert np.allclose(centre, [0.225, 0.1, 0.0], atol=1e-5), centre


@pytest.mark.parametrize("name", ["shirt", "skirt"])
def test_a_garment_shows_its_front_material_outside(name):
    # The renderer took the front of every mesh cloth to face up at rest; a skirt's normals
    # are horizontal, the mean picked the inside, and the skirt was drawn inside out.
    pytest.importorskip("moderngl")  # rustcloth.render needs the viewer extra
    from rustcloth.render.renderer import layout_of

    sim = rustcloth.Simulation(rustcloth.load_scene(name))
    sim.advance(2.0)
    layout = layout_of(sim)
    front = sim.normals if layout.front_is_winding else -sim.normals
    # Away from the body's vertical axis (x = z = 0).
    outward = sim.positions * [1.0, 0.0, 1.0]
    away = np.einsum("ij,ij->i", front, outward) > 0.0
    assert away.mean() > 0.8, away.mean()
