"""The local backend: the same bits as a serial loop for any worker count and order, failures
recorded rather than fatal, time limits, crashes, filters, and resuming after a real kill."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import sweep_functions as fn
from conftest import small_scene
from rustcloth.sweep import Filters, Record, Sweep, SweepError, read_index, run_sweep
from rustcloth.sweep.local import LocalBackend
from rustcloth.sweep.store import Store
from sweep_helpers import assert_matches_serial, failing_sweep, small_sweep


@pytest.mark.parametrize(("workers", "threads"), [(2, 1), (1, 2)])
def test_local_sweep_is_bitwise_the_serial_loop(tmp_path, workers, threads):
    sweep = small_sweep()
    result = run_sweep(sweep, tmp_path, workers=workers, threads=threads)
    assert result.counts == {"ok": 6}
    assert_matches_serial(result, sweep.expand())
    # Each worker's rayon pool has the size it was given (as rayon reports it, not assumed).
    assert {r["threads"] for r in result.records} == {threads}
    assert result.backend == f"local: {workers} worker(s) x {threads} thread(s)"


def test_a_workers_thread_count_is_its_pools_size_while_other_threads_start():
    # A Ray worker starts threads of its own while its first run starts; the reported size of
    # the rayon pool must be rayon's, not a count of whatever threads appeared meanwhile.
    code = """
import threading, time
from rustcloth.sweep import rayon_threads
stop = threading.Event()
def churn():
    while not stop.is_set():
        ts = [threading.Thread(target=time.sleep, args=(0.05,)) for _ in range(4)]
        for t in ts: t.start()
        for t in ts: t.join()
threading.Thread(target=churn, daemon=True).start()
time.sleep(0.05)
print(rayon_threads())
stop.set()
"""
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=60, check=True)
    assert out.stdout.split() == ["1"]


def test_order_does_not_change_any_result(tmp_path):
    runs = small_sweep().expand()
    forward = run_sweep(runs, tmp_path / "forward", workers=2, threads=1)
    backward = run_sweep(runs[::-1], tmp_path / "backward", workers=2, threads=1)
    for a, b in zip(forward.records, sorted(backward.records, key=lambda r: r["run"]),
                    strict=True):
        assert a["run_id"] == b["run_id"]
        x, y = forward.load(a), backward.load(b)
        assert all(np.array_equal(x[k], y[k]) for k in x if k != "meta")


def test_the_folder_holds_one_npz_per_run_and_an_index(tmp_path):
    result = run_sweep(small_sweep(), tmp_path, workers=2, threads=1)
    files = sorted(os.listdir(tmp_path / "runs"))
    assert len([f for f in files if f.endswith(".npz")]) == 6
    assert len([f for f in files if f.endswith(".json")]) == 6
    assert not [f for f in files if f.startswith(".tmp-")]
    index = (tmp_path / "index.csv").read_text().splitlines()
    assert index[0].split(",")[:4] == ["run", "run_id", "cloth.k_bend", "cloth.damping"]
    assert len(index) == 7 and all(",ok," in line for line in index[1:])
    arrays = result.load(result.records[0])
    frames = len(range(0, 121, 25)) + 1  # steps 0, 25, ..., 100 and the last, 120
    assert arrays["steps"].tolist() == [0, 25, 50, 75, 100, 120]
    assert arrays["positions"].shape == (frames, 48, 3)
    assert arrays["energy"].shape == (frames, 3) and arrays["lowest"].shape == (frames,)
    assert arrays["triangles"].dtype == np.uint32 and arrays["final_positions"].shape == (48, 3)
    assert [r["status"] for r in read_index(tmp_path)] == ["ok"] * 6


def test_rerunning_a_finished_sweep_runs_nothing(tmp_path):
    first = run_sweep(small_sweep(), tmp_path, workers=2, threads=1)
    again = run_sweep(small_sweep(), tmp_path, workers=2, threads=1)
    assert (again.ran, again.skipped) == (0, 6)
    assert [r["run_id"] for r in again.records] == [r["run_id"] for r in first.records]
    # A larger grid runs only what is new.
    bigger = small_sweep(grid={"cloth.k_bend": [2.0, 15.0, 60.0, 100.0],
                               "cloth.damping": [0.01, 0.05]})
    grown = run_sweep(bigger, tmp_path, workers=2, threads=1)
    assert (grown.ran, grown.skipped) == (2, 6)


def test_two_sweeps_cannot_write_one_folder_at_once(tmp_path):
    with Store(tmp_path).lock():  # as a sweep running in another process holds it
        with pytest.raises(SweepError, match="another sweep is writing to"):
            run_sweep(small_sweep(), tmp_path, workers=1)
    assert run_sweep(small_sweep(), tmp_path, workers=1).counts == {"ok": 6}


def test_a_diverging_and_a_raising_run_are_recorded_and_the_sweep_goes_on(tmp_path):
    sweep = failing_sweep(fn.fragile)
    result = run_sweep(sweep, tmp_path, workers=2, threads=1)
    statuses = [r["status"] for r in result.records]
    assert statuses == ["ok", "diverged", "error", "ok"]
    assert result.records[1]["reason"].startswith("overstretched at step ")
    assert "too large for this probe" in result.records[2]["reason"]
    assert "ValueError" in result.records[2]["traceback"]
    assert not os.path.exists(tmp_path / "runs" / f"{result.records[1]['run_id']}.npz")
    assert_matches_serial(result, sweep.expand())
    # Deterministic failures are complete: a rerun keeps them, unless asked to retry them.
    assert run_sweep(sweep, tmp_path, workers=2, threads=1).ran == 0
    assert run_sweep(sweep, tmp_path, workers=2, threads=1, retry_failed=True).ran == 2


def test_a_run_over_its_time_limit_is_stopped_and_recorded(tmp_path):
    long_runs = Sweep(base=small_scene(cloth={"nx": 32, "ny": 32}),
                      grid={"cloth.k_bend": [10.0, 20.0]}, steps=10_000_000, time_limit=3.0,
                      record=Record())
    short = small_sweep()
    runs = long_runs.expand() + short.expand()
    result = run_sweep(runs, tmp_path, workers=2, threads=1)
    assert [r["status"] for r in result.records[:2]] == ["timeout", "timeout"]
    assert "over the 3 s time limit at step" in result.records[0]["reason"]
    assert [r["status"] for r in result.records[2:]] == ["ok"] * 6


def test_a_stuck_run_is_killed_with_its_worker_and_the_sweep_goes_on(tmp_path):
    sweep = small_sweep(functions={"stuck": fn.stuck_when_soft}, time_limit=5.0)
    backend = LocalBackend(workers=2, threads=1, grace=0.3)
    start = time.monotonic()
    result = run_sweep(sweep, tmp_path, backend)
    assert time.monotonic() - start < 60  # not the 600 s the stuck function sleeps
    statuses = [(r["params"]["cloth.k_bend"], r["status"]) for r in result.records]
    assert statuses == [(2.0, "timeout"), (2.0, "timeout"), (15.0, "ok"), (15.0, "ok"),
                        (60.0, "ok"), (60.0, "ok")]
    assert "killed after" in result.records[0]["reason"]
    # Not complete: a rerun tries the timed-out runs again.
    again = run_sweep(sweep, tmp_path, backend)
    assert (again.ran, again.skipped) == (2, 4)


def test_a_crashing_worker_is_recorded_and_replaced(tmp_path):
    sweep = small_sweep(functions={"crash": fn.crash_when_soft})
    result = run_sweep(sweep, tmp_path, workers=2, threads=1)
    statuses = [r["status"] for r in result.records]
    assert statuses == ["crashed", "crashed", "ok", "ok", "ok", "ok"]
    assert result.records[0]["reason"] == "worker killed by SIGKILL"


def test_a_quality_filter_drops_overstretched_runs(tmp_path):
    sweep = small_sweep(filters=Filters(max_stretch=0.024))
    result = run_sweep(sweep, tmp_path, workers=2, threads=1)
    peaks = [r["peak_stretch"] for r in result.records]
    for record, peak in zip(result.records, peaks, strict=True):
        assert record["status"] == ("filtered" if peak > 0.024 else "ok")
        assert os.path.exists(tmp_path / "runs" / f"{record['run_id']}.npz") == (peak <= 0.024)
    assert 0 < sum(p > 0.024 for p in peaks) < len(peaks), peaks  # the bound splits the runs


def test_a_reject_function_drops_the_runs_it_names(tmp_path):
    sweep = small_sweep(filters=Filters(reject=fn.reject_high))
    result = run_sweep(sweep, tmp_path, workers=2, threads=1)
    statuses = [(r["params"]["cloth.k_bend"], r["status"]) for r in result.records]
    assert statuses == [(2.0, "ok"), (2.0, "ok"), (15.0, "filtered"), (15.0, "ok"),
                        (60.0, "filtered"), (60.0, "ok")]
    assert result.records[2]["reason"] == "lowest point 0.74945 m is above 0.7494 m"
    assert_matches_serial(result, sweep.expand())


SWEEP_TOML = """
base = "hanging"
steps = 6000
[grid]
"cloth.k_bend" = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0]
[record]
every = 1000
"""


def records(folder) -> set[str]:
    """Run ids with a record in place (a temporary file is not one)."""
    return {f[:-5] for f in os.listdir(folder) if f.endswith(".json") and not f.startswith(".")}


def test_resume_after_killing_the_sweep_midway_completes_with_the_same_results(tmp_path):
    sweep_file = tmp_path / "sweep.toml"
    sweep_file.write_text(SWEEP_TOML)
    out = tmp_path / "out"
    command = [sys.executable, "-c",
               "import sys, rustcloth.sweep as s; sys.exit(s.main(sys.argv[1:]))",
               str(sweep_file), "--out", str(out), "--workers", "2", "--threads", "1",
               "--progress", "none"]
    driver = subprocess.Popen(command, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    records_dir = out / "runs"
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            done = records(records_dir) if records_dir.exists() else set()
            if len(done) >= 2 or driver.poll() is not None:
                break
            time.sleep(0.01)
        os.killpg(driver.pid, signal.SIGKILL)  # the driver and its workers, mid-run
    finally:
        driver.wait()
    assert driver.returncode == -signal.SIGKILL
    finished = records(records_dir)
    assert 2 <= len(finished) < 10, "the kill came too late to be midway"
    sweep = Sweep.from_toml(sweep_file)
    resumed = run_sweep(sweep, out, workers=2, threads=1)
    assert resumed.skipped == len(finished) and resumed.ran == 10 - len(finished)
    assert resumed.counts == {"ok": 10}
    assert not [f for f in os.listdir(records_dir) if f.startswith(".tmp-")]
    assert_matches_serial(resumed, sweep.expand())
    index = read_index(out)
    assert [r["status"] for r in index] == ["ok"] * 10
    assert json.loads((out / "sweep.json").read_text())["steps"] == 6000
