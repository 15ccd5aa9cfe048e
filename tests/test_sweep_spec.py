"""Sweep descriptions: expansion, run ids, TOML, and every bad description rejected before any
run starts."""

from __future__ import annotations

import os
import shutil
import tracemalloc

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
    # A sweep file loads .py files from its own folder only.
    shutil.copy(os.path.join(HERE, "sweep_functions.py"), tmp_path)
    (tmp_path / "sweep.toml").write_text(
        'base = "base.toml"\n'
        "steps = 120\n"
        "[grid]\n"
        '"cloth.k_bend" = [2.0, 15.0, 60.0]\n'
        "[grid.cloth]\n"
        "damping = [0.01, 0.05]\n"
        "[record]\n"
        "every = 25\n"
        'functions = { lowest = "sweep_functions.py:lowest_point" }\n'
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
        ({"steps": 0}, SweepError, "steps must be a whole number from 1"),
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


# -- a sweep file is code -----------------------------------------------------------------------
MARKER_MODULE = """
import pathlib
pathlib.Path(__file__).with_name("imported").write_text("yes")

def make(k_bend):
    raise AssertionError("called")
"""


def test_a_sweep_file_cannot_name_a_module_it_was_not_given(tmp_path):
    # `scene_fn = "os:system"` in a sweep file ran a shell command for each run: any module of
    # the interpreter was importable from a file the user may only have downloaded.
    (tmp_path / "sweep.toml").write_text('scene_fn = "os:system"\nsteps = 1\n'
                                         '[grid]\ncommand = ["touch pwned"]\n')
    with pytest.raises(SweepError, match="--module os"):
        Sweep.from_toml(tmp_path / "sweep.toml")
    # Named by the caller, the module is allowed (and imported only when the sweep expands).
    sweep = Sweep.from_toml(tmp_path / "sweep.toml", modules=["os"])
    assert sweep.scene_fn == "os:system"


@pytest.mark.parametrize("where", ["../elsewhere.py", "/tmp/elsewhere.py", "sub/../../x.py"])
def test_a_sweep_file_loads_py_files_only_from_its_own_folder(tmp_path, where):
    (tmp_path / "sweeps").mkdir()
    path = tmp_path / "sweeps" / "sweep.toml"
    path.write_text(f'base = "hanging"\nsteps = 1\n[filters]\nreject = "{where}:f"\n')
    with pytest.raises(SweepError, match="only from its own folder"):
        Sweep.from_toml(path)


def test_reading_a_sweep_file_imports_nothing(tmp_path):
    # Sweep.from_toml executed every file.py the description named, before anything else.
    (tmp_path / "make.py").write_text(MARKER_MODULE)
    (tmp_path / "sweep.toml").write_text('scene_fn = "make.py:make"\nsteps = 1\n'
                                         '[grid]\nk_bend = [1.0]\n')
    sweep = Sweep.from_toml(tmp_path / "sweep.toml")
    assert [p.params for p in sweep.preview()] == [{"k_bend": 1.0}]
    assert not (tmp_path / "imported").exists()
    with pytest.raises(AssertionError, match="called"):  # expanding is what imports and calls
        sweep.expand()
    assert (tmp_path / "imported").exists()


# -- bounds ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("changes", [{"steps": None, "seconds": 1e308}, {"steps": 2**70},
                                     {"steps": 10**9}])
def test_a_run_longer_than_the_step_limit_is_refused_naming_the_key(changes):
    # `seconds = 1e308` died in round() with "cannot convert float infinity to integer", and
    # `steps = 2**70` was accepted, to overflow in the core.
    sweep = Sweep(**{"base": "hanging", "steps": 1, **changes})
    key = "seconds" if "seconds" in changes else "steps"
    with pytest.raises(SweepError, match=f"^{key}"):
        sweep.expand()
    with pytest.raises(SweepError, match=f"^{key}"):
        list(sweep.preview())


def test_a_sweep_file_nested_too_deeply_is_a_sweep_error(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(SweepError, match="nested too deeply"):
        Sweep.from_toml(path)
    path.write_bytes(b'base = "\xff"\n')
    with pytest.raises(SweepError, match="sweep.toml"):
        Sweep.from_toml(path)


def _held_by_rustcloth() -> int:
    """Bytes now held that were allocated with a rustcloth frame on the stack. tracemalloc sees
    every thread: a thread left behind by an earlier test must not move a measurement."""
    mine = tracemalloc.take_snapshot().filter_traces(
        [tracemalloc.Filter(True, "*rustcloth*", all_frames=True)])
    return sum(stat.size for stat in mine.statistics("filename"))


def test_runs_are_built_one_at_a_time():
    # Expanding a sweep kept a whole scene per run (1e5 runs: 514 MB before anything ran).
    # Taking the runs one by one holds one scene at a time, whatever the size of the sweep.
    def held(n: int) -> int:
        sweep = Sweep(base="hanging", grid={"cloth.k_bend": [float(k) for k in range(1, n + 1)]},
                      steps=1)
        tracemalloc.start(8)
        try:
            for taken, _ in enumerate(sweep.iter_runs(), start=1):
                if taken == n:
                    return _held_by_rustcloth()
            raise AssertionError("fewer runs than asked")
        finally:
            tracemalloc.stop()

    # A scene held per run is about 5 KB: 500 runs would hold 2.5 MB against the 0.2 MB allowed.
    runs = 500
    small, large = held(20), held(runs)
    # The bookkeeping of run ids grows (about 100 bytes a run); the scenes must not.
    assert small > 0 and large < small + runs * 400, (small, large)


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/full"])
def test_a_device_is_not_read_as_a_sweep_file(device):
    # /dev/full and /dev/zero read zeros forever: reading one as a sweep file filled memory.
    with pytest.raises(SweepError, match="not a regular file"):
        Sweep.from_toml(device)


class _Consuming:
    """A backend that takes every run it is given and runs none. When it takes the last run it
    measures the memory still held that rustcloth's own code allocated."""

    name, threads = "consuming", 1

    def __init__(self) -> None:
        self.held_at_last_run = 0

    def describe(self) -> str:
        return self.name

    def run(self, runs):
        total = len(runs)
        for taken, _ in enumerate(runs, start=1):
            if taken == total:
                self.held_at_last_run = _held_by_rustcloth()
        yield from ()


def test_run_sweep_holds_no_scene_per_run(tmp_path):
    # run_sweep expanded the whole sweep into a list before anything ran, every run with its
    # scene: with a mesh collider in the base, megabytes per hundred runs.
    n = 12
    vertices = [[x / n, 0.0, z / n] for z in range(n + 1) for x in range(n + 1)]
    triangles = [[z * (n + 1) + x, (z + 1) * (n + 1) + x, z * (n + 1) + x + 1]
                 for z in range(n) for x in range(n)]
    base = small_scene(colliders=[{"shape": "mesh", "vertices": vertices,
                                   "triangles": triangles}])

    def held(runs: int) -> int:
        sweep = Sweep(base=base, grid={"cloth.k_bend": [float(k) for k in range(1, runs + 1)]},
                      steps=1)
        backend = _Consuming()
        tracemalloc.start(8)
        try:
            run_sweep(sweep, tmp_path / str(runs), backend)
            return backend.held_at_last_run
        finally:
            tracemalloc.stop()

    small, large = held(10), held(200)
    # Each scene is about 35 KB here; the bookkeeping kept per run is a few hundred bytes.
    assert small > 0 and large < small + 200 * 4000, (small, large)
