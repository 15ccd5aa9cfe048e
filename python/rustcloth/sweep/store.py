"""The output folder: one ``runs/<run_id>.npz`` per run that ended ``ok``, one
``runs/<run_id>.json`` record per finished run (any status), ``index.csv`` over them, and
``sweep.json``, the description.

Every file is written to a temporary name in the same folder and renamed into place, so a file
that exists under its own name is complete; a run's ``.npz`` is renamed before its ``.json``,
so a record that says ``ok`` always has its arrays. The records are what a resumed sweep
trusts; the index is rebuilt from them.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import tempfile
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import IO, Any, Protocol

import numpy as np

from .runner import COMPLETE, RunResult
from .spec import Run, SweepError

RUNS = "runs"
INDEX = "index.csv"
#: Columns of the index after the parameters.
COLUMNS = ("status", "reason", "wall_s", "steps", "peak_stretch", "energy", "threads", "file")


class Keyed(Protocol):
    """What the store needs of a run to find its files and list it: a :class:`Run`, or a
    :class:`RunKey` where the run's scene need not be kept."""

    @property
    def index(self) -> int: ...
    @property
    def run_id(self) -> str: ...
    @property
    def params(self) -> dict[str, Any]: ...


@dataclass(frozen=True, slots=True)
class RunKey:
    """A run without its scene."""

    index: int
    run_id: str
    params: dict[str, Any]


def _atomic_write(path: str, write: Any, binary: bool, sync: bool = False) -> None:
    """Write through a temporary file and rename it into place. ``sync``: fsync it first, so
    that after a power cut the name never points at a file whose data was not written (a
    process that dies cannot do that harm: only the machine going down can)."""
    folder = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path), dir=folder)
    try:
        handle: IO[Any] = (os.fdopen(fd, "wb") if binary
                           else os.fdopen(fd, "w", encoding="utf-8", newline=""))
        with handle as f:
            write(f)
            if sync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


class Store:
    """The output folder of a sweep (created if missing)."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.out = os.fspath(out)
        self.runs_dir = os.path.join(self.out, RUNS)
        os.makedirs(self.runs_dir, exist_ok=True)
        self._index_written = 0.0

    def lock(self) -> Any:
        """Hold ``OUT/.lock`` for as long as the returned file stays open: a second sweep into
        the same folder at the same time fails at once instead of mixing its files with this
        one's (on Linux and macOS; elsewhere nothing is locked)."""
        f = open(os.path.join(self.out, ".lock"), "w")  # closed by the caller
        try:
            import fcntl

            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:
            pass
        except OSError:
            f.close()
            raise SweepError(f"another sweep is writing to {self.out}; wait for it to finish "
                             "or use another folder") from None
        return f

    def npz_path(self, run_id: str) -> str:
        return os.path.join(self.runs_dir, run_id + ".npz")

    def record_path(self, run_id: str) -> str:
        return os.path.join(self.runs_dir, run_id + ".json")

    def clean(self) -> int:
        """Remove temporary files a killed sweep left; returns how many."""
        removed = 0
        for name in os.listdir(self.runs_dir):
            if name.startswith(".tmp-"):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(self.runs_dir, name))
                    removed += 1
        return removed

    def write_description(self, description: dict[str, Any]) -> None:
        _atomic_write(os.path.join(self.out, "sweep.json"),
                      lambda f: json.dump(description, f, indent=1, default=_json_value),
                      binary=False)

    def read_record(self, run_id: str) -> dict[str, Any] | None:
        """The run's record if it is complete on disk (an ``ok`` record with its arrays)."""
        try:
            with open(self.record_path(run_id), encoding="utf-8") as f:
                record: dict[str, Any] = json.load(f)
        except (OSError, ValueError):
            return None
        if record.get("status") == "ok" and not os.path.exists(self.npz_path(run_id)):
            return None
        return record

    def completed(self, runs: Sequence[Keyed],
                  retry_failed: bool = False) -> dict[str, dict[str, Any]]:
        """Records of the runs that need not run again: those that ended ``ok`` or
        ``filtered``, and (unless ``retry_failed``) ``diverged`` or ``error``."""
        keep = ("ok", "filtered") if retry_failed else COMPLETE
        done = {}
        for run in runs:
            record = self.read_record(run.run_id)
            if record is not None and record.get("status") in keep:
                done[run.run_id] = record
        return done

    def write(self, run: Run, result: RunResult) -> dict[str, Any]:
        """Store a finished run: its arrays (status ``ok``), then its record. Returns the
        record."""
        file = ""
        if result.status == "ok":
            meta = {"run_id": run.run_id, "params": run.params, "scene": run.scene,
                    "steps": run.steps}
            arrays = dict(result.arrays)
            arrays["meta"] = np.asarray(json.dumps(meta, sort_keys=True))
            _atomic_write(self.npz_path(run.run_id), lambda f: np.savez(f, **arrays),  # type: ignore[arg-type]
                          binary=True, sync=True)
            file = os.path.join(RUNS, run.run_id + ".npz")
        record = {
            "run": run.index,
            "run_id": run.run_id,
            "params": run.params,
            "status": result.status,
            "reason": result.reason,
            "file": file,
            **{k: v for k, v in result.info.items() if k not in ("reason", "status")},
        }
        # Not synced: a record lost or torn by a power cut reads as missing, and the run is
        # simply run again.
        _atomic_write(self.record_path(run.run_id),
                      lambda f: json.dump(record, f, indent=1, sort_keys=True), binary=False)
        return record

    def write_index(self, runs: Sequence[Keyed], records: dict[str, dict[str, Any]],
                    every: float = 0.0) -> None:
        """Rewrite ``index.csv``: one row per run in sweep order, with its parameters and
        its status (``pending`` for a run without a record). With ``every``, only if the last
        rewrite is that many seconds old."""
        now = time.monotonic()
        if every and now - self._index_written < every:
            return
        self._index_written = now
        keys: list[str] = []
        for run in runs:
            keys.extend(k for k in run.params if k not in keys)
        rows = []
        for run in runs:
            record = records.get(run.run_id, {"status": "pending"})
            row = {"run": run.index, "run_id": run.run_id}
            row.update({k: _cell(run.params.get(k, "")) for k in keys})
            row.update({k: _cell(record.get(k, "")) for k in COLUMNS})
            rows.append(row)
        header = ["run", "run_id", *keys, *COLUMNS]

        def write(f: io.TextIOBase) -> None:
            writer = csv.DictWriter(f, fieldnames=header)
            writer.writeheader()
            writer.writerows(rows)

        _atomic_write(os.path.join(self.out, INDEX), write, binary=False)


def _json_value(value: Any) -> Any:
    """A value JSON has no type for: a numpy array (a scene's mesh) as lists, anything else as
    its text."""
    return value.tolist() if isinstance(value, np.ndarray) else str(value)


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list | dict):
        return json.dumps(value)
    return value


def read_index(out: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The records of the runs listed in ``OUT/index.csv``, in sweep order (a run with no
    record yet reads ``{"status": "pending"}``)."""
    store = Store(out)
    with open(os.path.join(store.out, INDEX), encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    records = []
    for row in rows:
        record = store.read_record(row["run_id"])
        records.append(record if record is not None else
                       {"run": int(row["run"]), "run_id": row["run_id"], "status": "pending"})
    return records


def load_run(out: str | os.PathLike[str], run_id: str) -> dict[str, np.ndarray]:
    """The arrays of an ``ok`` run (``meta`` decoded into a dict)."""
    with np.load(Store(out).npz_path(run_id)) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["meta"] = json.loads(str(arrays["meta"]))
    return arrays


def statuses(records: Iterable[dict[str, Any]]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for record in records:
        counts[record["status"]] = counts.get(record["status"], 0) + 1
    return counts
