"""Read a sweep's results back: the index of runs with their parameters and status, and each
run's arrays. Give it a sweep's output folder (`rustcloth sweep ... --out DIR`, or
`run_sweep(sweep, DIR)`); without one it runs a small sweep into out/sag first.

    python examples/read_sweep_results.py [DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import rustcloth
from _quick import pick
from rustcloth.sweep import Record, Sweep, load_run, read_index, run_sweep


def small_sweep(out: Path) -> None:
    base = rustcloth.load_scene("hanging").replace(cloth={"nx": 12, "ny": 12})
    sweep = Sweep(base=base, grid={"cloth.k_structural": [100.0, 400.0, 1600.0]},
                  seconds=pick(1.0, 0.2), record=Record(every=50))
    run_sweep(sweep, out, "local", workers=1)


def main(argv: list[str]) -> None:
    out = Path(argv[0]) if argv else Path("out/sag")
    if not argv:
        small_sweep(out)
    records = read_index(out)  # one dict a run: run_id, params, status, ...
    print(f"{out}: {len(records)} runs, "
          f"{sum(r['status'] == 'ok' for r in records)} ok")
    for record in records:
        if record["status"] != "ok":
            print(f"  {record['run_id']}: {record['status']} {record.get('reason', '')}")
            continue
        arrays = load_run(out, record["run_id"])  # steps, time, positions, energy, ...
        lowest = arrays["positions"][:, :, 1].min(axis=1)  # (F,) per recorded frame
        print(f"  {record['params']}: {len(arrays['time'])} frames to t = "
              f"{arrays['time'][-1]:.2f} s, lowest point {lowest[-1]:.3f} m, "
              f"max stretch {np.max(arrays['max_stretch']):.2%}")


if __name__ == "__main__":  # needed: local workers import this file
    main(sys.argv[1:])
