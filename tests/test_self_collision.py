"""Self-collision from Python: the scene key, the pass in ``effects`` and ``profile()``, and
bad values raising ``ParameterError`` naming the parameter. The guarantee itself (no crossing
at any frame) is proved in tests/self_collision.rs by an independent checker."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import at_1ms
from rustcloth import Scene, Simulation
from rustcloth.errors import ParameterError, ParameterTypeError


def _pile(n: int = 12, **self_collision: object) -> Scene:
    return at_1ms("pile").replace(
        cloth={"nx": n, "ny": n}, self_collision=self_collision
    )


def test_the_key_fills_its_defaults_and_round_trips():
    scene = Scene(self_collision={"thickness": 0.004})
    assert scene.self_collision == {"thickness": 0.004, "friction": 0.2, "iterations": 4,
                                    "solve_stiffness": 0.0}
    assert Scene.from_toml_str(scene.to_toml()) == scene
    assert Scene().self_collision is None


def test_the_pass_runs_is_listed_and_timed():
    sim = Simulation(_pile())
    assert sim.effects[-1] == "self_collision"
    sim.step(5)
    timing = sim.profile().passes["self_collision"]
    assert timing.calls == 5 * 2  # two substeps per step
    assert np.isfinite(timing.seconds) and timing.seconds > 0.0
    plain = Simulation(_pile().replace(self_collision=None))
    assert "self_collision" not in plain.effects


def test_a_pile_stays_apart_and_finite():
    sim = Simulation(_pile(12))
    sim.step(600)
    x = sim.positions
    assert np.isfinite(x).all() and (np.abs(x) < 5.0).all()
    # The floor still holds every particle (the pass only shortens motion along its path).
    assert (x[:, 1] >= 0.003 - 1e-6).all()


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("thickness", 0.0),
        ("thickness", -1.0),
        ("thickness", float("nan")),
        ("thickness", 0.5),  # beyond half the grid spacing
        ("friction", -0.1),
        ("iterations", 0),
        ("solve_stiffness", -1.0),
        ("solve_stiffness", float("nan")),
    ],
)
def test_bad_values_name_the_parameter(key: str, value: float):
    with pytest.raises(ParameterError, match=f"self_collision.{key}") as info:
        Scene(self_collision={key: value})
    assert info.value.parameter == f"self_collision.{key}"


def test_wrong_types_and_unknown_keys_are_refused():
    with pytest.raises(ParameterTypeError, match="self_collision"):
        Scene(self_collision=3)
    with pytest.raises(ParameterError, match="unknown field"):
        Scene(self_collision={"radius": 0.1})


def test_the_pass_reports_what_it_did():
    sim = Simulation(_pile(20))
    sim.step(900)
    stats = sim.self_collision_stats()
    assert stats is not None
    assert stats["substeps"] == 1800
    assert stats["contacts"] > 0 and stats["pairs"] >= stats["contacts"]
    # Every substep used the kept list or the swept search, and the list was built far fewer
    # times than there were substeps that used it.
    listed = stats["substeps"] - stats["swept_substeps"]
    assert 0 < stats["rebuilds"] < listed
    assert 0.0 < stats["min_distance"] < 0.01
    assert Simulation(_pile().replace(self_collision=None)).self_collision_stats() is None


def test_the_stages_are_timed_and_the_search_counts_what_it_tested():
    # The split a profile of the pass needs: each stage's time (together within the pass's own
    # time), and the search's funnel: an overlapping pair needs at least one box test.
    sim = Simulation(_pile(20))
    sim.step(900)
    stats = sim.self_collision_stats()
    assert stats is not None
    assert stats["swept_substeps"] > 0
    assert stats["boxes_tested"] >= stats["candidates"] > 0
    for stage in ("search", "repulsion", "cap"):
        seconds = stats[f"{stage}_seconds"]
        assert np.isfinite(seconds) and seconds > 0.0, stage
    assert stats["redone"] > 0 or stats["redo_seconds"] == 0.0
    total = sum(stats[f"{s}_seconds"] for s in ("search", "repulsion", "cap", "redo"))
    assert total <= sim.profile().passes["self_collision"].seconds
