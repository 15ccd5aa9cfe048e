"""Scaffolding shared by the sweep tests: small scenes, record functions that behave, fail,
hang or crash, and the comparison of a sweep's files with a serial loop over its runs.

The record functions live in ``sweep_functions.py``: local workers (spawned interpreters, which
get the test's sys.path) unpickle them by name; Ray workers load them by file path
(``FUNCTIONS``) because this folder is not on their path.
"""

from __future__ import annotations

import os

import numpy as np
from conftest import small_scene
from rustcloth.sweep import Filters, Record, Sweep, execute
from sweep_functions import lowest_point

HERE = os.path.dirname(os.path.abspath(__file__))
FUNCTIONS = os.path.join(HERE, "sweep_functions.py")


def small_sweep(functions=None, **changes) -> Sweep:
    """Six short runs of the 8 x 6 test cloth over k_bend and damping, frames every 25 steps."""
    values = dict(
        base=small_scene(),
        grid={"cloth.k_bend": [2.0, 15.0, 60.0], "cloth.damping": [0.01, 0.05]},
        steps=120,
        record=Record(every=25, functions=functions or {"lowest": lowest_point}),
    )
    values.update(changes)
    return Sweep(**values)


def failing_sweep(functions) -> Sweep:
    """Four runs: one that diverges (a watchdog bound the sagging cloth passes at once), one
    whose record function raises (dt = 2 ms), and two that finish."""
    return Sweep(
        base=small_scene(),
        runs=[{}, {"watchdog.max_stretch": 1.0001}, {"dt": 0.002}, {"cloth.k_bend": 30.0}],
        steps=80,
        record=Record(every=20, functions={"probe": functions}),
        filters=Filters(),
    )


def assert_matches_serial(result, runs) -> None:
    """Every ok run's arrays equal, bit for bit and dtype for dtype, those of execute() in this
    process; every run has the status execute() gives it."""
    by_id = {r["run_id"]: r for r in result.records}
    assert set(by_id) == {run.run_id for run in runs}
    for run in runs:
        expected = execute(run)
        record = by_id[run.run_id]
        assert record["status"] == expected.status, (run.params, record["reason"])
        if expected.status != "ok":
            continue
        stored = result.load(record)
        assert set(stored) - {"meta"} == set(expected.arrays)
        for key, value in expected.arrays.items():
            assert stored[key].dtype == value.dtype, key
            assert np.array_equal(stored[key], value), (run.params, key)
        assert stored["meta"]["params"] == run.params
