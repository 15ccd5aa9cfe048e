"""Sweep throughput: a serial loop against the local and Ray backends, in one sitting.

    python benches/bench_sweep.py                # 200 runs of a 64 x 64 cloth for 2 s each
    python benches/bench_sweep.py --quick        # 20 runs of 32 x 32 for 0.5 s: a smoke test
    python benches/bench_sweep.py --no-write     # print, leave docs/sweeps.md alone

Each configuration runs in its own driver process (so each driver's peak memory is its own)
into its own temporary folder: the serial loop (``execute`` over the runs in one process, rayon
on every core), the local backend at 1 worker x 1 thread, 1 x 2 and 2 x 1, and Ray at 2 tasks
x 1 thread. Per configuration it reports the wall time, the speed-up over the serial loop,
core utilisation (the CPU time the runs themselves used, summed, over wall time x cores), the
per-run overhead (wall time x slots minus the time spent inside runs, per run; and the wall
time per run of 200 runs that do nothing), the driver's peak RSS, and what else the machine was
doing meanwhile (its busy fraction from /proc/stat minus our own processes' share). The results
replace the benchmark section of docs/sweeps.md (between its ``bench:`` markers).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle BLAS threads would steal the cores

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "sweeps.md"
START, END = "<!-- bench:start -->", "<!-- bench:end -->"

CONFIGS = {  # name: (backend, workers, threads)
    "serial": ("serial", 1, None),
    "local 1x1": ("local", 1, 1),
    "local 1x2": ("local", 1, 2),
    "local 2x1": ("local", 2, 1),
    "ray 2x1": ("ray", None, 1),
}


def the_sweep(n: int, seconds: float, runs: int):
    """``runs`` runs of the hanging cloth at n x n over a k_bend x damping grid, recording
    positions, energy and stretch every 250 steps and the final mesh."""
    import numpy as np
    from rustcloth.sweep import Record, Sweep

    k = max(1, runs // 10)
    grid = {"cloth.k_bend": np.linspace(5.0, 50.0, k).round(4).tolist(),
            "cloth.damping": np.linspace(0.005, 0.05, runs // k).round(5).tolist(),
            "cloth.nx": [n], "cloth.ny": [n]}
    return Sweep(base="hanging", grid=grid, seconds=seconds, record=Record(every=250))


def empty_sweep(runs: int):
    """``runs`` runs that do (almost) nothing: a 2 x 2 cloth for one step, its final state."""
    from rustcloth.sweep import Record, Sweep

    return Sweep(base={"cloth": {"nx": 2, "ny": 2}},
                 grid={"cloth.k_bend": [float(k) for k in range(1, runs + 1)]}, steps=1,
                 record=Record(positions=False, energy=False, max_stretch=False))


def _cpu_ticks() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine."""
    with open("/proc/stat") as f:
        fields = [int(v) for v in f.readline().split()[1:]]
    idle = fields[3] + fields[4]
    return sum(fields) - idle, sum(fields)


def one(config: str, args: argparse.Namespace, empty: bool) -> dict:
    """Run one configuration in this process and return its measurements."""
    from rustcloth.sweep import execute, run_sweep
    from rustcloth.sweep.local import LocalBackend, available_cores

    backend, workers, threads = CONFIGS[config]
    sweep = empty_sweep(args.runs) if empty else the_sweep(args.n, args.seconds, args.runs)
    runs = sweep.expand()
    out = tempfile.mkdtemp(prefix="bench_sweep_")
    extra = {}
    try:
        if backend == "ray":
            import ray

            t = time.perf_counter()
            ray.init(num_cpus=available_cores(), include_dashboard=False, log_to_driver=False)
            extra["ray_init_s"] = time.perf_counter() - t
            # Start the workers (with RAYON_NUM_THREADS set) before the clock: Ray's start-up
            # is paid once per session, not per sweep.
            run_sweep(empty_sweep(4).expand(), out + "-warm", "ray", threads=threads)
        busy0, total0 = _cpu_ticks()
        start = time.perf_counter()
        if backend == "serial":
            results = [execute(run) for run in runs]
            records = [{"status": r.status, **r.info} for r in results]
            slots = 1
        else:
            engine = LocalBackend(workers, threads) if backend == "local" else "ray"
            result = run_sweep(runs, out, engine, threads=threads)
            records = result.records
            slots = workers or max(1, available_cores() // threads)
            if backend == "local":
                extra["startup_s"] = engine.startup_s
        wall = time.perf_counter() - start
        busy1, total1 = _cpu_ticks()
        if backend == "ray":
            ray.shutdown()
    finally:
        shutil.rmtree(out, ignore_errors=True)
        shutil.rmtree(out + "-warm", ignore_errors=True)
    cores = available_cores()
    run_cpu = sum(r.get("cpu_s", 0.0) for r in records)
    run_wall = sum(r.get("wall_s", 0.0) for r in records)
    machine_busy = (busy1 - busy0) / max(total1 - total0, 1)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return {
        "config": config, "empty": empty, "runs": len(records), "wall_s": wall, "slots": slots,
        "statuses": sorted({r["status"] for r in records}),
        "threads_seen": sorted({r.get("threads") for r in records if r.get("threads")}),
        "run_cpu_s": run_cpu, "run_wall_s": run_wall,
        "utilisation": run_cpu / (wall * cores),
        "overhead_ms": 1e3 * (wall * slots - run_wall) / len(records),
        "per_run_ms": 1e3 * wall / len(records),
        "machine_busy": machine_busy,
        "driver_cpu_s": usage.ru_utime + usage.ru_stime,
        "driver_peak_mib": usage.ru_maxrss / 1024,
        "loadavg": os.getloadavg(),
        **extra,
    }


def run_config(config: str, args: argparse.Namespace, empty: bool) -> dict:
    command = [sys.executable, __file__, "--one", config, "--runs", str(args.runs), "--n",
               str(args.n), "--seconds", str(args.seconds)] + (["--empty"] if empty else [])
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{config} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def median(values: list[float]) -> float:
    values = sorted(values)
    mid = len(values) // 2
    return values[mid] if len(values) % 2 else (values[mid - 1] + values[mid]) / 2


def table(rounds: dict[str, list[dict]], serial_wall: float) -> list[str]:
    lines = ["| configuration | wall [s] (each round) | vs serial | core utilisation | machine "
             "idle | others' load | run CPU [s] | overhead/run [ms] | driver CPU [s] | driver "
             "peak RSS [MiB] | rayon threads |",
             "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"]
    for config, rs in rounds.items():
        wall = median([r["wall_s"] for r in rs])
        ours = median([r["utilisation"] for r in rs])
        idle = median([1.0 - r["machine_busy"] for r in rs])
        others = median([max(0.0, r["machine_busy"] - r["utilisation"]) for r in rs])
        each = " / ".join(f"{r['wall_s']:.1f}" for r in rs)
        lines.append(
            f"| {config} | **{wall:.1f}** ({each}) | {serial_wall / wall:.2f}x | {ours:.0%} | "
            f"{idle:.0%} | {others:.0%} | {median([r['run_cpu_s'] for r in rs]):.1f} | "
            f"{median([r['overhead_ms'] for r in rs]):.1f} | "
            f"{median([r['driver_cpu_s'] for r in rs]):.1f} | "
            f"{max(r['driver_peak_mib'] for r in rs):.0f} | "
            f"{','.join(str(t) for t in sorted({t for r in rs for t in r['threads_seen']}))} |")
    return lines


def report(rounds: dict[str, list[dict]], empties: list[dict], args: argparse.Namespace) -> str:
    serial_wall = median([r["wall_s"] for r in rounds["serial"]])
    run_ms = 1e3 * median([r["run_wall_s"] for r in rounds["local 1x1"]]) / args.runs
    one, two = (median([r["wall_s"] for r in rounds[c]]) for c in ("local 1x1", "local 2x1"))
    lines = [
        f"Measured {datetime.date.today().isoformat()} by `python benches/bench_sweep.py` on "
        f"{platform.machine()} with {os.cpu_count()} cores, Python "
        f"{platform.python_version()}: {args.runs} runs of the hanging cloth at {args.n} x "
        f"{args.n} for {args.seconds:g} s each ({round(args.seconds / 0.001)} steps of 2 "
        "substeps), positions, energy and stretch every 250 steps plus the final mesh (0.6 MB "
        f"per run at 64 x 64). One run takes {run_ms:.0f} ms inside a 1-thread worker (median "
        f"over the rounds, on the loaded machine). {args.repeats} round(s), each running every "
        "configuration once in its own driver process, one after the other; the table gives "
        "the median and each round's wall time.",
        "",
        *table(rounds, serial_wall),
        "",
        f"From 1 to 2 workers (1 thread each) the sweep's wall time goes from {one:.1f} s to "
        f"{two:.1f} s, {one / two:.2f}x.",
        "",
        "*Core utilisation*: the CPU time of the runs themselves (process CPU time inside "
        "`execute`, summed: *run CPU*) over wall time x cores. *Machine idle*: the share of the "
        "machine's CPU time nobody used (/proc/stat) over the same interval, so 0 % means the "
        "sweep left no core unused; *others' load*: the machine's busy share minus ours, the "
        "other agents sharing this machine. *Overhead/run*: wall time x slots minus the time "
        "spent inside runs, per run (starting workers, sending runs, returning and writing "
        "results). *Driver CPU*: the driver process's own CPU time, which it takes from the "
        "same cores.",
        "",
        f"Per-run overhead measured directly, with {args.runs} runs that do nothing (a 2 x 2 "
        "cloth for one step, final state only): wall time per run, and that x slots (what one "
        "worker spends per run outside it). Of the local backend's, about 5 ms is the fsync "
        "of each result (see *Atomic writes*), which the driver waits for while the workers "
        "already have their next run.",
        "",
        "| configuration | wall [s] | ms per run | ms per run x slots | the same without "
        "starting the workers |",
        "|---|--:|--:|--:|--:|",
        *(f"| {e['config']} | {e['wall_s']:.2f} | {e['per_run_ms']:.2f} | "
          f"{e['per_run_ms'] * e['slots']:.2f} | "
          f"{1e3 * (e['wall_s'] - (e.get('startup_s') or 0.0)) * e['slots'] / e['runs']:.2f} |"
          for e in empties),
    ]
    starts = [r["startup_s"] for rs in rounds.values() for r in rs
              if r.get("startup_s") is not None]
    if starts:
        lines += ["", "The local rows include starting their workers (fresh interpreters that "
                  f"import numpy and rustcloth): {min(starts):.2f}-{max(starts):.2f} s per "
                  "sweep here."]
    inits = [r["ray_init_s"] for rs in rounds.values() for r in rs if "ray_init_s" in r]
    if inits:
        lines += ["", f"`ray.init()` took {min(inits):.1f}-{max(inits):.1f} s here and is not "
                  "in the Ray rows (nor is the start of its workers: a 4-run warm-up sweep ran "
                  "first); a session pays it once."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--n", type=int, default=64, help="cloth particles per side")
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated time per run")
    parser.add_argument("--quick", action="store_true", help="20 runs of 32 x 32 for 0.5 s")
    parser.add_argument("--repeats", type=int, default=2, help="rounds over the configurations")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray configuration")
    parser.add_argument("--no-write", action="store_true", help="do not touch docs/sweeps.md")
    parser.add_argument("--one", choices=CONFIGS, help=argparse.SUPPRESS)
    parser.add_argument("--empty", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.quick:
        args.runs, args.n, args.seconds, args.repeats = 20, 32, 0.5, 1
    if args.one:
        print(json.dumps(one(args.one, args, args.empty)))
        return
    configs = [c for c in CONFIGS if not (args.no_ray and c.startswith("ray"))]
    print(f"loadavg before: {os.getloadavg()}", flush=True)
    rounds: dict[str, list[dict]] = {c: [] for c in configs}
    empties = []
    for round_ in range(args.repeats):
        for config in configs:
            r = run_config(config, args, empty=False)
            rounds[config].append(r)
            print(f"round {round_ + 1} {config:10} {r['wall_s']:7.2f} s  utilisation "
                  f"{r['utilisation']:.0%}  machine busy {r['machine_busy']:.0%}  overhead "
                  f"{r['overhead_ms']:.1f} ms/run  driver {r['driver_peak_mib']:.0f} MiB  "
                  f"threads {r['threads_seen']}  {r['statuses']}", flush=True)
    for config in [c for c in configs if c in ("serial", "local 2x1", "ray 2x1")]:
        empties.append(run_config(config, args, empty=True))
        e = empties[-1]
        print(f"{config:10} empty runs: {e['per_run_ms']:.2f} ms/run", flush=True)
    text = report(rounds, empties, args)
    print("\n" + text)
    if not args.no_write and not args.quick:
        doc = DOC.read_text()
        head, rest = doc.split(START)
        _, tail = rest.split(END)
        DOC.write_text(f"{head}{START}\n{text}\n{END}{tail}")
        print(f"\nwrote {DOC.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
