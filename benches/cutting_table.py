"""Cost of cutting at 128 x 128 and 512 x 512: one stroke segment, one tear, the
drawn mesh's rebuild after a cut and its per-frame positions, and the step after many cuts
against an uncut cloth. Writes the table into docs/cutting.md between its markers.

    .venv/bin/python benches/cutting_table.py [--quick]

Times are medians of repeated calls in one process; the step comparison alternates the cut and
the uncut cloth and reports the ratio, as the machine this runs on is shared and noisy.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rustcloth

DOC = Path(__file__).resolve().parent.parent / "docs" / "cutting.md"
BEGIN, END = "<!-- cutting-table:begin -->", "<!-- cutting-table:end -->"
EYE = np.array([0.0, 1.5, 3.0], np.float32)


def curtain(n: int, tearing: bool = False) -> rustcloth.Simulation:
    """An ``n`` x ``n`` curtain, 1 m square in the xy plane, pinned along its top, sagging."""
    scene = {
        "integrator": "symplectic_euler", "dt": 0.0005, "substeps": 1,
        "cloth": {"nx": n, "ny": n, "size": [1.0, 1.0], "center": [0.0, 1.5, 0.0],
                  "plane": "xy", "particle_mass": 0.001, "k_structural": 200.0,
                  "k_shear": 50.0, "k_bend": 5.0, "damping": 0.01, "pins": ["top_edge"]},
    }
    if tearing:
        scene["tearing"] = {"max_strain": 0.5, "max_per_step": 8}
    sim = rustcloth.Simulation(rustcloth.Scene(**scene))
    sim.step(5)
    return sim


def ray_to(x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
    """A ray from the eye through the point (x, y, 0) on the curtain."""
    return EYE, np.array([x, y, 0.0], np.float32) - EYE


def median_us(f: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return 1e6 * statistics.median(times)


def stroke_segment(n: int, repeat: int) -> tuple[float, float, float]:
    """(short segment, full-width segment, sever + drawn-mesh rebuild) in us. The same segment
    again finds the same springs (already severed: nothing changes), so repeating it times
    the test itself; the first cut of a fresh cloth times the sever and the rebuild."""
    sim = curtain(n)
    short = [ray_to(-0.02, 1.43), ray_to(0.02, 1.44)]  # a mouse move of about 4 cm
    full = [ray_to(-0.7, 1.41), ray_to(0.7, 1.46)]
    assert sim.sever_stroke(short) > 0 and sim.sever_stroke(full) > 0
    t_short = median_us(lambda: sim.sever_stroke(short), repeat)
    t_full = median_us(lambda: sim.sever_stroke(full), repeat)
    rebuilds = []
    for k in range(max(3, repeat // 20)):
        fresh = curtain(n)
        y = 1.3 + 0.01 * k
        t0 = time.perf_counter()
        fresh.sever_stroke([ray_to(-0.7, y), ray_to(0.7, y + 0.02)])
        fresh.render_topology()
        rebuilds.append(time.perf_counter() - t0)
    return t_short, t_full, 1e6 * statistics.median(rebuilds)


def tear(n: int, repeat: int) -> tuple[float, float]:
    """(the tearing pass per step, a tear's drawn-mesh rebuild) in us."""
    sim = curtain(n, tearing=True)
    sim.step(20)
    passes = sim.profile().passes
    pass_us = 1e6 * passes["tearing"].seconds / passes["tearing"].calls
    # A tear is a sever without a stroke: what follows it is the same rebuild.
    times = []
    for k in range(max(3, repeat // 20)):
        sim.sever_stroke([ray_to(-0.01 + 0.02 * k, 1.2), ray_to(0.01 + 0.02 * k, 1.2)])
        t0 = time.perf_counter()
        sim.render_topology()
        times.append(time.perf_counter() - t0)
    return pass_us, 1e6 * statistics.median(times)


def frame(n: int, repeat: int) -> float:
    """The drawn mesh's positions and normals after a step (with a long cut), in us."""
    sim = curtain(n)
    sim.sever_stroke([ray_to(-0.7, 1.4), ray_to(0.7, 1.45)])
    sim.render_topology()

    def one() -> None:
        sim.set_positions(sim.positions)  # a new state, nothing moved: times the read alone
        sim.render_positions()

    base = median_us(lambda: sim.set_positions(sim.positions), repeat)
    return median_us(one, repeat) - base


def step_ratio(n: int, rounds: int) -> float:
    """Step time of a cloth cut by 20 strokes over that of an uncut one."""
    cut, uncut = curtain(n), curtain(n)
    for k in range(20):
        y = 1.05 + 0.045 * k
        cut.sever_stroke([ray_to(-0.7, y), ray_to(0.7, y + 0.01 * (k % 3))])
    steps = 20 if n <= 128 else 3
    ratios = []
    for _ in range(rounds):
        t = []
        for sim in (cut, uncut):
            t0 = time.perf_counter()
            sim.step(steps)
            t.append(time.perf_counter() - t0)
        ratios.append(t[0] / t[1])
    return statistics.median(ratios)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeat = 40 if args.quick else 200
    rows = []
    for n in (128, 512):
        short, full, rebuild = stroke_segment(n, repeat if n <= 128 else repeat // 4)
        tear_pass, tear_rebuild = tear(n, repeat // 4)
        positions = frame(n, repeat // 4)
        ratio = step_ratio(n, 7 if args.quick else 15)
        rows.append(f"| {n} x {n} | {short:.0f} | {full:.0f} | {rebuild:.0f} | {tear_pass:.0f} | "
                    f"{tear_rebuild:.0f} | {positions:.0f} | {ratio:.3f} |")
        print(rows[-1], flush=True)
    table = "\n".join([
        "| cloth | stroke segment, 4 cm (us) | stroke segment, full width (us) | "
        "first cut: sever + drawn-mesh rebuild (us) | tearing pass per step (us) | "
        "a tear's drawn-mesh rebuild (us) | drawn positions per frame (us) | "
        "step after 20 cuts / uncut |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"`.venv/bin/python benches/cutting_table.py` on {rustcloth._core.thread_count()} threads, "
        f"instruction set {rustcloth._core.instruction_set()}; medians, in one process.",
    ])
    text = DOC.read_text()
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    DOC.write_text(text[:start] + "\n" + table + "\n" + text[end:])


if __name__ == "__main__":
    main()
