"""newton's ``example_cloth_twist`` and rustcloth's 50 x 50 twist in one process, their frames
alternated, so both run under the same load on a shared machine.

    RAYON_NUM_THREADS=1 PYTHONPATH=python .venv-peers/bin/python \\
        benches/peers/twist_side_by_side.py              # about 2.5 minutes on the 2-core Xeon

The peers venv (``benches/peers/setup.sh``) gives newton, Warp and ``usd-core``; rustcloth is
taken from ``PYTHONPATH`` (a build of the working tree) when it is set. newton runs as
``impl_newton_twist.py`` runs it (Warp on the CPU device, its own unchanged ``Example``, one
``step()`` per frame); rustcloth as ``self_collision.py``'s ``twist50`` sets it up
(``impl_rustcloth_twist.py``'s scene and driver), at newton's 10 steps a frame without the
in-solve term and at 2 steps a frame with ``solve_stiffness`` 30.

Every simulation is stepped untimed to ``--start`` s (2.0: the cloth wound onto itself), then
the next ``--frames`` frames are timed in turn: a newton frame, a frame of each rustcloth
setting, and again. Warp's CPU kernels run on one thread, so ``RAYON_NUM_THREADS=1`` makes the
comparison thread for thread; with 2 the rustcloth frames use both cores and newton's still one.
Prints per simulation the wall and CPU (the process's, every thread's) ms a frame, median and
mean over the timed frames, and the crossings (``tri_check``) at the end;
``--json`` writes them too.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402
import tri_check  # noqa: E402
import warp as wp  # noqa: E402
from warp_cpu import start_warp_on_cpu  # noqa: E402

FRAME = 1.0 / 60.0


def newton_twist() -> tuple[Callable[[], None], Callable[[], tuple[np.ndarray, np.ndarray]]]:
    """newton's example, built as ``impl_newton_twist.py`` builds it: its frame, and its
    positions and triangles."""
    import newton  # noqa: PLC0415
    import newton.viewer  # noqa: PLC0415
    from newton.examples.cloth.example_cloth_twist import Example  # noqa: PLC0415

    example = Example(newton.viewer.ViewerNull(), None)
    wp.synchronize()
    triangles = example.model.tri_indices.numpy()

    def step() -> None:
        example.step()
        wp.synchronize()

    return step, lambda: (example.state_0.particle_q.numpy(), triangles)


def rustcloth_twist(steps_per_frame: int, solve_stiffness: float) -> tuple[
        Callable[[], None], Callable[[], tuple[np.ndarray, np.ndarray]]]:
    """rustcloth's 50 x 50 twist as ``impl_rustcloth_twist.py`` sets it up: its frame (the
    driver's pins before each step, as that script counts them), and its positions and
    triangles."""
    import impl_rustcloth_twist as peer  # noqa: PLC0415
    import rustcloth  # noqa: PLC0415
    from rustcloth.drivers import TwistDriver  # noqa: PLC0415

    sim = rustcloth.Simulation(peer.scene("implicit_euler", (1000.0, 250.0, 10.0),
                                          steps_per_frame, solve_stiffness))
    driver = TwistDriver(sim, turns=peer.RATE_TURNS * peer.END, seconds=peer.END)

    def step() -> None:
        for _ in range(steps_per_frame):
            driver.before_step(sim)
            sim.step()

    return step, lambda: (sim.positions, sim.triangles)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--start", type=float, default=2.0, help="s stepped untimed first")
    p.add_argument("--frames", type=int, default=10, help="frames timed per simulation")
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args()
    start_warp_on_cpu(False)
    import rustcloth  # noqa: PLC0415

    sims = {
        "newton example_cloth_twist (VBD, 10 substeps)": newton_twist(),
        "rustcloth, 10 steps a frame, K 0": rustcloth_twist(10, 0.0),
        "rustcloth, 2 steps a frame, K 30": rustcloth_twist(2, 30.0),
    }
    lead = round(args.start / FRAME)
    t0 = time.perf_counter()
    for name, (step, _) in sims.items():
        for _ in range(lead):
            step()
        print(f"{name}: stepped to {args.start} s", flush=True)
    lead_s = time.perf_counter() - t0
    times: dict[str, dict[str, list[float]]] = {name: {"wall": [], "cpu": []} for name in sims}
    load0 = os.getloadavg()
    for _ in range(args.frames):
        for name, (step, _) in sims.items():
            w0, c0 = time.perf_counter(), time.process_time()
            step()
            times[name]["cpu"].append(1e3 * (time.process_time() - c0))
            times[name]["wall"].append(1e3 * (time.perf_counter() - w0))
    load1 = os.getloadavg()
    out: dict[str, object] = {
        "threads_rustcloth": rustcloth._core.thread_count(),
        "load_start": load0, "load_end": load1, "lead_s": lead_s,
        "window": [args.start, args.start + args.frames * FRAME],
    }
    for name, (_, positions) in sims.items():
        x, triangles = positions()
        t = times[name]
        result = {
            "wall_median": statistics.median(t["wall"]), "wall_mean": statistics.fmean(t["wall"]),
            "cpu_median": statistics.median(t["cpu"]), "cpu_mean": statistics.fmean(t["cpu"]),
            "crossings": tri_check.count(np.asarray(x, np.float64), triangles),
        }
        out[name] = {**result, "wall": t["wall"], "cpu": t["cpu"]}
        print(f"{name}: wall {result['wall_median']:.1f} ms a frame (median; mean "
              f"{result['wall_mean']:.1f}), CPU {result['cpu_median']:.1f} (mean "
              f"{result['cpu_mean']:.1f}), {result['crossings']} crossings at "
              f"{args.start + args.frames * FRAME:.2f} s", flush=True)
    print(f"rustcloth threads {out['threads_rustcloth']}, load average {load0} -> {load1}")
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
