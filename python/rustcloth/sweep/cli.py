"""``python -m rustcloth sweep SWEEP.toml [--backend local|ray] [--out DIR]``: run a sweep with a
progress bar and a summary table at the end."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from typing import Any, TextIO

from .._cli import Parser, guarded, positive, positive_int, progress
from .driver import BACKENDS, SweepResult, run_sweep
from .local import available_cores
from .runner import STATUSES
from .spec import Sweep


def parser() -> argparse.ArgumentParser:
    p = Parser(prog="rustcloth sweep",
               description="Run the simulations a sweep file describes, skipping those whose\n"
                           "results are already in the output folder; a progress bar while they\n"
                           "run, a summary table at the end. Format, backends, statuses:\n"
                           "docs/sweeps.md.\n\n"
                           "A sweep file is code: the functions it names (scene_fn,\n"
                           "record.functions, filters.reject) run as Python in this process and\n"
                           "in its workers, so run only sweep files you trust. They may load .py\n"
                           "files from the sweep file's own folder, and a module only if you\n"
                           "name it with --module; --dry-run imports none of them.")
    p.add_argument("sweep", help="the sweep description, a TOML file (format: docs/sweeps.md)")
    p.add_argument("--out", default=None,
                   help="output folder (runs/*.npz, index.csv) (default: the sweep file's name "
                        "without .toml, beside it)")
    p.add_argument("--backend", choices=BACKENDS, default="local",
                   help="local: a process pool on this machine; ray: Ray tasks")
    p.add_argument("--workers", type=positive_int, default=None,
                   help=f"local: worker processes (default: cores / threads; {available_cores()}"
                        " cores here)")
    p.add_argument("--threads", type=positive_int, default=None,
                   help="rayon threads per run (default local: cores / workers; ray: 1)")
    p.add_argument("--address", default=None,
                   help="ray: cluster address ('auto', 'ray://host:10001') (default: start a "
                        "local Ray)")
    p.add_argument("--time-limit", type=positive, default=None,
                   help="wall seconds per run (default: the file's time_limit; none there: no "
                        "limit)")
    p.add_argument("--module", action="append", default=[], metavar="NAME",
                   help="let the sweep file name functions in module NAME ('NAME:function'); "
                        "repeat for more (default: none, only .py files beside the sweep file)")
    p.add_argument("--retry-failed", action="store_true",
                   help="run diverged and error runs again (timeout and crashed always are)")
    p.add_argument("--progress", choices=("auto", "tqdm", "plain", "none"), default="auto",
                   help="auto and tqdm: a tqdm bar on a terminal; plain: a line every few "
                        "seconds (for logs); none: no progress")
    p.add_argument("--dry-run", action="store_true",
                   help="check the description and list its runs without running them, and "
                        "without importing or calling any function the file names")
    return p


class PlainProgress:
    """``[ 37/200] 35 ok, 2 failed, 3.1 runs/s, ETA 0:00:52`` on one line (rewritten in place
    on a terminal; elsewhere printed every few seconds)."""

    def __init__(self, total: int, done: int, stream: TextIO | None = None) -> None:
        self.total, self.start_done = total, done
        self.stream = stream or sys.stderr
        self.start = time.monotonic()
        self.tty = self.stream.isatty()
        self.last = 0.0

    def __call__(self, record: dict[str, Any], done: int, total: int, failed: int) -> None:
        now = time.monotonic()
        if not self.tty and done < total and now - self.last < 5.0:
            return
        self.last = now
        rate = (done - self.start_done) / max(now - self.start, 1e-9)
        eta = (total - done) / rate if rate > 0 else float("nan")
        eta_text = time.strftime("%H:%M:%S", time.gmtime(eta)) if eta == eta else "?"
        line = (f"[{done:>{len(str(total))}}/{total}] {done - failed} ok, {failed} failed, "
                f"{rate:.2f} runs/s, ETA {eta_text}")
        self.stream.write(("\r" + line) if self.tty else line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty and self.last:
            self.stream.write("\n")


class TqdmProgress:
    def __init__(self, total: int, done: int) -> None:
        self.bar = progress(total, "run", initial=done)

    def __call__(self, record: dict[str, Any], done: int, total: int, failed: int) -> None:
        self.bar.update(1)
        self.bar.set_postfix(failed=failed, refresh=False)

    def close(self) -> None:
        self.bar.close()


class _Bar:
    """The progress of ``kind``, started once the driver knows how many runs there are."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.bar: Any = None

    def start(self, total: int, done: int) -> None:
        if self.kind == "none":
            return
        print(f"{total} runs, {done} already complete", file=sys.stderr)
        self.bar = (PlainProgress if self.kind == "plain" else TqdmProgress)(total, done)

    def __call__(self, record: dict[str, Any], done: int, total: int, failed: int) -> None:
        if self.bar is not None:
            self.bar(record, done, total, failed)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def summary(result: SweepResult, stream: TextIO | None = None, failures: int = 10) -> None:
    """Counts by status, timing, and the failed runs with their reasons."""
    stream = stream or sys.stdout
    records = result.records
    walls = [r["wall_s"] for r in records if isinstance(r.get("wall_s"), int | float)]
    print(f"\n{len(records)} runs in {result.out} ({result.backend}): {result.ran} ran now, "
          f"{result.skipped} already complete, {result.wall_s:.1f} s", file=stream)
    print(f"{'status':<10} {'runs':>6}", file=stream)
    for status in STATUSES:
        if result.counts.get(status):
            print(f"{status:<10} {result.counts[status]:>6}", file=stream)
    if walls:
        walls.sort()
        print(f"run wall time: median {walls[len(walls) // 2]:.3f} s, max {walls[-1]:.3f} s",
              file=stream)
    bad = [r for r in records if r["status"] not in ("ok",)]
    if bad:
        print(f"\n{'run':>5} {'status':<9} {'reason':<50} parameters", file=stream)
        for r in bad[:failures]:
            params = ", ".join(f"{k}={v}" for k, v in r["params"].items())
            print(f"{r['run']:>5} {r['status']:<9} {r['reason'][:50]:<50} {params}", file=stream)
        if len(bad) > failures:
            print(f"... and {len(bad) - failures} more in {os.path.join(result.out, 'index.csv')}",
                  file=stream)


def main(argv: list[str] | None = None) -> int:
    """The ``sweep`` command; returns the exit status (0: every run finished, whatever its
    status; 1: interrupted; 2: a bad command line, description or output folder, said in one
    line)."""
    return guarded("rustcloth sweep", lambda: _main(sys.argv[1:] if argv is None else argv))


def _main(argv: list[str]) -> int:
    options = parser()
    args = options.parse_args(argv)
    prog = options.prog
    if args.address is not None and args.backend != "ray":
        options.error("--address is for the ray backend")
    if args.workers is not None and args.backend == "ray":
        options.error("--workers is for the local backend (ray runs as many tasks as the "
                      "cluster has CPUs for; --threads sets CPUs per task)")
    sweep = Sweep.from_toml(args.sweep, modules=args.module)
    if args.time_limit is not None:
        sweep = dataclasses.replace(sweep, time_limit=args.time_limit)
    if args.dry_run:
        return _dry_run(sweep)
    out = args.out or os.path.splitext(os.path.abspath(args.sweep))[0]
    bar = _Bar(args.progress)
    try:
        result = run_sweep(sweep, out, args.backend, workers=args.workers,
                           threads=args.threads, address=args.address,
                           retry_failed=args.retry_failed, progress=bar, on_plan=bar.start)
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted; run the same command again to resume", file=sys.stderr)
        return 1
    finally:
        bar.close()
    summary(result)
    return 0


def _dry_run(sweep: Sweep) -> int:
    """List the runs; with scene_fn, their parameters only (ids and steps need its scenes)."""
    count = 0
    for run in sweep.preview():
        params = ", ".join(f"{k}={v!r}" for k, v in run.params.items())
        steps = "?" if run.steps is None else run.steps
        print(f"{run.index:>5} {run.run_id or '?':<16} {steps:>7} steps  {params}")
        count += 1
    print(f"{count} runs" + ("" if sweep.scene_fn is None else
                             " (scene_fn is not called in a dry run: ids and steps unknown)"))
    return 0
