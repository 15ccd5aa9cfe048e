"""The accuracy study's report: tables, a reading computed from the numbers
(``accuracy.md``) and the plot (``accuracy.png``), from what :mod:`rustcloth.study.measure`
measured. The plot needs matplotlib, imported only here when it is drawn."""

from __future__ import annotations

import math
import os
import platform
from pathlib import Path

from .measure import EXPLICIT, OrderResult, Run


def fmt_dt(dt: float) -> str:
    return f"1/{1 / dt:.0f}"


def fmt(x: float, spec: str = ".1e") -> str:
    return "—" if x is None or math.isnan(x) else format(x, spec)


def pareto(points: list[tuple[float, float, Run]]) -> list[Run]:
    """Runs not beaten by another run that is both faster and more accurate."""
    front, best = [], math.inf
    for _, error, run in sorted(points, key=lambda p: (p[0], p[1])):
        if error < best:
            front.append(run)
            best = error
    return front


def front_of(runs: list[Run]) -> list[Run]:
    return pareto([(r.wall_per_second, r.error, r) for r in runs
                   if r.stable and not math.isnan(r.error)])


def reading(orders: list[OrderResult], stiff: list[Run], integrators: list[str]) -> list[str]:
    """Every sentence computed from the numbers."""
    text = []
    by_regime: dict[bool, dict[str, list[float]]] = {True: {}, False: {}}
    for res in orders:
        for integrator, s in res.slopes.items():
            if not math.isnan(s):
                by_regime[res.case.damped].setdefault(integrator, []).append(s)

    def span(values: list[float]) -> str:
        return (f"{min(values):.2f}" if len(values) == 1 or max(values) - min(values) < 0.005
                else f"{min(values):.2f} to {max(values):.2f}")

    for integrator in integrators:
        cons, damp = by_regime[False].get(integrator), by_regime[True].get(integrator)
        if not cons and not damp:
            continue
        parts = []
        if cons:
            parts.append(f"{span(cons)} without velocity-dependent forces")
        if damp:
            parts.append(f"{span(damp)} with spring damping and air drag")
        sentence = f"- **{integrator}**: measured order " + "; ".join(parts) + "."
        if integrator == "verlet" and cons and damp:
            if min(cons) >= 1.7 and max(damp) <= 1.4:
                sentence += (" Second order only where the forces depend on positions alone: "
                             "its velocity `(x_n - x_{n-1}) / h` lags half a step, and damping "
                             "and drag fed that velocity make it first order in positions.")
            elif min(cons) >= 1.7 and min(damp) >= 1.7:
                sentence += " Second order in both regimes at these steps."
            else:
                sentence += " Not cleanly second order in either regime at these steps."
        if integrator == "rk4" and (cons or damp):
            best = max((cons or []) + (damp or []))
            if best >= 3.5:
                sentence += " Fourth order where its errors stand above the float32 floor."
            else:
                sentence += (" Its finer steps fall to the float32 floor, which flattens the "
                             "fitted slope.")
        if integrator in ("implicit_euler", "projective_dynamics") and min(
                (cons or []) + (damp or [])) < 0.85:
            sentence += (" Below one where the errors have not left the regime in which "
                         "backward Euler damps the motion away (the stretched sheet's vibration "
                         "at these steps): first order only at finer steps.")
        text.append(sentence)
    for res in orders:
        front = front_of(res.runs)
        if front:
            names = sorted({r.integrator for r in front})
            text.append(f"- **{res.case.label}**: float32 floor {res.floor:.1e} m; the Pareto "
                        f"front is made of {', '.join(names)}.")
    if stiff:
        stable = [r for r in stiff if r.stable and not math.isnan(r.error)]
        front = front_of(stiff)
        if front:
            text.append(
                "- **Stiff cloth at 1/60 s**: the Pareto front (fastest way to each error) is "
                + ", ".join(f"{r.method}"
                            + (f" with {r.substeps} substeps" if r.substeps > 1 else "")
                            + f" ({r.error:.1e} m, {1e3 * r.wall_per_second:.0f} ms/s)"
                            for r in front) + ".")
        for limit in (1e-2, 1e-3, 1e-4, 1e-5):
            within = [r for r in stable if r.error <= limit]
            if not within:
                text.append(f"  - to an error of at most {limit:g} m: nothing run gets there.")
                continue
            cheapest = min(within, key=lambda r: r.wall_per_second)
            text.append(
                f"  - to an error of at most {limit:g} m the cheapest is {cheapest.method}"
                + (f" with {cheapest.substeps} substeps" if cheapest.substeps > 1 else "")
                + f" ({cheapest.error:.1e} m at {1e3 * cheapest.wall_per_second:.0f} ms per "
                  "simulated second).")
        implicit = [r for r in stable if r.integrator in ("implicit_euler", "projective_dynamics")
                    and r.substeps == 1]
        explicit = [r for r in stable if r.integrator in EXPLICIT]
        if implicit and explicit:
            best_i = min(implicit, key=lambda r: r.error)
            cheap_e = min(explicit, key=lambda r: r.wall_per_second)
            text.append(
                f"- At one step per frame the implicit solvers' best error is {best_i.error:.1e} m "
                f"({best_i.method}, {1e3 * best_i.wall_per_second:.0f} ms/s): backward Euler "
                f"damps the cloth's motion at 1/60 s. The cheapest explicit run, "
                f"{cheap_e.method} with {cheap_e.substeps} substeps, is "
                f"{best_i.error / cheap_e.error:.0f} times more accurate at "
                f"{cheap_e.wall_per_second / best_i.wall_per_second:.2f} times the cost"
                + (". On this cloth substepping an explicit method is the better choice; the "
                   "implicit solvers earn their place where no substep count is safe (stiffer "
                   "or lighter cloth, fast drags, a step that must never blow up)."
                   if cheap_e.error < best_i.error and
                   cheap_e.wall_per_second <= 2 * best_i.wall_per_second else "."))
        unstable = sorted({r.method for r in stiff if not r.stable})
        if unstable:
            text.append(f"- Unstable at 1/60 s with the substeps given: {', '.join(unstable)}.")
    return text


def write_report(orders: list[OrderResult], stiff: list[Run], stiff_ratio: float,
                 integrators: list[str], out: Path, elapsed: float) -> None:
    lines = [
        "# Accuracy versus time",
        "",
        "Generated by `python -m rustcloth accuracy --out docs` (`make accuracy`); do not edit "
        "by hand.",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; the "
        f"study took {elapsed:.0f} s. Wall times are from one run on a shared machine: compare "
        "them within a table, not across reports.",
        "",
        "**error**: RMS particle distance from a float64 reference (the same model in numpy, "
        "adaptive Dormand-Prince 5(4) to 1e-11, none of the integrators under test) at the "
        "case's time. **ms/s**: wall-clock milliseconds of stepping per simulated second. "
        "**—**: unstable (diverged or left a 10 m box). **floor**: the smallest error any "
        "integrator reached on the case, the float32 round-off level. **order**: the slope of log "
        "error against log dt between the two finest steps of the clean stretch of each curve: "
        "the longest run of consecutive steps whose errors stand above three times the floor, "
        "below 1 cm, and fall from step to step (round-off grows with the step count).",
        "",
        "## Measured orders",
        "",
        "| case | time | floor | " + " | ".join(integrators) + " |",
        "|---|---|---|" + "---|" * len(integrators),
    ]
    for res in orders:
        lines.append(f"| {res.case.label} | {res.case.time:g} s | {res.floor:.1e} | "
                     + " | ".join(fmt(res.slopes.get(i, math.nan), ".2f") for i in integrators)
                     + " |")
    lines += ["", "## Largest stable dt of the ladder", "",
              "| case | " + " | ".join(integrators) + " |",
              "|---|" + "---|" * len(integrators)]
    for res in orders:
        cells = []
        for integrator in integrators:
            stable = [r.dt for r in res.runs if r.integrator == integrator and r.stable]
            cells.append(fmt_dt(max(stable)) if stable else "none")
        lines.append(f"| {res.case.label} | " + " | ".join(cells) + " |")
    lines += ["", "## Pareto fronts (fastest way to each accuracy)", ""]
    for res in orders:
        lines.append(f"- **{res.case.label}**: " + ", ".join(
            f"{r.integrator} {fmt_dt(r.dt)} ({fmt(r.error)} m, {1e3 * r.wall_per_second:.0f} ms/s)"
            for r in front_of(res.runs)))
    for res in orders:
        lines += ["", f"## {res.case.label}", "",
                  "| integrator | dt | error [m] | ms/s | solver it/step |",
                  "|---|---|---|---|---|"]
        for r in res.runs:
            lines.append(f"| {r.integrator} | {fmt_dt(r.dt)} | {fmt(r.error)} | "
                         f"{fmt(1e3 * r.wall_per_second, '.1f')} | {fmt(r.iterations, '.1f')} |")
    if stiff:
        lines += ["", f"## Stiff cloth at 1/60 s ({stiff[0].case}, k dt^2 / m = "
                  f"{stiff_ratio:.0f})", "",
                  "| method | substeps | error [m] | ms/s | solver it/substep |",
                  "|---|---|---|---|---|"]
        for r in stiff:
            lines.append(f"| {r.method} | {r.substeps} | {fmt(r.error)} | "
                         f"{fmt(1e3 * r.wall_per_second, '.0f')} | {fmt(r.iterations, '.1f')} |")
    lines += ["", "## Reading", ""] + reading(orders, stiff, integrators)
    lines += ["", "![error against dt and against time](accuracy.png)", ""]
    out.write_text("\n".join(lines))


def plot(orders: list[OrderResult], stiff: list[Run], integrators: list[str],
         out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = len(orders) + (1 if stiff else 0)
    cols = min(3, panels)
    rows = math.ceil(panels / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.3 * cols, 3.5 * rows), squeeze=False)
    colors = dict(zip(integrators, plt.rcParams["axes.prop_cycle"].by_key()["color"],
                      strict=False))
    for ax, res in zip(axes.flat, orders, strict=False):
        for integrator in integrators:
            rs = [r for r in res.runs if r.integrator == integrator and r.stable]
            if rs:
                ax.loglog([r.dt for r in rs], [max(r.error, 1e-9) for r in rs], "o-", ms=3,
                          color=colors[integrator], label=integrator)
        ax.axhline(res.floor, color="grey", lw=0.8, ls=":")
        ax.set_title(res.case.label, fontsize=9)
        ax.set_xlabel("dt [s]", fontsize=8)
        ax.set_ylabel(f"RMS error at {res.case.time:g} s [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.2)
    if stiff:
        ax = list(axes.flat)[len(orders)]
        for integrator in integrators:
            rs = [r for r in stiff if r.integrator == integrator and r.stable]
            if rs:
                ax.loglog([r.wall_per_second for r in rs], [r.error for r in rs], "o", ms=4,
                          color=colors[integrator], label=integrator)
        front = front_of(stiff)
        ax.loglog([r.wall_per_second for r in front], [r.error for r in front], "k--", lw=1)
        ax.set_title(f"{stiff[0].case}: Pareto front", fontsize=9)
        ax.set_xlabel("wall time per simulated second [s]", fontsize=8)
        ax.set_ylabel("RMS error [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.2)
    for ax in list(axes.flat)[panels:]:
        ax.axis("off")
    handles = [matplotlib.lines.Line2D([], [], color=colors[i], marker="o", ms=3, label=i)
               for i in integrators]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(out, dpi=110)
    plt.close(fig)
