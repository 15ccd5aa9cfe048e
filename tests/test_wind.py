"""Wind from Python: the ``[wind]`` table, its pass, its errors (the physics is tested in
tests/wind.rs)."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth
from rustcloth import Scene
from rustcloth.errors import ParameterError


def _curtain(**wind: object) -> Scene:
    return Scene(
        cloth={"nx": 12, "ny": 12, "plane": "xy", "size": [0.6, 0.6], "mass": 0.15,
               "center": [0.0, 1.0, 0.0], "pins": ["top_edge"]},
        substeps=2,
        wind=wind or None,
    )


def test_wind_deflects_a_hanging_cloth_downwind_and_its_absence_changes_nothing():
    still = rustcloth.Simulation(_curtain())
    windy = rustcloth.Simulation(_curtain(velocity=[0.0, 0.0, 3.0], gust=0.0, turbulence=0.0))
    assert "wind" in windy.effects and "wind" not in still.effects
    still.step(800)
    windy.step(800)
    assert abs(still.positions[:, 2]).max() < 1e-6
    assert windy.positions[:, 2].mean() > 0.02
    assert windy.scene.wind is not None and windy.scene.wind["drag"] == pytest.approx(1.2)
    assert "wind" in windy.profile().passes


def test_the_flag_scene_blows_and_round_trips():
    scene = rustcloth.load_scene("flag")
    assert scene.wind is not None and scene.wind["seed"] == 7
    assert Scene.from_toml_str(scene.to_toml()) == scene
    sim = rustcloth.Simulation(scene)
    sim.step(200)
    assert np.isfinite(sim.positions).all()


@pytest.mark.parametrize(
    ("key", "value"),
    [("gust", 2.0), ("gust_period", 0.0), ("turbulence", -1.0), ("air_density", 0.0),
     ("velocity", [1e9, 0.0, 0.0]), ("seed", -1)],
)
def test_bad_wind_settings_are_named(key, value):
    with pytest.raises(ParameterError, match=f"wind.{key}"):
        _curtain(**{key: value})
