"""The stiff-cloth benchmark of issue 14: rustcloth's implicit solvers against their own
references, the code before the multigrid preconditioner, and newton's VBD, on the scene of
``stiff_scene.py``; writes ``docs/stiff.md`` and ``docs/stiff.png``.

    .venv/bin/python benches/peers/stiff.py                  # everything (about 40 minutes)
    .venv/bin/python benches/peers/stiff.py --quick          # a few frames of each, to check
    .venv/bin/python benches/peers/stiff.py --report-only    # rewrite the docs from the JSON
    .venv/bin/python benches/peers/stiff.py --before /tmp/base/.venv/bin/python

Every configuration runs in its own process (``RAYON_NUM_THREADS`` set per run), one after
the other in one session, and the results land in ``benches/peers/stiff_results.json``.
``--before PYTHON`` names an interpreter whose rustcloth is the code before this work (build
commit f63df6d into a venv); without it the report keeps the before-rows of the last run that
had them. newton runs under ``--newton-python`` (default ``.venv-peers/bin/python``, made by
``benches/peers/setup.sh``); the plot needs matplotlib (the ``[study]`` extra).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import platform
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
RESULTS = HERE / "stiff_results.json"
sys.path.insert(0, str(HERE))

from stiff_scene import DT, K, particle_mass  # noqa: E402

TOL = 1e-4
REFERENCE_TOL = 1e-8
NEWTON = [(1, 10), (10, 10), (10, 20), (20, 10), (20, 20), (40, 10)]
# "Equal mean stretch": within this fraction of the rustcloth reference's. Converged solvers
# with different time steps (newton's substeps) swing differently, so their mean stretch over
# the first second differs by several per cent even between newton's converged settings.
EQUAL = 0.10
PD_ITERATIONS = [10, 20, 40]
PD_REFERENCE = 300


def runs(quick: bool, before: str | None) -> list[dict]:
    """Every configuration: a dict of the implementation, its arguments and its threads."""
    frames = 6 if quick else 60
    out: list[dict] = []

    def rust(name, threads, n=128, f=frames, python=None, **kw):
        out.append({"key": name, "impl": "rustcloth", "threads": threads, "n": n, "frames": f,
                    "python": python, "args": kw})

    rust("multigrid-2", 2, preconditioner="multigrid", tolerance=TOL)
    rust("multigrid-1", 1, preconditioner="multigrid", tolerance=TOL)
    rust("reference", 2, preconditioner="multigrid", tolerance=REFERENCE_TOL)
    rust("block_jacobi-2", 2, preconditioner="block_jacobi", tolerance=TOL)
    rust("jacobi-2", 2, preconditioner="jacobi", tolerance=TOL)
    if before:
        rust("before-2", 2, python=before, tolerance=TOL)
        rust("before-1", 1, python=before, tolerance=TOL)
        rust("before-capped-2", 2, python=before, tolerance=TOL, max_iterations=200)
    # The explicit alternative: as many substeps as the stability report asks for.
    for integrator in ("symplectic_euler", "verlet"):
        rust(f"{integrator}-1", 1, integrator=integrator, substeps="auto")
        rust(f"{integrator}-2", 2, integrator=integrator, substeps="auto")
    for k in PD_ITERATIONS:
        rust(f"pd{k}-2", 2, integrator="projective_dynamics", pd_iterations=k)
    rust("pd-reference", 2, integrator="projective_dynamics",
         pd_iterations=12 if quick else PD_REFERENCE)
    for substeps, iterations in NEWTON[:2] if quick else NEWTON:
        out.append({"key": f"newton-{substeps}x{iterations}", "impl": "newton", "threads": 1,
                    "n": 128, "frames": frames,
                    "args": {"substeps": substeps, "iterations": iterations}})
    # Growth with size: the same cloth, finer.
    for n, f in [(256, 3 if quick else 30), (512, 2 if quick else 12)]:
        rust(f"multigrid-2-{n}", 2, n=n, f=f, preconditioner="multigrid", tolerance=TOL)
        rust(f"pd20-2-{n}", 2, n=n, f=2 if quick else (10 if n == 256 else 3),
             integrator="projective_dynamics", pd_iterations=20)
    for n, f in [(256, 2 if quick else 10), (512, 2 if quick else 4)]:
        rust(f"verlet-2-{n}", 2, n=n, f=f, integrator="verlet", substeps="auto")
    rust("jacobi-2-256", 2, n=256, f=2 if quick else 8, preconditioner="jacobi", tolerance=TOL)
    rust("block_jacobi-2-256", 2, n=256, f=2 if quick else 8, preconditioner="block_jacobi",
         tolerance=TOL)
    return out


def command(run: dict, rust_python: str, newton_python: str) -> list[str]:
    if run["impl"] == "newton":
        a = run["args"]
        return [newton_python, str(HERE / "impl_newton_vbd.py"), "--n", str(run["n"]),
                "--frames", str(run["frames"]), "--substeps", str(a["substeps"]),
                "--iterations", str(a["iterations"]), "--name", run["key"]]
    cmd = [run["python"] or rust_python, str(HERE / "impl_rustcloth_stiff.py"),
           "--n", str(run["n"]), "--frames", str(run["frames"]), "--name", run["key"]]
    for key, value in run["args"].items():
        cmd += ["--" + key.replace("_", "-"), str(value)]
    return cmd


def execute(run: dict, rust_python: str, newton_python: str) -> dict:
    env = {**os.environ, "RAYON_NUM_THREADS": str(run["threads"]), "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.run(command(run, rust_python, newton_python), capture_output=True,
                          text=True, env=env, cwd=str(ROOT), timeout=3600)
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return {**json.loads(line[len("RESULT "):]), "threads": run["threads"]}
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return {"error": f"exit {proc.returncode}: " + " | ".join(tail)}


def averaged(result: dict) -> tuple[float, float]:
    """Mean stretch averaged over the run's samples, and the largest stretch of any sample."""
    samples = result.get("samples") or []
    if not samples:
        return math.nan, math.nan
    return (sum(s["mean_stretch"] for s in samples) / len(samples),
            max(s["max_stretch"] for s in samples))


# ----- the report --------------------------------------------------------------------------

def fmt(x, spec=".1f", missing="—"):
    return missing if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def verdict(ok: bool) -> str:
    return "**met**" if ok else "**missed**"


def report(data: dict, out: Path) -> None:
    r = data["results"]
    get = r.get
    ref = get("reference", {})
    ref_mean, ref_max = averaged(ref)
    lines = [
        "# Stiff cloth at a display frame's step",
        "",
        "Generated by `benches/peers/stiff.py` from `benches/peers/stiff_results.json`; do not "
        "edit by hand. Scene (`benches/peers/stiff_scene.py`): a square metre of 0.5 kg cloth "
        f"hung by two corners of its horizontal start, {K[0]:g} / {K[1]:g} / {K[2]:g} N/m "
        "structural / shear / bending springs, 0.01 N s/m damping along them, "
        f"dt = 1/60 s, one step per frame, so `k_structural dt^2 / m` = "
        f"{K[0] * DT**2 / particle_mass(128):.0f} at 128 x 128 (issue 14 asks for >= 100). "
        "Each run drapes the cloth from rest for "
        f"{ref.get('frames', '?')} frames; **stretch** is `l / L - 1` of the structural "
        "springs, its mean over the cloth averaged over a sample every 10 frames, and the "
        "largest over all samples.",
        "",
        f"Measured {data['date']} on {data['machine']}, commit {data['commit']}. The machine "
        "is shared by several agents: the load average during each run is given, and CPU "
        "time (all threads) per frame beside wall time, which is the steadier of the two under "
        "load. Ratios are between runs of this session.",
        "",
    ]
    # Targets.
    mg2, mg1 = get("multigrid-2", {}), get("multigrid-1", {})
    mg_mean, mg_max = averaged(mg2)
    its = mg2.get("iterations_mean", math.nan)
    dmean = abs(mg_mean / ref_mean - 1) if ref_mean else math.nan
    dmax = abs(mg_max / ref_max - 1) if ref_max else math.nan
    lines += ["## Targets at 128 x 128", "",
              "| what | target | measured | |", "|---|---|---|---|",
              f"| CG iterations per frame to 1e-4, multigrid | <= 30 | {fmt(its)} mean, "
              f"{mg2.get('iterations_max', '—')} most | {verdict(its <= 30)} |",
              f"| time per frame, 2 threads | <= 16 ms | {fmt(mg2.get('ms_per_frame'))} ms wall "
              f"(load {fmt(mg2.get('load'), '.1f')}), {fmt(mg2.get('cpu_ms_per_frame'))} ms CPU | "
              f"{verdict(mg2.get('ms_per_frame', 1e9) <= 16)} |",
              f"| mean stretch against the 1e-8 solve | within 1 % | {fmt(100 * dmean, '.2f')} % "
              f"| {verdict(dmean <= 0.01)} |",
              f"| largest stretch against the 1e-8 solve | within 1 % | {fmt(100 * dmax, '.2f')} % "
              f"| {verdict(dmax <= 0.01)} |"]
    newton_rows = sorted(
        (v for k, v in r.items() if k.startswith("newton-") and "error" not in v),
        key=lambda v: v["substeps"] * v["iterations"])
    match = None
    for v in newton_rows:
        m, _ = averaged(v)
        if ref_mean and abs(m / ref_mean - 1) <= EQUAL:
            match = v
            break
    if match and mg1:
        ratio = match["ms_per_frame"] / mg1["ms_per_frame"]
        cpu_ratio = match["cpu_ms_per_frame"] / mg1["cpu_ms_per_frame"]
        lines.append(
            f"| newton VBD at equal mean stretch (within {100 * EQUAL:.0f} %), thread for thread "
            f"| 50x | "
            f"{match['substeps']} substeps x {match['iterations']} iterations: "
            f"{fmt(ratio, '.0f')}x wall, {fmt(cpu_ratio, '.0f')}x CPU | {verdict(ratio >= 50)} |")
    elif newton_rows and mg1:
        best = newton_rows[-1]
        m, _ = averaged(best)
        ratio = best["ms_per_frame"] / mg1["ms_per_frame"]
        lines.append(
            f"| newton VBD at equal mean stretch, thread for thread | 50x | no configuration "
            f"run came within {100 * EQUAL:.0f} % of the reference's mean stretch; the most "
            f"converged "
            f"({best['substeps']} x {best['iterations']}) is "
            f"{fmt(100 * (m / ref_mean - 1), '+.0f')} % off and {fmt(ratio, '.0f')}x slower | "
            "**not measured at equal stretch** |")
    lines += [""]
    # The solvers at 128.
    lines += ["## Every solver at 128 x 128", "",
              "| run | threads | it/frame (most) | ms/frame wall | ms/frame CPU | setup ms | "
              "solve ms | mean stretch | vs ref | largest stretch | vs ref | load |",
              "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"]
    order = ["multigrid-2", "multigrid-1", "reference", "block_jacobi-2", "jacobi-2",
             "before-2", "before-1", "before-capped-2", "symplectic_euler-2",
             "symplectic_euler-1", "verlet-2", "verlet-1"]
    order += [f"pd{k}-2" for k in PD_ITERATIONS] + ["pd-reference"]
    labels = {
        "multigrid-2": "implicit_euler, multigrid, 1e-4",
        "multigrid-1": "implicit_euler, multigrid, 1e-4",
        "reference": "implicit_euler, multigrid, 1e-8 (reference)",
        "block_jacobi-2": "implicit_euler, block Jacobi, 1e-4",
        "jacobi-2": "implicit_euler, Jacobi, 1e-4",
        "before-2": "before (f63df6d): Jacobi CG, 1e-4",
        "before-1": "before (f63df6d): Jacobi CG, 1e-4",
        "before-capped-2": "before (f63df6d): Jacobi CG, 1e-4, its default cap of 200",
        "pd-reference": f"projective_dynamics, {PD_REFERENCE} iterations (its reference)",
        "symplectic_euler-2": "symplectic_euler, substeps it needs",
        "symplectic_euler-1": "symplectic_euler, substeps it needs",
        "verlet-2": "verlet, substeps it needs",
        "verlet-1": "verlet, substeps it needs",
    }
    pd_ref_mean, pd_ref_max = averaged(get("pd-reference", {}))
    for key in order:
        v = get(key)
        if not v or "error" in v:
            continue
        mean, mx = averaged(v)
        is_pd = key.startswith("pd")
        rm, rx = (pd_ref_mean, pd_ref_max) if is_pd else (ref_mean, ref_max)
        label = labels.get(key) or f"projective_dynamics, {key[2:-2]} iterations"
        if v.get("substeps", 1) > 1:
            label += f" ({v['substeps']})"
        lines.append(
            f"| {label} | {v['threads']} | {fmt(v.get('iterations_mean'))} "
            f"({v.get('iterations_max') or '—'}) | {fmt(v['ms_per_frame'])} | "
            f"{fmt(v['cpu_ms_per_frame'])} | {fmt(v.get('setup_ms_per_frame'))} | "
            f"{fmt(v.get('solve_ms_per_frame'))} | {fmt(mean, '.5f')} | "
            f"{fmt(100 * (mean / rm - 1), '+.2f')} % | {fmt(mx, '.3f')} | "
            f"{fmt(100 * (mx / rx - 1), '+.2f')} % | {fmt(v['load'])} |")
    lines += ["",
              "`vs ref`: against the implicit-Euler solve at 1e-8 for implicit Euler, against "
              f"{PD_REFERENCE} local-global iterations for projective dynamics (which solves the "
              "backward-Euler step exactly rather than linearised once, so its converged "
              "stretch differs from implicit Euler's by the linearisation: "
              f"{fmt(100 * (pd_ref_mean / ref_mean - 1), '+.1f')} % in the mean). "
              "`setup`: assembly and preconditioner (implicit Euler), factorisations "
              "(projective dynamics, all in the first frame, so averaged here over the run); "
              "`solve`: the iterations.", ""]
    # newton.
    lines += ["## newton's VBD, side by side", "",
              "The same mass-spring model in NVIDIA newton 1.8 (`SolverVBD`, Warp CPU device, one "
              "thread), `benches/peers/impl_newton_vbd.py`; each frame is `substeps` VBD steps "
              "of `iterations` iterations. Thread for thread means against rustcloth's "
              "one-thread run "
              f"({fmt(mg1.get('ms_per_frame'))} ms wall, "
              f"{fmt(mg1.get('cpu_ms_per_frame'))} ms CPU per frame).", "",
              "| substeps x iterations | ms/frame wall | ms/frame CPU | mean stretch "
              "| vs rustcloth ref | largest stretch | vs rustcloth ref | x rustcloth (wall) "
              "| x rustcloth (CPU) | load |", "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|"]
    for v in newton_rows:
        mean, mx = averaged(v)
        lines.append(
            f"| {v['substeps']} x {v['iterations']} | {fmt(v['ms_per_frame'], '.0f')} | "
            f"{fmt(v['cpu_ms_per_frame'], '.0f')} | {fmt(mean, '.5f')} | "
            f"{fmt(100 * (mean / ref_mean - 1), '+.0f')} % | {fmt(mx, '.3f')} | "
            f"{fmt(100 * (mx / ref_max - 1), '+.0f')} % | "
            f"{fmt(v['ms_per_frame'] / mg1['ms_per_frame'], '.0f')}x | "
            f"{fmt(v['cpu_ms_per_frame'] / mg1['cpu_ms_per_frame'], '.0f')}x | "
            f"{fmt(v['load'])} |")
    lines += [""]
    # Growth.
    lines += ["## Growth with size", "",
              "The same cloth, finer: `k dt^2 / m` grows with `n^2` (4600, 18500, 74000).", "",
              "| n x n | solver | frames | it/frame (most) | ms/frame wall | ms/frame CPU | "
              "setup ms | solve ms | factorisation s | load |",
              "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|"]
    growth = [("multigrid-2", 128), ("multigrid-2-256", 256), ("multigrid-2-512", 512),
              ("block_jacobi-2", 128), ("block_jacobi-2-256", 256), ("jacobi-2", 128),
              ("jacobi-2-256", 256), ("verlet-2", 128), ("verlet-2-256", 256),
              ("verlet-2-512", 512), ("pd20-2", 128), ("pd20-2-256", 256),
              ("pd20-2-512", 512)]
    for key, n in growth:
        v = get(key)
        if not v or "error" in v:
            continue
        if key.startswith("pd"):
            solver = "projective dynamics, 20 iterations"
        elif key.startswith("verlet"):
            solver = f"Verlet, {v.get('substeps')} substeps (the fewest stable)"
        else:
            solver = "implicit Euler, " + key.split("-")[0].replace("_", " ") + ", 1e-4"
        factor = (v.get("setup_ms_per_frame") or 0) * v["frames"] / 1e3 / max(
            v.get("factorizations") or 1, 1) if key.startswith("pd") else None
        lines.append(
            f"| {n} | {solver} | {v['frames']} | {fmt(v.get('iterations_mean'))} "
            f"({v.get('iterations_max') or '—'}) | {fmt(v['ms_per_frame'])} | "
            f"{fmt(v['cpu_ms_per_frame'])} | {fmt(v.get('setup_ms_per_frame'))} | "
            f"{fmt(v.get('solve_ms_per_frame'))} | {fmt(factor, '.2f')} | {fmt(v['load'])} |")
    lines += ["", "![time per frame and iterations against size](stiff.png)", ""]
    lines += reading(data)
    out.write_text("\n".join(lines) + "\n")


def reading(data: dict) -> list[str]:
    """Sentences computed from the numbers."""
    r = data["results"]
    text = ["## Reading", ""]
    mg, bj, jac = r.get("multigrid-2"), r.get("block_jacobi-2"), r.get("jacobi-2")
    if mg and bj and jac:
        text.append(
            f"- **Preconditioners.** To 1e-4 at 128 x 128, Jacobi takes "
            f"{jac['iterations_mean']:.0f} CG iterations a frame, block Jacobi "
            f"{bj['iterations_mean']:.0f} "
            f"({100 * (1 - bj['iterations_mean'] / jac['iterations_mean']):.0f} % fewer), "
            f"multigrid {mg['iterations_mean']:.1f}; per frame that is "
            f"{jac['cpu_ms_per_frame'] / mg['cpu_ms_per_frame']:.0f}x and "
            f"{bj['cpu_ms_per_frame'] / mg['cpu_ms_per_frame']:.0f}x the multigrid's CPU time.")
    before, capped = r.get("before-2"), r.get("before-capped-2")
    if mg and before and "error" not in before:
        text.append(
            f"- **Before and after.** The code before this work needs "
            f"{before['iterations_mean']:.0f} iterations and {before['ms_per_frame']:.0f} ms "
            f"a frame (2 threads) to reach 1e-4"
            + (f"; at its default cap of 200 iterations it stops short on "
               f"{capped['not_converged']} of {capped['frames']} frames and the mean stretch is "
               f"{100 * (averaged(capped)[0] / averaged(r['reference'])[0] - 1):+.1f} % off"
               if capped and capped.get("not_converged") is not None else "")
            + f". After: {mg['iterations_mean']:.1f} iterations and "
            f"{mg['ms_per_frame']:.1f} ms, {before['ms_per_frame'] / mg['ms_per_frame']:.0f}x "
            f"faster.")
    mg1 = r.get("multigrid-1")
    if mg and mg1:
        text.append(
            f"- **Threads under load.** During these runs the load average was "
            f"{mg['load']:.1f} on {os.cpu_count()} cores: two threads ran the frame in "
            f"{mg['ms_per_frame']:.1f} ms, one in {mg1['ms_per_frame']:.1f} ms, with "
            f"{mg['cpu_ms_per_frame']:.1f} and {mg1['cpu_ms_per_frame']:.1f} ms of CPU. The "
            "two threads did not get two cores; on two free cores the CPU time would be split "
            "between them (a projection, not a measurement).")
    ve, ve1 = r.get("verlet-2"), r.get("verlet-1")
    big = [(n, r.get(f"verlet-2-{n}"), r.get(f"multigrid-2-{n}")) for n in (256, 512)]
    if ve and ve1 and mg and mg1:
        ref_mean, ref_max = averaged(r["reference"])
        text.append(
            f"- **Explicit substepping.** Verlet with the {ve['substeps']} substeps the "
            f"stability estimate asks for takes {ve['ms_per_frame']:.1f} ms a frame (2 "
            f"threads, {ve1['ms_per_frame']:.1f} ms on one) against implicit Euler's "
            f"{mg['ms_per_frame']:.1f} ({mg1['ms_per_frame']:.1f}): on this cloth at 128 x 128 "
            f"it is the faster, and with steps of 1/{round(1 / DT) * ve['substeps']} s it is the "
            "more accurate (its stretch differs from the implicit reference's by "
            f"{100 * (averaged(ve)[0] / ref_mean - 1):+.0f} % in the mean and "
            f"{100 * (averaged(ve)[1] / ref_max - 1):+.0f} % at the largest: "
            "backward Euler at 1/60 s damps the swing; docs/accuracy.md measures both against "
            "a float64 reference). Its cost grows as n^3 (substeps as n, for a stiffest mode "
            "whose frequency grows with n): "
            + ", ".join(f"{n} x {n}: {v['substeps']} substeps, {v['ms_per_frame']:.0f} ms "
                        f"against the multigrid's {m['ms_per_frame']:.0f}"
                        for n, v, m in big if v and m and "error" not in v)
            + ". Implicit Euler is the choice where substeps run out: finer or stiffer cloth, "
            "and any step that must not blow up.")
    sizes = [(n, r.get(k)) for n, k in [(128, "multigrid-2"), (256, "multigrid-2-256"),
                                         (512, "multigrid-2-512")] if r.get(k)]
    if len(sizes) >= 2:
        (n0, a), (n1, b) = sizes[0], sizes[-1]
        growth = b["cpu_ms_per_frame"] / a["cpu_ms_per_frame"]
        text.append(
            f"- **Size.** From {n0} to {n1} (x{(n1 / n0) ** 2:.0f} particles, "
            f"x{(n1 / n0) ** 2:.0f} stiffer) the multigrid's iterations go from "
            f"{a['iterations_mean']:.1f} to {b['iterations_mean']:.1f} and its CPU time per "
            f"frame grows {growth:.0f}x: "
            + ("close to linear in the particles." if growth < 1.5 * (n1 / n0) ** 2
               else "faster than the particles."))
    pds = [r.get(f"pd{k}-2") for k in PD_ITERATIONS]
    pdr = r.get("pd-reference")
    if all(pds) and pdr and mg:
        ref_mean, _ = averaged(pdr)
        errs = [abs(averaged(p)[0] / ref_mean - 1) for p in pds]
        text.append(
            "- **Projective dynamics.** Its mean stretch is "
            + ", ".join(f"{100 * e:.1f} %" for e in errs)
            + f" from its converged value after {', '.join(map(str, PD_ITERATIONS))} "
            f"iterations, at "
            f"{', '.join(format(p['cpu_ms_per_frame'], '.0f') for p in pds)} ms CPU a frame "
            f"against implicit Euler's {mg['cpu_ms_per_frame']:.0f}. Each iteration is "
            "cheap (a pass over the springs, two triangular solves), but its constant matrix "
            "is much stiffer across the springs than the true Hessian, so it converges linearly "
            "and slowly on stiff cloth, and any change of pins or cuts refactors the matrix "
            "(see the factorisation column).")
    pd512 = r.get("pd20-2-512")
    if pd512 and "error" not in pd512:
        f = (pd512.get("setup_ms_per_frame") or 0) * pd512["frames"] / 1e3
        text.append(
            "- **Where the factorisation stops being interactive.** Projective dynamics' "
            "matrix (scalar, one unknown per particle) factors in "
            + ", ".join(
                f"{(r[k].get('setup_ms_per_frame') or 0) * r[k]['frames'] / 1e3:.2f} s at {n}"
                for k, n in [("pd20-2", 128), ("pd20-2-256", 256), ("pd20-2-512", 512)]
                if r.get(k) and "error" not in r[k])
            + f": a pin or a cut at 512 x 512 stalls the simulation for {f:.1f} s. Implicit "
            "Euler's matrix changes every step and is three times larger per particle (nine "
            "times the entries), so factoring it each step is out of the question at any of "
            "these sizes; the multigrid preconditioner needs no factorisation.")
    return text


def plot(data: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    r = data["results"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
    for keys, label in [
        (["multigrid-2", "multigrid-2-256", "multigrid-2-512"], "implicit Euler, multigrid"),
        (["block_jacobi-2", "block_jacobi-2-256"], "implicit Euler, block Jacobi"),
        (["jacobi-2", "jacobi-2-256"], "implicit Euler, Jacobi"),
        (["pd20-2", "pd20-2-256", "pd20-2-512"], "projective dynamics, 20 it."),
        (["verlet-2", "verlet-2-256", "verlet-2-512"], "Verlet, fewest stable substeps"),
    ]:
        rows = [r[k] for k in keys if r.get(k) and "error" not in r[k]]
        if not rows:
            continue
        ns = [v["n"] for v in rows]
        a1.loglog(ns, [v["cpu_ms_per_frame"] for v in rows], "o-", label=label)
        if not keys[0].startswith(("pd", "verlet")):
            a2.semilogx(ns, [v["iterations_mean"] for v in rows], "o-", label=label)
    a1.axhline(16, color="k", lw=0.8, ls=":", label="16 ms (real time)")
    for a in (a1, a2):
        a.set_xlabel("particles per side")
        a.set_xticks([128, 256, 512], ["128", "256", "512"])
        a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        a.grid(True, which="both", alpha=0.3)
    a1.set_ylabel("CPU ms per 1/60 s frame (2 threads)")
    a2.set_ylabel("CG iterations per frame to 1e-4")
    a2.set_yscale("log")
    a1.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--before", default=None, help="python with the rustcloth before this work")
    p.add_argument("--only", nargs="*", default=None, help="run only these keys")
    p.add_argument("--rust-python", default=sys.executable)
    p.add_argument("--newton-python", default=str(ROOT / ".venv-peers/bin/python"))
    p.add_argument("--out", type=Path, default=ROOT / "docs")
    args = p.parse_args()
    data = json.loads(RESULTS.read_text()) if RESULTS.exists() else {"results": {}}
    if not args.report_only:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=str(ROOT)).stdout.strip()
        data.update(date=dt.date.today().isoformat(), commit=commit,
                    machine=f"{platform.processor() or platform.machine()}, "
                            f"{os.cpu_count()} cores")
        for run in runs(args.quick, args.before):
            if args.only and run["key"] not in args.only:
                continue
            print(f"{run['key']:<22}", end=" ", flush=True)
            result = execute(run, args.rust_python, args.newton_python)
            data["results"][run["key"]] = result
            print(result.get("error") or f"{result['ms_per_frame']:.1f} ms/frame, "
                  f"{result.get('iterations_mean', float('nan')):.1f} it, load {result['load']}",
                  flush=True)
            RESULTS.write_text(json.dumps(data, indent=1) + "\n")
    args.out.mkdir(parents=True, exist_ok=True)
    report(data, args.out / "stiff.md")
    try:
        plot(data, args.out / "stiff.png")
    except ImportError:
        print("the plot needs matplotlib: pip install 'rustcloth[study]'", file=sys.stderr)
    print(f"wrote {args.out / 'stiff.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
