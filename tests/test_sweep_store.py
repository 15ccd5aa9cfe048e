"""The sweep's output folder: a run's record, the file a resumed sweep trusts, never exists
without the arrays it points to.

A test that killed a sweep at a random moment caught a record written before its ``.npz`` in
5 of 16 runs; these tests stop the store between its two writes on purpose, every time.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from rustcloth.sweep import RunResult, store
from rustcloth.sweep.store import Store
from sweep_helpers import small_sweep


class Stop(Exception):
    """The process dies here."""


@pytest.fixture
def finished():
    """A run and an ``ok`` result for it (small arrays; no simulation needed)."""
    run = small_sweep().expand()[0]
    arrays = {"steps": np.arange(3), "positions": np.zeros((3, 48, 3), np.float32)}
    return run, RunResult(run.run_id, "ok", arrays=arrays, info={"wall_s": 0.1})


def test_a_record_is_written_after_its_arrays(tmp_path, monkeypatch, finished):
    written = []
    real = store._atomic_write

    def watched(path, *args, **kwargs):
        real(path, *args, **kwargs)
        written.append(os.path.basename(path))

    monkeypatch.setattr(store, "_atomic_write", watched)
    run, result = finished
    Store(tmp_path).write(run, result)
    assert written == [f"{run.run_id}.npz", f"{run.run_id}.json"]


@pytest.mark.parametrize("dies_at", [".npz", ".json"])
def test_a_store_stopped_between_its_writes_leaves_no_record_without_arrays(
        tmp_path, monkeypatch, finished, dies_at):
    real = store._atomic_write

    def dying(path, *args, **kwargs):
        if path.endswith(dies_at):
            raise Stop
        real(path, *args, **kwargs)

    monkeypatch.setattr(store, "_atomic_write", dying)
    run, result = finished
    folder = Store(tmp_path)
    with pytest.raises(Stop):
        folder.write(run, result)
    # The record file itself, not read_record (which would hide an ok record without arrays).
    assert not os.path.exists(folder.record_path(run.run_id))
    assert os.path.exists(folder.npz_path(run.run_id)) == (dies_at == ".json")
    assert folder.completed([run]) == {}  # resumed, the run runs again
    assert not [f for f in os.listdir(folder.runs_dir) if f.startswith(".tmp-")]
