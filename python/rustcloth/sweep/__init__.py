"""Many simulations: parameter sweeps and datasets, on this machine's cores or a Ray cluster.

>>> from rustcloth.sweep import Sweep, Record, run_sweep
>>> sweep = Sweep(base="hanging", grid={"cloth.k_bend": [1.0, 10.0]}, seconds=0.5,
...               record=Record(every=100))
>>> result = run_sweep(sweep, "out/k_bend")            # doctest: +SKIP
>>> result.load(result.ok()[0])["positions"].shape     # doctest: +SKIP
(6, 1024, 3)

A sweep is a base scene plus overrides (``grid``, ``runs``), or a function of each run's
parameters that returns a scene; ``Sweep.from_toml("sweep.toml")`` reads the same keys. Each
run's result goes to ``OUT/runs/<run_id>.npz`` with a record beside it, and ``OUT/index.csv``
lists every run with its parameters and status. A run's arrays depend only on the run, never
on the backend, the number of workers or the order. Rerunning skips what is complete. See
docs/sweeps.md.
"""

from .cli import main
from .driver import BACKENDS, SweepResult, make_backend, run_sweep
from .runner import COMPLETE, RETRIED, STATUSES, RunResult, execute, rayon_threads
from .spec import Filters, FunctionRef, Record, Run, Sweep, SweepError
from .store import load_run, read_index

__all__ = [
    "BACKENDS",
    "COMPLETE",
    "Filters",
    "FunctionRef",
    "RETRIED",
    "Record",
    "Run",
    "RunResult",
    "STATUSES",
    "Sweep",
    "SweepError",
    "SweepResult",
    "execute",
    "load_run",
    "main",
    "make_backend",
    "rayon_threads",
    "read_index",
    "run_sweep",
]
