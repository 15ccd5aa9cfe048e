"""``python -m rustcloth sweep SWEEP.toml [--backend local|ray] [--out DIR]``: run a sweep with a
progress bar (tqdm if it is installed, else a plain line) and a summary table at the end."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from typing import Any, NoReturn, TextIO

from ..errors import RustclothError
from .driver import BACKENDS, SweepResult, run_sweep
from .local import available_cores
from .runner import STATUSES
from .spec import Sweep, SweepError
from .store import Store


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows a default where there is one to show (not None, not a flag's False)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default in (None, False):
            return action.help or ""
        return super()._get_help_string(action) or ""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not >= 1")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{value} is not a positive number")
    return value


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="rustcloth sweep", formatter_class=_Formatter,
                description="Run the simulations a sweep file describes, skipping those whose "
                            "results are already in the output folder; a progress bar while "
                            "they run, a summary table at the end. Format, backends, "
                            "statuses: docs/sweeps.md.")
    p.add_argument("sweep", help="the sweep description, a TOML file (format: docs/sweeps.md)")
    p.add_argument("--out", default=None,
                   help="output folder (runs/*.npz, index.csv); default: the sweep file's name "
                        "without .toml, beside it")
    p.add_argument("--backend", choices=BACKENDS, default="local",
                   help="local: a process pool on this machine; ray: Ray tasks")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help=f"local: worker processes (default: cores / threads; {available_cores()}"
                        " cores here)")
    p.add_argument("--threads", type=_positive_int, default=None,
                   help="rayon threads per run (default local: cores / workers; ray: 1)")
    p.add_argument("--address", default=None,
                   help="ray: cluster address ('auto', 'ray://host:10001'); default: start a "
                        "local Ray")
    p.add_argument("--time-limit", type=_positive_float, default=None,
                   help="wall seconds per run (default: the file's time_limit; none there: no "
                        "limit)")
    p.add_argument("--retry-failed", action="store_true",
                   help="run diverged and error runs again (timeout and crashed always are)")
    p.add_argument("--progress", choices=("auto", "tqdm", "plain", "none"), default="auto",
                   help="auto: tqdm if installed, else a plain line")
    p.add_argument("--dry-run", action="store_true",
                   help="check the description and list its runs without running them")
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
        from tqdm import tqdm

        self.bar = tqdm(total=total, initial=done, unit="run", dynamic_ncols=True)

    def __call__(self, record: dict[str, Any], done: int, total: int, failed: int) -> None:
        self.bar.update(1)
        self.bar.set_postfix(failed=failed, refresh=False)

    def close(self) -> None:
        self.bar.close()


def make_progress(kind: str, total: int, done: int) -> Any:
    if kind in ("auto", "tqdm"):
        try:
            return TqdmProgress(total, done)
        except ImportError:
            if kind == "tqdm":
                raise SweepError("--progress tqdm: tqdm is not installed") from None
    if kind == "none":
        return None
    return PlainProgress(total, done)


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
    status; 1: interrupted; 2: a bad command line or description)."""
    args_parser = parser()
    try:
        args = args_parser.parse_args(sys.argv[1:] if argv is None else argv)
    except SystemExit as stop:
        return int(stop.code or 0)
    prog = args_parser.prog
    if args.address is not None and args.backend != "ray":
        print(f"{prog}: error: --address is for the ray backend", file=sys.stderr)
        return 2
    if args.workers is not None and args.backend == "ray":
        print(f"{prog}: error: --workers is for the local backend (ray runs as many tasks as "
              "the cluster has CPUs for; --threads sets CPUs per task)", file=sys.stderr)
        return 2
    try:
        sweep = Sweep.from_toml(args.sweep)
        if args.time_limit is not None:
            sweep = dataclasses.replace(sweep, time_limit=args.time_limit)
        runs = sweep.expand()
    except (ValueError, TypeError) as err:  # SweepError, and the scene's ParameterError
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    if args.dry_run:
        for run in runs:
            params = ", ".join(f"{k}={v!r}" for k, v in run.params.items())
            print(f"{run.index:>5} {run.run_id} {run.steps:>7} steps  {params}")
        print(f"{len(runs)} runs")
        return 0
    out = args.out or os.path.splitext(os.path.abspath(args.sweep))[0]
    bar: Any = None
    try:
        if args.progress != "none":
            done = len(Store(out).completed(runs, args.retry_failed))
            bar = make_progress(args.progress, len(runs), done)
            kind = "tqdm" if isinstance(bar, TqdmProgress) else "a plain line (no tqdm)"
            print(f"{len(runs)} runs, {done} already complete; progress: {kind}",
                  file=sys.stderr)
        result = run_sweep(sweep, out, args.backend, workers=args.workers,
                           threads=args.threads, address=args.address,
                           retry_failed=args.retry_failed, progress=bar)
    except (SweepError, RustclothError, ImportError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted; run the same command again to resume", file=sys.stderr)
        return 1
    finally:
        if bar is not None:
            bar.close()
    summary(result)
    return 0
