"""Hostile input to every entry point, and the defects an adversarial pass found with it.

The property test feeds nested, huge and crafted values to the scene constructors,
``Simulation``, ``set_state``, ``pickle.loads`` and the sweep description in a subprocess
(``hostile_worker.py``), so that a crash fails the test rather than ending the run. Every value
is either accepted or refused by the package's own error naming the parameter, and a refused
state leaves the simulation as it was.

The regression tests after it are named after what they protect; each failed before its fix:
a state nested 10,000 deep crashed the interpreter (a stack overflow converting it), a list
3,000 deep raised a bare ``RecursionError``, iteration counts up to 2^32 - 1 made one step run
for hours, a crafted watchdog hold or ``advance`` remainder made ``step(1)`` or ``advance(0)``
run for ever, Ctrl-C during a long ``sever_stroke`` was lost (and the stroke severed springs
after it), and ``memory_bytes()`` left out what a mesh collider holds.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import rustcloth
from conftest import HOSTILE_COUNTS, python_ctrl_c
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rustcloth.errors import ParameterError

WORKER = os.path.join(os.path.dirname(__file__), "hostile_worker.py")

SCENE_ENTRIES = ["Scene", "from_dict", "from_toml_str", "Simulation"]
SCENE_KEYS = ["gravity", "cloth.nx", "cloth.size", "cloth.pins", "dt", "integrator",
              "floor.height", "spheres", "colliders", "watchdog.max_substeps",
              "pd_iterations", "self_collision.iterations", "strain_limit.iterations"]
STATE_KEYS = ["scene.gravity", "scene.cloth.nx", "accumulator", "watchdog.hold",
              "watchdog.last_substeps", "steps", "targets", "positions", "scene.pd_iterations"]


def run_worker(cases: list[list[object]]) -> list[str]:
    """The outcome of each case, run in a fresh interpreter; a crash fails here, naming the
    case it came in."""
    done = subprocess.run(
        [sys.executable, WORKER], input=json.dumps(cases), capture_output=True, text=True,
        timeout=600,
    )
    lines = [line.split(" ", 1) for line in done.stdout.splitlines()]
    outcomes = {int(i): rest for i, rest in lines if rest != "started"}
    for outcome in outcomes.values():
        HOSTILE_COUNTS["tried"] += 1
        HOSTILE_COUNTS[outcome.split(" ", 1)[0].lower()] += 1
    if done.returncode != 0:
        running = max((int(i) for i, _ in lines), default=-1)
        case = cases[running] if running >= 0 else None
        pytest.fail(
            f"the worker died (exit {done.returncode}) on case {running}: {case}\n"
            f"{done.stderr[-2000:]}"
        )
    return [outcomes[i] for i in range(len(cases))]


leaves = st.sampled_from([0.0, 1.0, -1.0, "x", True])
recipes = st.one_of(
    st.tuples(st.just("nest"), st.sampled_from([1, 3, 33, 40, 3_000, 10_000, 100_000]), leaves),
    st.tuples(st.just("table"), st.sampled_from([1, 40, 5_000, 50_000])),
    st.tuples(st.just("int"), st.sampled_from(["0", "-1", str(2**31), str(2**32 - 1),
                                               str(2**63), str(2**70), str(-(2**64))])),
    st.tuples(st.just("float"), st.sampled_from(["nan", "inf", "-inf", "1e308", "-1e308",
                                                 "5e-324", "1e6", "18446744073709551616"])),
    st.tuples(st.just("list"), st.sampled_from([0, 2, 3, 4, 100_000]),
              st.sampled_from([0.0, [0.0, 0.0, 0.0], "top_edge", {}])),
    st.tuples(st.just("str"), st.sampled_from([0, 1, 1_000_000])),
    st.tuples(st.just("array"), st.sampled_from([0, 1, 3, 100])),
)
scene_cases = st.tuples(st.sampled_from(SCENE_ENTRIES), st.sampled_from(SCENE_KEYS), recipes)
state_cases = st.tuples(st.sampled_from(["set_state", "pickle"]), st.sampled_from(STATE_KEYS),
                        recipes)
sweep_cases = st.tuples(st.just("sweep"), st.sampled_from(["gravity", "cloth.nx", "dt"]), recipes)


@settings(max_examples=6, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(cases=st.lists(st.one_of(scene_cases, state_cases, sweep_cases), min_size=40,
                      max_size=40))
def test_hostile_values_are_accepted_or_refused_by_name_never_a_crash(cases):
    cases = [[entry, key, list(recipe)] for entry, key, recipe in cases]
    outcomes = run_worker(cases)
    wrong = [(case, out) for case, out in zip(cases, outcomes, strict=True)
             if out.startswith("WRONG")]
    assert not wrong, wrong[:5]


def test_every_entry_point_refuses_nesting_ten_thousand_deep_by_name():
    # Every conversion of nested input recurses per level: without one bound where input
    # enters, 10,000 levels overflow the native stack (SIGSEGV) and 3,000 Python's
    # (a bare RecursionError).
    deep = ["nest", 10_000, 0.0]
    cases = [[entry, "gravity", deep] for entry in SCENE_ENTRIES]
    cases += [["set_state", "scene.gravity", deep], ["pickle", "scene.gravity", deep],
              ["from_toml_str", "gravity", ["nest", 3_000, 0.0]],
              ["from_dict", "cloth", ["table", 5_000]]]
    outcomes = run_worker(cases)
    for case, outcome in zip(cases, outcomes, strict=True):
        assert outcome.startswith("refused Parameter"), (case, outcome)


def test_the_nesting_bound_leaves_room_for_every_scene_key():
    # A mesh collider's coordinates are the deepest values of the schema: accepted as before.
    scene = rustcloth.Scene().with_mesh_collider(
        [[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 2, 1]])
    assert len(rustcloth.Scene.from_dict(scene.to_dict()).colliders) == 1
    with pytest.raises(ParameterError, match="nest at most") as info:
        deep: object = 0.0
        for _ in range(rustcloth._core.MAX_NESTING):
            deep = [deep]
        rustcloth.Scene(gravity=deep)
    assert info.value.parameter.startswith("gravity")


@pytest.mark.parametrize("key", ["pd_iterations", "cg_max_iterations",
                                 "strain_limit.iterations", "self_collision.iterations"])
def test_iteration_counts_that_would_hold_a_step_for_hours_are_refused(key):
    # Accepted up to 2^32 - 1, and a step runs every iteration before Ctrl-C is looked at.
    table, _, name = key.rpartition(".")
    value = {name: 2**32 - 1}
    with pytest.raises(ParameterError, match="from 1 to 10000") as info:
        rustcloth.Scene(**({table: value} if table else value))
    assert info.value.parameter == key
    rustcloth.Scene(**({table: {name: 10_000}} if table else {name: 10_000}))


def _stepped() -> rustcloth.Simulation:
    sim = rustcloth.Simulation("hanging")
    sim.step(5)
    return sim


def test_a_crafted_watchdog_hold_is_refused_and_step_returns():
    # A saved state is input too: a hold of 2^31 substeps until step 1e18 would make step(1)
    # run for ever.
    sim = _stepped()
    before = pickle.dumps(sim.get_state())
    for hold in [(2**31, 10**18), (2, 10**18), (2**31, 7), (0, 7)]:
        state = sim.get_state()
        state["watchdog"]["hold"] = hold
        with pytest.raises(ParameterError) as info:
            sim.set_state(state)
        assert info.value.parameter.endswith("watchdog.hold"), hold
        assert pickle.dumps(sim.get_state()) == before
    state = sim.get_state()
    state["watchdog"]["hold"] = (4, sim.steps + 10)  # what a rescued step leaves
    sim.set_state(state)
    sim.step(1)


def test_a_crafted_advance_remainder_is_refused():
    # 2^64 s owed made every later advance() raise blaming `seconds`.
    sim = _stepped()
    state = sim.get_state()
    state["accumulator"] = 2.0**64
    with pytest.raises(ParameterError) as info:
        sim.set_state(state)
    assert info.value.parameter.endswith("accumulator")
    assert sim.advance(sim.dt) == 1


def _long_stroke(rays: int) -> np.ndarray:
    """A stroke of `rays` rays straight down across the hanging cloth (level at y = 1.5 m),
    back and forth, as an (M, 2, 3) array."""
    x = np.linspace(-0.6, 0.6, 101)
    xs = np.resize(np.concatenate([x, x[::-1]]), rays)
    origins = np.stack([xs, np.full(rays, 2.5), np.full(rays, 0.05)], axis=1)
    directions = np.tile([0.0, -1.0, 0.0], (rays, 1))
    return np.stack([origins, directions], axis=1)


def test_ctrl_c_during_a_long_sever_stroke_severs_nothing():
    # A long stroke checks for signals: Ctrl-C interrupts it, and the springs are severed only
    # if the whole stroke ran, never half of it.
    sim = rustcloth.Simulation("hanging")
    before = pickle.dumps(sim.get_state())
    stroke = _long_stroke(2_000_000)
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), 2))
    timer.start()
    started = time.perf_counter()
    try:
        with python_ctrl_c(), pytest.raises(KeyboardInterrupt):
            sim.sever_stroke(stroke)
    finally:
        timer.cancel()
    assert time.perf_counter() - started < 5.0
    assert pickle.dumps(sim.get_state()) == before
    assert sim.pieces() == 1
    # The same stroke, short, does cut the cloth in two.
    assert sim.sever_stroke(stroke[:101]) > 0
    assert sim.pieces() == 2


def test_memory_bytes_counts_what_a_mesh_collider_holds():
    # A mesh collider's triangles and trees are most of the memory a scene with one holds.
    sheet = _sheet(100)
    scene = rustcloth.load_scene("hanging")
    bare = rustcloth.Simulation(scene).memory_bytes()
    with_mesh = rustcloth.Simulation(scene.with_mesh_collider(*sheet))
    triangles = len(sheet[1])
    # At least the scene's own copy (48 bytes a triangle and its share of vertices) and
    # parry's triangles and tree.
    assert with_mesh.memory_bytes() - bare > 60 * triangles


def _sheet(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A flat n x n grid of vertices 0.5 m under the cloth, two triangles a cell, facing up."""
    u = np.linspace(-1.0, 1.0, n)
    x, z = np.meshgrid(u, u, indexing="ij")
    vertices = np.stack([x.ravel(), np.full(n * n, 0.3), z.ravel()], axis=1)
    k = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    triangles = np.concatenate([np.stack([k, k + 1, k + n], 1),
                                np.stack([k + 1, k + n + 1, k + n], 1)])
    return vertices, triangles


def test_reading_a_scene_file_that_is_no_text_file_names_the_path(tmp_path):
    # A folder, a missing file, a non-UTF-8 file and a device (which would be read for ever) are
    # the package's errors naming the path, not Python's own.
    bad = tmp_path / "latin1.toml"
    bad.write_bytes("dt = 0.001 # caf\xe9".encode("latin-1"))
    for path, kind, words in [(tmp_path, ParameterError, "is a folder"),
                              (tmp_path / "missing.toml", FileNotFoundError, "path:"),
                              (bad, ParameterError, "not UTF-8"),
                              ("/dev/zero", ParameterError, "not a regular file")]:
        with pytest.raises(kind, match=words):
            rustcloth.Scene.from_toml(path)


def test_pin_many_with_ragged_input_names_the_parameter():
    sim = rustcloth.Simulation("hanging")
    before = pickle.dumps(sim.get_state())
    with pytest.raises(ParameterError, match="indices: must be a rectangular array"):
        sim.pin_many([[1, 2], [3]])
    with pytest.raises(ParameterError, match="targets: must be a rectangular array"):
        sim.pin_many([1, 2], [[0.0, 0.0, 0.0], [1.0, 1.0]])
    assert pickle.dumps(sim.get_state()) == before
