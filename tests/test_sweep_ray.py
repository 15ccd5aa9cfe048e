"""The Ray backend on a real local Ray (started once for the module, ``num_cpus=2``): the same bits
as a serial loop and as the local backend, failures recorded, time limits enforced by
cancelling the task."""

from __future__ import annotations

import os
import time

import pytest
from rustcloth.sweep import FunctionRef, run_sweep
from sweep_helpers import FUNCTIONS, assert_matches_serial, failing_sweep, small_sweep

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'rustcloth[ray]')")

# One process runs the whole module under pytest-xdist, so one local cluster serves it, as
# without xdist: a cluster per worker would cost its start-up twice and share two CPUs.
pytestmark = pytest.mark.xdist_group("ray")


@pytest.fixture(scope="module")
def local_ray():
    try:
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    except Exception as err:  # noqa: BLE001 - any failure to start is a reason to skip
        pytest.skip(f"Ray cannot start on this machine: {type(err).__name__}: {err}")
    yield ray
    ray.shutdown()


def by_path(name: str) -> FunctionRef:
    # Ray workers do not have tests/ on their path: they load the function from its file.
    return FunctionRef(f"{FUNCTIONS}:{name}")


@pytest.mark.parametrize("threads", [1, 2])
def test_ray_sweep_is_bitwise_the_serial_loop_and_the_local_backend(local_ray, tmp_path,
                                                                   threads):
    sweep = small_sweep(functions={"lowest": by_path("lowest_point")})
    result = run_sweep(sweep, tmp_path / "ray", "ray", threads=threads)
    assert result.counts == {"ok": 6}
    assert result.backend == f"ray: {2 // threads} task(s) at a time x {threads} thread(s)"
    assert_matches_serial(result, sweep.expand())
    # RAYON_NUM_THREADS reached the task through its runtime_env, before its first step.
    assert {r["threads"] for r in result.records} == {threads}
    local = run_sweep(sweep, tmp_path / "local", workers=2, threads=1)
    for a, b in zip(result.records, local.records, strict=True):
        x, y = result.load(a), local.load(b)
        assert set(x) == set(y)
        assert all((x[k] == y[k]).all() for k in x if k != "meta")
    # Ray was started by the test, so the sweep leaves it running.
    assert ray.is_initialized()


def test_ray_records_a_diverging_and_a_raising_run_and_goes_on(local_ray, tmp_path):
    sweep = failing_sweep(by_path("fragile"))
    result = run_sweep(sweep, tmp_path, "ray")
    assert [r["status"] for r in result.records] == ["ok", "diverged", "error", "ok"]
    assert "too large for this probe" in result.records[2]["reason"]
    assert_matches_serial(result, sweep.expand())


def test_ray_cancels_a_stuck_task_at_its_time_limit(local_ray, tmp_path):
    from rustcloth.sweep.ray_backend import RayBackend

    sweep = small_sweep(functions={"stuck": by_path("stuck_when_soft")}, time_limit=5.0)
    start = time.monotonic()
    result = run_sweep(sweep, tmp_path, RayBackend(grace=0.5))
    assert time.monotonic() - start < 120  # not the 600 s the stuck function sleeps
    assert [r["status"] for r in result.records] == ["timeout"] * 2 + ["ok"] * 4, \
        [r["reason"] for r in result.records]
    assert "cancelled after" in result.records[0]["reason"]
    assert not os.path.exists(tmp_path / "runs" / f"{result.records[0]['run_id']}.npz")


def test_ray_records_a_task_whose_worker_dies_and_goes_on(local_ray, tmp_path):
    sweep = small_sweep(functions={"crash": by_path("crash_when_soft")})
    result = run_sweep(sweep, tmp_path, "ray")
    assert [r["status"] for r in result.records] == ["crashed"] * 2 + ["ok"] * 4
    assert result.records[0]["reason"].startswith(("WorkerCrashedError", "RayTaskError"))
