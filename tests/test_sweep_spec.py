"""Sweep descriptions: expansion, run ids, TOML, and every bad description rejected before any
run starts."""

from __future__ import annotations

import pytest
import rustcloth
from conftest import small_scene
from rustcloth.sweep import Record, Sweep, SweepError, run_sweep
from sweep_helpers import HERE, small_sweep


def test_grid_is_every_combination_in_order():
    runs = small_sweep().expand()
    assert [r.params for r in runs] == [
        {"cloth.k_bend": k, "cloth.damping": c} for k in (2.0, 15.0, 60.0) for c in (0.01, 0.05)
    ]
    assert [r.index for r in runs] == list(range(6))
    assert runs[3].scene["cloth"]["k_bend"] == 15.0 and runs[3].scene["cloth"]["damping"] == 0.05
    # Keys not overridden keep the base scene's values.
    assert runs[3].scene["cloth"]["nx"] == small_scene().cloth["nx"]


def test_runs_are_combined_with_the_grid():
    sweep = Sweep(base=small_scene(), runs=[{"dt": 0.001}, {"dt": 0.0005}],
                  grid={"cloth.k_bend": [1.0, 2.0]}, seconds=0.1)
    runs = sweep.expand()
    assert [(r.params["dt"], r.params["cloth.k_bend"]) for r in runs] == [
        (0.001, 1.0), (0.001, 2.0), (0.0005, 1.0), (0.0005, 2.0)]
    # seconds becomes steps of each run's own dt.
    assert [r.steps for r in runs] == [100, 100, 200, 200]


def test_nested_tables_and_dotted_keys_are_the_same_override():
    dotted = Sweep(base=small_scene(), grid={"cloth.k_bend": [3.0]}, steps=5).expand()
    nested = Sweep(base=small_scene(), grid={"cloth": {"k_bend": [3.0]}}, steps=5).expand()
    assert dotted[0].run_id == nested[0].run_id


def test_run_id_depends_on_the_run_not_on_its_place_in_the_sweep():
    forward = Sweep(base=small_scene(), grid={"cloth.k_bend": [1.0, 2.0]}, steps=5).expand()
    backward = Sweep(base=small_scene(), grid={"cloth.k_bend": [2.0, 1.0]}, steps=5).expand()
    assert forward[0].run_id == backward[1].run_id
    assert forward[0].run_id != forward[1].run_id
    longer = Sweep(base=small_scene(), grid={"cloth.k_bend": [1.0, 2.0]}, steps=6).expand()
    assert longer[0].run_id != forward[0].run_id
    more = Sweep(base=small_scene(), grid={"cloth.k_bend": [1.0]}, steps=5,
                 record=Record(every=1)).expand()
    assert more[0].run_id != forward[0].run_id


def test_list_indices_reach_into_arrays_of_tables():
    base = rustcloth.load_scene("drape")
    runs = Sweep(base=base, grid={"spheres.0.radius": [0.3, 0.4]}, steps=1).expand()
    assert [r.scene["spheres"][0]["radius"] for r in runs] == [0.3, 0.4]


def make_scene(k_bend, size=0.5):
    return small_scene(cloth={"k_bend": k_bend, "size": [size, size]})


def not_a_scene(k_bend):
    return {"cloth": {"k_bend": k_bend}}


def test_a_scene_function_gets_the_parameters_as_keywords():
    runs = Sweep(scene_fn=make_scene, grid={"k_bend": [1.0, 4.0], "size": [0.4]},
                 steps=3).expand()
    assert [r.scene["cloth"]["k_bend"] for r in runs] == [1.0, 4.0]
    assert runs[1].params == {"k_bend": 4.0, "size": 0.4}
    by_name = Sweep(scene_fn=f"{__file__}:make_scene", grid={"k_bend": [1.0, 4.0],
                                                              "size": [0.4]}, steps=3).expand()
    assert [r.scene for r in by_name] == [r.scene for r in runs]


def test_toml_gives_the_same_runs_as_python(tmp_path):
    (tmp_path / "base.toml").write_text(small_scene().to_toml())
    (tmp_path / "sweep.toml").write_text(
        'base = "base.toml"\n'
        "steps = 120\n"
        "[grid]\n"
        '"cloth.k_bend" = [2.0, 15.0, 60.0]\n'
        "[grid.cloth]\n"
        "damping = [0.01, 0.05]\n"
        "[record]\n"
        "every = 25\n"
        f'functions = {{ lowest = "{HERE}/sweep_functions.py:lowest_point" }}\n'
    )
    from_toml = Sweep.from_toml(tmp_path / "sweep.toml").expand()
    from_python = small_sweep().expand()
    assert [r.scene for r in from_toml] == [r.scene for r in from_python]
    assert [r.params for r in from_toml] == [r.params for r in from_python]
    assert [r.steps for r in from_toml] == [r.steps for r in from_python]


@pytest.mark.parametrize(
    ("changes", "error", "message"),
    [
        ({"grid": {}}, SweepError, "grid is empty"),
        ({"grid": {"cloth.k_bend": []}}, SweepError, "'cloth.k_bend' has no values"),
        ({"grid": {"cloth.k_bend": 3.0}}, SweepError, "needs a list of values"),
        ({"runs": []}, SweepError, "runs is empty"),
        ({"grid": {"cloth.k_bnd": [1.0]}}, rustcloth.ParameterError, "k_bnd"),
        ({"grid": {"clth.k_bend": [1.0]}}, rustcloth.ParameterError, "clth"),
        ({"grid": {"dt.x": [1.0]}}, SweepError, "'dt' is a float, not a table"),
        ({"grid": {"spheres.3.radius": [1.0]}}, SweepError, "not an index"),
        ({"grid": {"cloth.k_bend": [1.0, -2.0]}}, rustcloth.ParameterError, "k_bend"),
        ({"grid": {"cloth.nx": ["many"]}}, rustcloth.ParameterTypeError, "nx"),
        ({"steps": None}, SweepError, "exactly one of seconds and steps"),
        ({"seconds": 1.0}, SweepError, "exactly one of seconds and steps"),
        ({"steps": 0}, SweepError, "steps must be a positive integer"),
        ({"time_limit": -1.0}, SweepError, "time_limit"),
        ({"record": Record(every=-1)}, SweepError, "record.every"),
        ({"record": Record(functions={"positions": len})}, SweepError, "usable name"),
        ({"record": Record(functions={"f": "no_such_module:f"})}, SweepError, "cannot be loaded"),
        ({"scene_fn": make_scene}, SweepError, "exactly one of base"),
        ({"runs": [{}, {}]}, SweepError, "are the same run"),
    ],
)
def test_bad_descriptions_are_rejected_before_any_run(tmp_path, changes, error, message):
    sweep = small_sweep(**changes)
    with pytest.raises(error, match=message):
        sweep.expand()
    with pytest.raises(error, match=message):
        run_sweep(sweep, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_scene_function_that_returns_no_scene_is_rejected(tmp_path):
    sweep = Sweep(scene_fn=not_a_scene, grid={"k_bend": [1.0]}, steps=3)
    with pytest.raises(SweepError, match="returned dict, not a rustcloth.Scene"):
        run_sweep(sweep, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_function_a_worker_cannot_import_is_rejected_for_local_workers(tmp_path):
    sweep = small_sweep(functions={"lowest": lambda sim: 0.0})
    with pytest.raises(SweepError, match="cannot be sent to a worker process"):
        run_sweep(sweep, tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('base = "hanging"\nsteps = 1\nsecnds = 2\n', "unknown sweep key 'secnds'"),
        ('base = "hanging"\nsteps = 1\n[record]\nevry = 2\n', "unknown record key 'evry'"),
        ('base = "hanging"\nsteps = 1\n[filters]\nstretch = 2\n', "unknown filters key"),
        ('base = "hanging"\nsteps = [1\n', "sweep.toml"),
    ],
)
def test_bad_toml_is_rejected_naming_the_key(tmp_path, text, message):
    (tmp_path / "sweep.toml").write_text(text)
    with pytest.raises(SweepError, match=message):
        Sweep.from_toml(tmp_path / "sweep.toml").expand()
