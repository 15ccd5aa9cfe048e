"""Side-by-side peer benchmark: rustcloth vs numpy, Taichi and newton on the same cloth.

Every implementation runs in its own subprocess (clean peak RSS, its own thread pool), the
implementations interleaved within each repeat, and the median over repeats is reported; the
ratios are taken between medians measured in this one run. Writes ``docs/benchmarks.md`` and
prints the tables.

    .venv-peers/bin/python benches/peers/run.py                 # 128, 256, 512
    .venv-peers/bin/python benches/peers/run.py --quick         # 128 only, 100 steps, 1 repeat
    .venv-peers/bin/python benches/peers/run.py --sizes 128 256 --repeats 5 --only rustcloth numpy
    .venv/bin/python benches/peers/run.py --only profile        # per-pass split only (see below)

``--only profile`` runs rustcloth alone (1 and 2 threads, with and without the floor and
sphere) and rewrites only the "Where the time goes" section of ``docs/benchmarks.md``: the
per-pass split from ``Simulation.profile()``. A full run writes that section too, from the
rustcloth runs it times anyway.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))

from common import QUICK_STEPS, STEPS  # noqa: E402

# Flops and bytes per particle per step, counted from the model's formulas (see the roofline
# section written into docs/benchmarks.md).
FLOPS_PER_SPRING_GATHER = 30  # one end: d, |d|^2, sqrt, 1/l, k(l-L), dv.d, s, s d, f += s d
FLOPS_PER_SPRING_SCATTER = 33  # both ends: + f_b -= s d
FLOPS_UPDATE = 16  # + m g, v += (h/m) f, x += h v
FLOPS_GATHER = 12 * FLOPS_PER_SPRING_GATHER + FLOPS_UPDATE  # 376
FLOPS_SCATTER = 6 * FLOPS_PER_SPRING_SCATTER + FLOPS_UPDATE  # 214
BYTES_STATE = 48  # read x, v and write x, v: 4 x 12 B (float32)
BYTES_TYPICAL = 48 + 4 + 24  # + inverse mass + 6 stored rest lengths


@dataclass
class Impl:
    key: str
    label: str
    script: str
    threads: int
    args: list[str] = field(default_factory=list)
    env: dict[str, str] = field(default_factory=dict)
    gather: bool = True  # 12 spring evaluations per particle (else 6, scattered)
    colliders: bool = False
    python: str | None = None


def implementations(rust_python: str) -> list[Impl]:
    return [
        Impl(
            "rustcloth-1",
            "rustcloth",
            "impl_rustcloth.py",
            1,
            env={"RAYON_NUM_THREADS": "1"},
            colliders=True,
            python=rust_python,
            gather=False,  # each spring evaluated once into per-block tables, then gathered
        ),
        Impl(
            "rustcloth-2",
            "rustcloth",
            "impl_rustcloth.py",
            2,
            env={"RAYON_NUM_THREADS": "2"},
            colliders=True,
            python=rust_python,
            gather=False,
        ),
        Impl("numpy", "numpy (rustcloth.reference)", "impl_numpy.py", 1, gather=False),
        Impl("taichi-1", "Taichi gather", "impl_taichi.py", 1),
        Impl("taichi-2", "Taichi gather", "impl_taichi.py", 2),
        Impl(
            "taichi-atomic-2",
            "Taichi per-spring atomic",
            "impl_taichi.py",
            2,
            args=["--variant", "atomic"],
            gather=False,
        ),
        Impl("newton", "newton SolverSemiImplicit", "impl_newton.py", 1, gather=False),
    ]


def rustcloth_python(explicit: str | None) -> str:
    """This interpreter if it can import rustcloth, else the lead's development venv."""
    candidates = [explicit] if explicit else [sys.executable, str(ROOT / ".venv/bin/python")]
    for py in candidates:
        ok = subprocess.run([py, "-c", "import rustcloth"], capture_output=True, cwd="/")
        if ok.returncode == 0:
            return py
    return candidates[0]


def run_one(impl: Impl, n: int, steps: int, colliders: bool, timeout: float) -> dict:
    cmd = [
        impl.python or sys.executable,
        str(HERE / impl.script),
        "--n",
        str(n),
        "--steps",
        str(steps),
        "--threads",
        str(impl.threads),
        *impl.args,
    ]
    if colliders:
        cmd.append("--colliders")
    env = {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
        **impl.env,
    }
    try:
        proc = subprocess.run(
            cmd, capture_output=True, text=True, env=env, timeout=timeout, cwd=str(ROOT)
        )
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:.0f} s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT ") :])
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return {"error": f"exit {proc.returncode}: " + " | ".join(tail)}


def median_result(results: list[dict]) -> dict:
    good = [r for r in results if "error" not in r]
    if not good:
        return results[-1] if results else {"error": "not run"}
    out = dict(good[0])
    for key in (
        "setup_s",
        "warmup_s",
        "run_s",
        "ms_per_step",
        "cpu_per_wall",
        "peak_rss_mb",
        "min_y",
    ):
        out[key] = statistics.median(r[key] for r in good)
    out["ms_all"] = [r["ms_per_step"] for r in good]
    out["finite"] = all(r["finite"] for r in good)
    profiles = [r["profile"] for r in good if r.get("profile", {}).get("total")]
    if profiles:
        # ms/step per pass and its share of the step, each the median over the repeats.
        names = [name for name in profiles[0] if name != "total"]
        out["profile"] = {
            name: statistics.median(p.get(name, 0.0) for p in profiles)
            for name in [*names, "total"]
        }
        out["profile"]["other"] = statistics.median(
            p["total"] - sum(p.get(name, 0.0) for name in names) for p in profiles
        )
        out["profile_share"] = {
            name: statistics.median(p.get(name, 0.0) / p["total"] for p in profiles)
            for name in names
        }
        out["profile_share"]["other"] = statistics.median(
            1 - sum(p.get(name, 0.0) for name in names) / p["total"] for p in profiles
        )
    return out


def git_describe() -> str:
    def git(*a: str) -> str:
        p = subprocess.run(["git", *a], capture_output=True, text=True, cwd=str(ROOT))
        return p.stdout.strip()

    head = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--", "src", "Cargo.toml", "Cargo.lock", "python")
    return f"commit {head}" + (" (Rust/Python sources modified in the tree)" if dirty else "")


def machine_info() -> dict:
    cpu = "unknown"
    mhz = None
    flags: set[str] = set()
    family = model = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            key, value = key.strip(), value.strip()
            if key == "model name" and cpu == "unknown":
                cpu = value
            elif key == "cpu MHz" and mhz is None:
                mhz = float(value)
            elif key == "flags" and not flags:
                flags = set(value.split())
            elif key == "cpu family" and family is None:
                family = int(value)
            elif key == "model" and model is None:
                model = int(value)
    except OSError:
        pass
    if "avx512f" in flags:
        simd = "AVX-512"
        lanes = 16
    elif "avx2" in flags:
        simd, lanes = "AVX2", 8
    else:
        simd, lanes = "SSE2", 4
    # 2 FMA pipes x lanes x 2 flops per FMA (Zen 4 splits 512-bit ops: count 256-bit there).
    if simd == "AVX-512" and family is not None and family == 25:
        lanes = 8
    flops_per_cycle = 2 * lanes * 2 if "fma" in flags else 2 * lanes
    return {
        "cpu": cpu,
        "cpu_family": family,
        "cpu_model": model,
        "cores": os.cpu_count(),
        "mhz": mhz,
        "simd": simd,
        "flops_per_cycle": flops_per_cycle,
        "peak_gflops_core": (mhz or 0) / 1e3 * flops_per_cycle,
        "python": platform.python_version(),
        "kernel": platform.release(),
    }


def fmt(value: float | None, digits: int = 3) -> str:
    if value is None:
        return "n/a"
    if value == 0:
        return "0"
    mag = abs(value)
    if mag >= 100:
        return f"{value:,.0f}"
    if mag >= 10:
        return f"{value:.1f}"
    return f"{value:.{digits}g}"


def size_table(n: int, steps: int, impls: list[Impl], res: dict[str, dict]) -> list[str]:
    particles = n * n
    r1 = res.get("rustcloth-1", {})
    r2 = res.get("rustcloth-2", {})
    ref_y = r1.get("min_y", r2.get("min_y"))
    lines = [
        f"### {n} x {n} ({particles:,} particles, {steps} steps timed)",
        "",
        "| implementation | threads | set-up s | warm-up s (5 steps, incl. JIT) | ms/step | "
        "CPU s / wall s | steps/s | M particle-updates/s | peak RSS MB | "
        "ms/step / rustcloth 1t | ms/step / rustcloth 2t | min y (m) | min y - rustcloth |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for impl in impls:
        r = res.get(impl.key)
        if r is None:
            continue
        if "error" in r:
            lines.append(
                f"| {impl.label} | {impl.threads} | not measured: {r['error']} |" + " |" * 10
            )
            continue
        ms = r["ms_per_step"]
        s1 = ms / r1["ms_per_step"] if "ms_per_step" in r1 else None
        s2 = ms / r2["ms_per_step"] if "ms_per_step" in r2 else None
        dy = r["min_y"] - ref_y if ref_y is not None else None
        flag = "" if dy is None or abs(dy) <= 1e-3 else " **MISMATCH**"
        lines.append(
            f"| {impl.label} | {impl.threads} | {fmt(r['setup_s'])} | {fmt(r['warmup_s'])} | "
            f"{fmt(ms)} | {r.get('cpu_per_wall', 0):.2f} | {fmt(1e3 / ms)} | "
            f"{fmt(particles / ms / 1e3)} | "
            f"{fmt(r['peak_rss_mb'])} | {fmt(s1)} | {fmt(s2)} | {r['min_y']:.5f} | "
            f"{'n/a' if dy is None else f'{dy:+.1e}'}{flag}"
            + ("" if r["finite"] else " (NON-FINITE)")
            + " |"
        )
    lines.append("")
    return lines


def summary_lines(sizes, impls, results) -> list[str]:
    """rustcloth's speed-up over each peer at the same thread count, and the cross-check."""
    head = "| peer | threads | " + " | ".join(f"{n} x {n}" for n in sizes) + " |"
    lines = [
        "Summary: rustcloth's speed-up over each peer at the same thread count (peer "
        "ms/step / rustcloth ms/step, medians of this run):",
        "",
        head,
        "|---|--:|" + "--:|" * len(sizes),
    ]
    worst = 0.0
    for impl in impls:
        if impl.key.startswith("rustcloth"):
            continue
        ref = "rustcloth-1" if impl.threads == 1 else "rustcloth-2"
        cells = []
        for n in sizes:
            r, b = results[n].get(impl.key, {}), results[n].get(ref, {})
            ok = "ms_per_step" in r and "ms_per_step" in b
            cells.append(f"{r['ms_per_step'] / b['ms_per_step']:.1f}x" if ok else "n/a")
            if ok:
                worst = max(worst, abs(r["min_y"] - b["min_y"]))
        lines.append(f"| {impl.label} | {impl.threads} | " + " | ".join(cells) + " |")
    cells = []
    for n in sizes:
        a, b = results[n].get("rustcloth-1", {}), results[n].get("rustcloth-2", {})
        ok = "ms_per_step" in a and "ms_per_step" in b
        cells.append(f"{a['ms_per_step'] / b['ms_per_step']:.2f}x" if ok else "n/a")
    lines += [
        "| (rustcloth 2 threads over 1 thread) | 2 | " + " | ".join(cells) + " |",
        "",
        f"Cross-check: every implementation's lowest y after the run is within {worst:.1e} m "
        "of rustcloth's (tolerance 1e-3 m).",
        "",
    ]
    return lines


def measure_peak() -> dict[int, dict]:
    """Compile and run peakflops.c (FMA and sqrt + divide throughput), 1 and 2 threads."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if not cc:
        return {}
    with tempfile.TemporaryDirectory() as tmp:
        exe = os.path.join(tmp, "peakflops")
        build = subprocess.run(
            [cc, "-O3", "-march=native", "-fno-math-errno", "-pthread",
             str(HERE / "peakflops.c"), "-o", exe, "-lm"],
            capture_output=True, text=True,
        )  # fmt: skip
        if build.returncode != 0:
            return {}
        out: dict[int, dict] = {}
        for threads in (1, 2):
            runs = []
            for _ in range(3):
                p = subprocess.run([exe, str(threads)], capture_output=True, text=True)
                if p.returncode == 0:
                    runs.append(json.loads(p.stdout))
            if runs:
                out[threads] = {
                    "fma_gflops": max(r["fma_gflops"] for r in runs),
                    "sqrt_div_gpairs": max(r["sqrt_div_gpairs"] for r in runs),
                }
        return out


PROFILE_HEADING = "## Where the time goes: the per-pass split from profile()"

# Passes in step order, with what each one is; passes a scene does not have are skipped.
PASS_LABELS = {
    "gravity": "gravity (force)",
    "air_drag": "air drag (force)",
    "structural_springs": "structural springs (force)",
    "shear_springs": "shear springs (force)",
    "bend_springs": "bending springs (force)",
    "symplectic_euler": "symplectic Euler (integrator)",
    "kinematic_pins": "kinematic pins",
    "spheres": "spheres (collider)",
    "floor": "floor (collider)",
    "other": "other (step bookkeeping)",
}
SPRING_PASSES = ("structural_springs", "shear_springs", "bend_springs")
COLLIDER_PASSES = ("spheres", "floor")


def profile_lines(sizes, impls, results, collider_results, source: str) -> list[str]:
    """The per-pass split of rustcloth's step, from ``Simulation.profile()``.

    ``source`` says which runs the profiles come from, and when they were measured.
    """
    lines = [
        PROFILE_HEADING,
        "",
        f"`Simulation.profile()` of {source}: the benchmark scene, without and with the "
        "floor and sphere, the timed steps only (warm-up excluded). Each cell is the wall time "
        "of a pass in ms per step and, in brackets, its share of the step, both medians over "
        "the repeats. The force terms run fused in one sweep over blocks of particles (each "
        "block's spring-force table, then every term adding into the block's forces); "
        "profile() splits the sweep's wall time among the terms in proportion to the CPU time "
        "each measured, so a spring family's time is computing its springs' forces into the "
        "table and gathering them (terms added in one pass share that pass's time as the "
        "arrays each reads). Other is what the step spends outside the passes. Threads busy "
        "is the process's CPU time over the wall time of the timed steps: below the thread "
        "count, the second thread often found its core taken by other jobs.",
        "",
    ]
    summary = []
    for impl in impls:
        if not impl.key.startswith("rustcloth"):
            continue
        columns = []
        for n in sizes:
            for label, res in (("", results), (" + floor, sphere", collider_results)):
                r = res.get(n, {}).get(impl.key, {})
                if "profile" in r:
                    columns.append((n, bool(label), f"{n} x {n}{label}", r))
        if not columns:
            continue
        seen = {name for *_, r in columns for name in r["profile"]} - {"total"}
        names = [name for name in PASS_LABELS if name in seen] + sorted(seen - set(PASS_LABELS))
        threads = f"{impl.threads} thread{'s' if impl.threads > 1 else ''}"
        lines += [
            f"rustcloth, {threads} (ms per step, % of the step):",
            "",
            "| pass | " + " | ".join(head for _, _, head, _ in columns) + " |",
            "|---|" + "--:|" * len(columns),
        ]
        for name in names:
            cells = [
                f"{fmt(r['profile'][name])} ({100 * r['profile_share'][name]:.0f} %)"
                if name in r["profile"]
                else ""
                for *_, r in columns
            ]
            lines.append(f"| {PASS_LABELS.get(name, name)} | " + " | ".join(cells) + " |")
        lines += [
            "| **step (profile total)** | "
            + " | ".join(f"**{fmt(r['profile']['total'])}**" for *_, r in columns)
            + " |",
            "| threads busy (CPU s / wall s) | "
            + " | ".join(f"{r.get('cpu_per_wall', 0):.2f}" for *_, r in columns)
            + " |",
            "",
        ]

        def share(r, names):
            return 100 * sum(r["profile_share"].get(name, 0.0) for name in names)

        def ms(r, names):
            return sum(r["profile"].get(name, 0.0) for name in names)

        def span(values, form="{:.0f} %"):
            lo, hi = form.format(min(values)), form.format(max(values))
            return lo if lo == hi else f"{lo} to {hi}"

        euler = ("symplectic_euler",)
        every = [r for *_, r in columns]
        with_c = {n: r for n, c, _, r in columns if c}
        pairs = [(r, with_c[n]) for n, c, _, r in columns if not c and n in with_c]
        springs = span([share(r, SPRING_PASSES) for r in every])
        update = span([share(r, euler) for r in every])
        gravity = span([share(r, ("gravity",)) for r in every])
        text = f"at {threads} the three spring families take {springs} of the step, the "
        text += f"integrator's update {update}, gravity {gravity}"
        if pairs:
            colliders = span([share(c, COLLIDER_PASSES) for _, c in pairs])
            per_update = span([ms(c, COLLIDER_PASSES) / ms(c, euler) for _, c in pairs], "{:.1f}")
            drift = span(
                [100 * (ms(c, SPRING_PASSES) / ms(r, SPRING_PASSES) - 1) for r, c in pairs],
                "{:+.0f} %",
            )
            text += (
                f", the floor and sphere together {colliders} ({per_update} times the "
                "integrator's update), and the springs' own time with the colliders differs "
                f"from that without by {drift}"
            )
        busy = statistics.median(r.get("cpu_per_wall", 0.0) for r in every)
        if impl.threads > 1 and busy < impl.threads - 0.5:
            text += (
                f" (these runs kept only {busy:.1f} cores busy: other jobs held the rest, so "
                "their times are no measure of the parallel speed-up)"
            )
        summary.append(text)
    if summary:
        lines += [
            "Reading it: " + "; ".join(summary) + ". So the spring forces are the step: "
            "six spring evaluations per particle (one sqrt and one divide each) written into "
            "the block's table and twelve table reads gathered back, two springs per particle "
            "in each family, which is why the three families cost about the same. Each "
            "collider is one streaming pass over positions and velocities, like the "
            "integrator's update, so the floor and sphere add about what the update costs and "
            "leave the springs in first place; the force sweep does no different work when "
            "they are on (the springs' difference above is run-to-run noise between "
            "processes). Collisions add to the picture without changing it.",
            "",
        ]
    return lines


def splice_section(text: str, section: list[str]) -> str:
    """``text`` with its profile section replaced by ``section`` (or put before the roofline)."""
    lines = text.splitlines()
    if PROFILE_HEADING in lines:
        start = lines.index(PROFILE_HEADING)
        end = next(
            (i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines)
        )
    else:
        start = end = next(
            (i for i, line in enumerate(lines) if line.startswith("## Roofline")), len(lines)
        )
    return "\n".join(lines[:start] + section + lines[end:]) + "\n"


def profile_only(args, impls, steps_for) -> None:
    """Times rustcloth alone and rewrites only the per-pass section of the output."""
    impls = [i for i in impls if i.key.startswith("rustcloth")]
    results: dict[int, dict[str, dict]] = {}
    collider_results: dict[int, dict[str, dict]] = {}
    for n in args.sizes:
        steps = steps_for.get(n, 100)
        raw: dict[tuple[str, bool], list[dict]] = {}
        for rep in range(args.repeats):
            for impl in impls if rep % 2 == 0 else impls[::-1]:
                for colliders in (False, True) if rep % 2 == 0 else (True, False):
                    r = run_one(impl, n, steps, colliders, args.timeout)
                    raw.setdefault((impl.key, colliders), []).append(r)
                    print(
                        f"  n={n} rep={rep} {impl.key}{' +colliders' if colliders else ''}: "
                        + (r["error"] if "error" in r else f"{r['ms_per_step']:.4g} ms/step"),
                        flush=True,
                    )
        results[n] = {k: median_result(v) for (k, c), v in raw.items() if not c}
        collider_results[n] = {k: median_result(v) for (k, c), v in raw.items() if c}
    built = next(
        (r["built"] for per in results.values() for r in per.values() if "built" in r), "?"
    )
    timed = ", ".join(f"{steps_for.get(n, 100)} steps at {n}" for n in args.sizes)
    source = (
        "rustcloth runs made for this section by `run.py --only profile` on "
        f"{dt.datetime.now(dt.UTC).strftime('%Y-%m-%d %H:%M UTC')} (1 and 2 threads, each run "
        f"in its own process as above, {args.repeats} repeat(s), {timed} timed; extension "
        f"built {built}, repository at {git_describe()})"
    )
    section = profile_lines(args.sizes, impls, results, collider_results, source)
    print("\n".join(section))
    if not args.no_write:
        out = Path(args.output)
        old = out.read_text() if out.exists() else ""
        out.write_text(splice_section(old, section))
        print(f"wrote the per-pass section of {out}")


def roofline_lines(sizes, impls, results, bw, machine, peak) -> list[str]:
    est1 = machine["peak_gflops_core"]
    bw_t = {
        1: max(bw.get("copy_1t_gbs", 0), bw.get("add_1t_gbs", 0)),
        2: max(bw.get("copy_2t_gbs", 0), bw.get("add_2t_gbs", 0)),
    }
    fma = {t: peak.get(t, {}).get("fma_gflops") or est1 * t for t in (1, 2)}
    sqd = {t: peak.get(t, {}).get("sqrt_div_gpairs") for t in (1, 2)}
    lines = [
        "## Roofline",
        "",
        "Counted from the model's formulas, float32, per particle per step:",
        "",
        f"* **flops**: one spring evaluation (one end) is {FLOPS_PER_SPRING_GATHER} flops "
        "(d = x_b - x_a: 3, |d|^2: 5, sqrt: 1, 1/l: 1, k (l - L): 2, (v_b - v_a) . d: 8, "
        "c (...) / l + ...: 3, s = (...) / l: 1, s d: 3, f += s d: 3), of which **one sqrt "
        f"and one divide**; {FLOPS_PER_SPRING_SCATTER} when both ends are updated "
        f"(f_b -= s d). The update (gravity, v += (h/m) f, x += h v) is {FLOPS_UPDATE}. A "
        f"per-particle gather (Taichi gather) evaluates 12 springs: "
        f"**{FLOPS_GATHER} flops/particle, 12 sqrt + 12 div**; evaluating each spring once "
        f"(6 per particle: numpy, newton and Taichi atomic scatter them; rustcloth writes them "
        f"to a per-block table, about 10 % of them twice at block edges, and gathers) is "
        f"**{FLOPS_SCATTER} flops/particle, 6 sqrt + 6 div** (plus the scatter's "
        "read-modify-write of a force buffer, or the table's write and read).",
        "* **bytes**: at least the state, read and written once: x and v in, x and v out, "
        f"4 x 12 B = **{BYTES_STATE} B/particle**; with an inverse mass and 6 stored rest "
        f"lengths read too, {BYTES_TYPICAL} B. Neighbour reads hit in cache when rows are "
        "streamed (a gather touches rows j-2..j+2). A per-spring scatter also writes and "
        "re-reads a force buffer (+24 B) and numpy's temporaries add far more.",
        f"* arithmetic intensity, gather: {FLOPS_GATHER}/{BYTES_STATE} = "
        f"{FLOPS_GATHER / BYTES_STATE:.1f} flop/B (state only), "
        f"{FLOPS_GATHER / BYTES_TYPICAL:.1f} flop/B with inverse mass and rest lengths.",
        "",
        "Machine ceilings, measured in this run: memory bandwidth by `benches/peers/membw.py` "
        "(numpy stream-like loops on 256 MiB float32 arrays, reads + writes counted, no "
        "write-allocate, best of 8); FMA and sqrt + divide throughput by "
        "`benches/peers/peakflops.c` (cc -O3 -march=native; 12 independent chains on 16-lane "
        "vectors, best of 3). On a shared 2-core VM the 2-thread figures are whatever the "
        "other jobs left.",
        "",
        "| | 1 thread | 2 threads |",
        "|---|--:|--:|",
        f"| copy a = b, GB/s | {fmt(bw.get('copy_1t_gbs'))} | {fmt(bw.get('copy_2t_gbs'))} |",
        f"| add a = b + c, GB/s | {fmt(bw.get('add_1t_gbs'))} | {fmt(bw.get('add_2t_gbs'))} |",
        f"| FMA peak, GFLOP/s (measured) | {fmt(fma[1])} | {fmt(fma[2])} |",
        f"| sqrt + divide pairs, G/s (measured) | {fmt(sqd[1])} | {fmt(sqd[2])} |",
        f"| FMA peak estimate, GFLOP/s ({machine['mhz']:.0f} MHz x "
        f"{machine['flops_per_cycle']} flop/cycle, {machine['simd']}) | {fmt(est1)} | "
        f"{fmt(2 * est1)} |",
        "",
    ]
    if sqd[1]:
        gather_ceilings = {
            "memory": BYTES_STATE / bw_t[1],
            "FMA arithmetic": FLOPS_GATHER / fma[1],
            "sqrt + divide": 12 / sqd[1],
        }
        binding = max(gather_ceilings, key=gather_ceilings.get)
        lines += [
            f"Per particle and step on one thread: memory {BYTES_STATE} B / {fmt(bw_t[1])} "
            f"GB/s = {BYTES_STATE / bw_t[1]:.2f} ns (and the whole state of the 512 x 512 "
            "cloth, 6 MiB of x and v, fits in the 32 MiB L3, so this is pessimistic); "
            f"arithmetic {FLOPS_GATHER} / {fmt(fma[1])} GFLOP/s = {FLOPS_GATHER / fma[1]:.2f} "
            f"ns for the gather; **sqrt + divide: 12 / {fmt(sqd[1])} G/s = "
            f"{12 / sqd[1]:.2f} ns for the gather, 6 / {fmt(sqd[1])} = {6 / sqd[1]:.2f} ns "
            f"evaluating each spring once**. For the gather the binding ceiling is "
            f"**{binding}**: the model is compute bound on this machine, memory is not the "
            "limit. The FMA ceiling is optimistic (it counts an FMA as 2 flops; this kernel's "
            "adds and multiplies mostly do not fuse), and the exact sqrt and divide cost "
            "about as much as all the other arithmetic (an approximate rsqrt with a Newton "
            "step would lift that part). The bound below is the largest of the three "
            "ceilings for the implementation's spring count and thread count.",
            "",
        ]
    lines += [
        "| size | implementation | threads | ns/particle/step | bound ns | % of bound | "
        "GFLOP/s (counted) | GB/s (state only) |",
        "|---|---|--:|--:|--:|--:|--:|--:|",
    ]
    for n in sizes:
        for impl in impls:
            r = results.get(n, {}).get(impl.key)
            if not r or "error" in r:
                continue
            t = impl.threads
            ns = r["ms_per_step"] * 1e6 / (n * n)
            flops = FLOPS_GATHER if impl.gather else FLOPS_SCATTER
            springs = 12 if impl.gather else 6
            ceilings = [BYTES_STATE / bw_t[t], flops / fma[t]]
            if sqd[t]:
                ceilings.append(springs / sqd[t])
            bound = max(ceilings)
            lines.append(
                f"| {n} | {impl.label} | {t} | {fmt(ns)} | {bound:.2f} | "
                f"{100 * bound / ns:.1f} | {fmt(flops / ns)} | {fmt(BYTES_STATE / ns)} |"
            )
    lines.append("")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512])
    p.add_argument("--quick", action="store_true", help="128 only, 100 steps, 1 repeat")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument(
        "--only",
        nargs="+",
        help="implementation keys to run (default: all); 'profile': only rustcloth's per-pass "
        "split, written into its section of the output",
    )
    p.add_argument("--no-colliders", action="store_true", help="skip the floor + sphere table")
    p.add_argument("--rustcloth-python", help="interpreter that imports rustcloth")
    p.add_argument("--output", default=str(ROOT / "docs/benchmarks.md"))
    p.add_argument("--no-write", action="store_true", help="print only")
    p.add_argument("--timeout", type=float, default=600.0, help="per subprocess, s")
    args = p.parse_args()
    if args.quick:
        args.sizes, args.repeats = [128], 1
    steps_for = QUICK_STEPS if args.quick else STEPS

    rust_py = rustcloth_python(args.rustcloth_python)
    impls = implementations(rust_py)
    if args.only == ["profile"]:
        profile_only(args, impls, steps_for)
        return
    if args.only:
        unknown = set(args.only) - {i.key for i in impls}
        if unknown:
            raise SystemExit(
                f"unknown implementations {sorted(unknown)}; known: {[i.key for i in impls]}"
            )
        impls = [i for i in impls if i.key in args.only]

    machine = machine_info()
    print(
        f"machine: {machine['cpu']}, {machine['cores']} cores; rustcloth via {rust_py}", flush=True
    )
    bw_run = run_one(Impl("membw", "membw", "membw.py", 1), 0, 0, False, args.timeout)
    bw = {k: v for k, v in bw_run.items() if k.endswith("_gbs")}
    peak = measure_peak()
    print("compute peak:", peak, flush=True)
    print("memory bandwidth:", {k: round(v, 1) for k, v in bw.items()}, flush=True)

    results: dict[int, dict[str, dict]] = {}
    collider_results: dict[int, dict[str, dict]] = {}
    for n in args.sizes:
        steps = steps_for.get(n, 100)
        raw: dict[str, list[dict]] = {i.key: [] for i in impls}
        raw_c: dict[str, list[dict]] = {i.key: [] for i in impls if i.colliders}
        for rep in range(args.repeats):
            # alternate the order so that no implementation always runs first or last
            for impl in impls if rep % 2 == 0 else impls[::-1]:
                r = run_one(impl, n, steps, False, args.timeout)
                raw[impl.key].append(r)
                print(
                    f"  n={n} rep={rep} {impl.key}: "
                    + (
                        r["error"]
                        if "error" in r
                        else f"{r['ms_per_step']:.4g} ms/step, min y {r['min_y']:.5f}"
                    ),
                    flush=True,
                )
                if impl.colliders and not args.no_colliders:
                    rc = run_one(impl, n, steps, True, args.timeout)
                    raw_c[impl.key].append(rc)
                    print(
                        f"  n={n} rep={rep} {impl.key} +colliders: "
                        + (
                            rc["error"]
                            if "error" in rc
                            else f"{rc['ms_per_step']:.4g} ms/step, min y {rc['min_y']:.5f}"
                        ),
                        flush=True,
                    )
        results[n] = {k: median_result(v) for k, v in raw.items()}
        collider_results[n] = {k: median_result(v) for k, v in raw_c.items() if v}

    # Versions, from the runs themselves.
    built = next(
        (r["built"] for per in results.values() for r in per.values() if "built" in r), "?"
    )
    versions = {}
    for per_size in results.values():
        for key, r in per_size.items():
            if "version" in r:
                versions[key.split("-")[0]] = r["version"]

    timed = ", ".join(f"{steps_for.get(n, 100)} steps at {n}" for n in args.sizes)
    lines = [
        "# Peer benchmarks",
        "",
        "Written by `benches/peers/run.py` (`make bench-peers`); do not edit by hand.",
        "",
        "rustcloth against the same mass-spring cloth written with numpy "
        "(`rustcloth.reference`, in float32), Taichi (CPU) and NVIDIA newton "
        "(`SolverSemiImplicit`, Warp CPU device).",
        "",
        "## Scene",
        "",
        "N x N particles, spacing 0.01 m, particle mass 1e-3 kg, structural + shear + bend "
        "springs (12 neighbours, 6 springs per particle), k = 50 N/m for every family, spring "
        "damping 0.01 N s/m, no air drag, gravity -9.81 m/s^2, symplectic Euler, dt = 1e-3 s, "
        "plane xy (the cloth hangs), the two corners of the top edge pinned, no colliders. "
        f"5 warm-up steps, then {timed} "
        "timed. Each implementation runs in its own process (peak RSS = `ru_maxrss` of that "
        "process, so it includes the interpreter and the libraries); within each repeat the "
        "implementations run back to back (the order reversed every other repeat), "
        f"{args.repeats} repeat(s), medians reported; "
        "the ratios (ms/step / rustcloth's ms/step: > 1 means rustcloth is faster) are between "
        "medians of this one run. Cross-check: the lowest particle's y after the run, which "
        "must agree with rustcloth's to 1e-3 m. CPU s / wall s is the process's CPU time over "
        "the timed steps divided by their wall time: about the number of threads that were "
        "really busy. The machine is shared (2 cores, other jobs running), so absolute "
        "numbers are noisy and a second thread often finds its core taken; the ratios are "
        "what to read.",
        "",
        "## Machine and versions",
        "",
        f"* date: {dt.datetime.now(dt.UTC).strftime('%Y-%m-%d %H:%M UTC')}",
        f"* CPU: {machine['cpu']} (family {machine['cpu_family']}), {machine['cores']} cores "
        f"visible, {machine['mhz']} MHz reported, {machine['simd']}; Linux {machine['kernel']}",
        f"* Python {machine['python']}; "
        + "; ".join(f"{k}: {v}" for k, v in sorted(versions.items())),
        f"* rustcloth from `{rust_py}`, extension built {built} from the working tree; "
        f"repository at {git_describe()} when measured",
        "* threads: rustcloth `RAYON_NUM_THREADS=1` and `2` (separate processes); numpy 1 "
        "(elementwise ufuncs); Taichi `cpu_max_num_threads` = 1 and 2; newton/Warp CPU 1 "
        "(Warp runs CPU kernels on one thread)",
        "",
        "## Results",
        "",
    ]
    lines += summary_lines(args.sizes, impls, results)
    for n in args.sizes:
        lines += size_table(n, steps_for.get(n, 100), impls, results[n])
    if not args.no_colliders:
        lines += [
            "## With a floor and a sphere",
            "",
            "The same scenes plus a floor 5 mm below the cloth's lower edge (friction 0.3, "
            "thickness 2 mm) and a sphere of radius 0.2 x the cloth's width just under the "
            "middle of the lower edge (friction 0.2). Only rustcloth has colliders: numpy, "
            "Taichi and newton are n/a (newton has shape contacts, but through its collision "
            "pipeline with a penalty model that is not this one).",
            "",
        ]
        for n in args.sizes:
            coll = collider_results.get(n, {})
            table = size_table(n, steps_for.get(n, 100), [i for i in impls if i.colliders], coll)
            # speed-ups within this table are between rustcloth runs; add the no-collider cost
            lines += table[:-1]
            for impl in impls:
                if not impl.colliders:
                    lines.append(f"| {impl.label} | {impl.threads} | n/a |" + " |" * 10)
            for key in ("rustcloth-1", "rustcloth-2"):
                a, b = coll.get(key, {}), results[n].get(key, {})
                if "ms_per_step" in a and "ms_per_step" in b:
                    lines.append("")
                    lines.append(
                        f"{key}: colliders cost x{a['ms_per_step'] / b['ms_per_step']:.2f} "
                        "the collider-free step time."
                    )
            lines.append("")
    if not args.no_colliders:
        lines += profile_lines(
            args.sizes, impls, results, collider_results, "the rustcloth runs timed above"
        )
    lines += roofline_lines(args.sizes, impls, results, bw, machine, peak)
    lines += [
        "## Raw per-repeat ms/step",
        "",
        "```",
        *(
            f"{n} {k}: {[round(x, 4) for x in r.get('ms_all', [])]}"
            for n in args.sizes
            for k, r in results[n].items()
        ),
        "```",
        "",
    ]
    text = "\n".join(lines)
    print()
    print(text)
    if not args.no_write:
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_text(text)
        print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
