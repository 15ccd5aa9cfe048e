"""CPU time per 1/60 s frame of newton's 50 x 50 twist (benches/peers/impl_rustcloth_twist.py),
or per step of the 64 x 64 or 128 x 128 pile (benches/self_collision.py's ``pile``), for
comparing two builds on a loaded machine, where wall times are not steady.

    RAYON_NUM_THREADS=1 PYTHONPATH=BUILD python benches/self_collision_cpu.py [--settle 2.0]
        [--frames 10] [--case twist50|pile64|pile128] [--no-pass] [--state FILE]

Steps to ``--settle`` s (the pile: 1.0 s unless given), then times ``--frames`` frames (the
pile: steps, of two substeps each) by ``time.process_time()``. Prints the state hash after
them (equal for two builds whose pass gives the same result), the CPU and wall milliseconds per
frame, and the pass's search per substep over the timed window: its milliseconds, boxes
tested, candidates, pairs, and the share of substeps on the swept search. ``--no-pass`` times
the same scene without ``[self_collision]``. ``--state FILE`` starts the timed window from the
state pickled there (``get_state()``) and, when the file is missing, settles and pickles it
first: the 128 x 128 pile takes minutes to settle on one thread, and a restored state steps
bitwise as the original, so two builds time the same window.

Two builds alternated in one session (what docs/contact.md's comparisons come from):

    for t in 1 2; do for c in "twist50 --frames 5" "pile64 --frames 100"; do
        for b in BEFORE AFTER; do
            RAYON_NUM_THREADS=$t PYTHONPATH=$b python benches/self_collision_cpu.py --case $c
        done
        RAYON_NUM_THREADS=$t PYTHONPATH=BEFORE python benches/self_collision_cpu.py --case $c \
            --no-pass
    done; done
"""

from __future__ import annotations

import argparse
import hashlib
import pickle
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import impl_rustcloth_twist as peer  # noqa: E402
import rustcloth  # noqa: E402
from rustcloth.drivers import TwistDriver  # noqa: E402

import self_collision as bench  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("twist50", "pile64", "pile128"), default="twist50")
    parser.add_argument("--settle", type=float, default=None)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--no-pass", action="store_true")
    parser.add_argument("--state", type=Path, default=None)
    args = parser.parse_args()
    if args.state is not None and (args.case == "twist50" or args.no_pass):
        parser.error("--state is for the pile with the pass")
    if args.case == "twist50":
        scene = peer.scene("implicit_euler", (1000.0, 250.0, 10.0), peer.STEPS_PER_FRAME)
        if args.no_pass:
            scene = scene.replace(self_collision=None)
        sim = rustcloth.Simulation(scene)
        driver: TwistDriver | None = TwistDriver(
            sim, turns=peer.RATE_TURNS * peer.END, seconds=peer.END)
        steps_per_frame, settle, unit = peer.STEPS_PER_FRAME, 2.0, "frame"
    else:
        n = 64 if args.case == "pile64" else 128
        sim = rustcloth.Simulation(bench.scene("pile", n, not args.no_pass))
        driver, steps_per_frame, settle, unit = None, 1, 1.0, "step"
    settle = settle if args.settle is None else args.settle

    def step() -> None:
        if driver is not None:
            driver.before_step(sim)
        sim.step()

    if args.state is not None and args.state.exists():
        sim = rustcloth.Simulation.from_state(pickle.loads(args.state.read_bytes()))
    while sim.time < settle - 0.5 * sim.dt:
        step()
    if args.state is not None and not args.state.exists():
        args.state.write_bytes(pickle.dumps(sim.get_state()))
    before = dict(sim.self_collision_stats() or {})
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(args.frames * steps_per_frame):
        step()
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    after = dict(sim.self_collision_stats() or {})
    split = bench.per_substep(before, after)
    rebuilds, requeries, requeried, widened = (
        after.get(k, 0) - before.get(k, 0)
        for k in ("rebuilds", "requeries", "requeried", "widened"))
    digest = hashlib.sha1(sim.positions.tobytes()).hexdigest()[:12]
    print(f"{args.case}{' without the pass' if args.no_pass else ''}: state {digest} "
          f"cpu {1e3 * cpu / args.frames:.1f} ms per {unit} "
          f"wall {1e3 * wall / args.frames:.1f} ms per {unit}; per substep: "
          f"search {split['search']:.2f} ms, boxes tested {split['boxes_tested']:.0f}, "
          f"candidates {split['candidates']:.0f}, pairs {split['pairs']:.0f}, "
          f"swept {100 * split['swept_substeps']:.0f} %; list rebuilds {rebuilds}, "
          f"partial {requeries} ({requeried} vertices queried again); "
          f"substeps that looked at every listed pair {widened}")


if __name__ == "__main__":
    main()
