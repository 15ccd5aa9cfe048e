"""The accuracy-versus-time study: what each integrator's accuracy costs.

``python -m rustcloth accuracy --out DIR`` writes ``DIR/accuracy.md`` (tables, the measured
orders, Pareto fronts and a reading generated from the numbers) and ``DIR/accuracy.png``
(``DIR`` is ``out/accuracy`` unless given; ``make accuracy`` writes the repository's
``docs``). It has two parts.

**Orders.** Every integrator over a ladder of time steps on smooth motion that exercises the
springs: a cloth swinging down from two pinned corners, and a free sheet kicked into
vibration (no gravity), each in two regimes: *damped* (spring damping and air drag, forces that
depend on velocity) and *conservative* (neither). The error is the RMS particle distance at a
fixed time from a float64 reference that is none of the integrators under test: the same model
in numpy (``rustcloth.reference``), integrated by adaptive Dormand-Prince 5(4) to a local error
of 1e-11. rustcloth steps in float32, so errors below a floor of about 1e-6 m are round-off; each
integrator's order is the slope of log error against log dt at the fine end of its clean
stretch above three times that floor.

**Stiff cloth at a display frame.** The draping scene of docs/stiff.md (k dt^2 / m of 280 at
32 x 32) at dt = 1/60 s: the explicit integrators with the substeps they need and more,
implicit Euler with each preconditioner and tolerance and with substeps, projective dynamics
with several iteration counts. Error against cost (wall-clock ms per simulated second), the
Pareto front, and which method is cheapest for each accuracy.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

from .. import INTEGRATORS
from .._cli import Parser, guarded, progress, writable_folder
from .._extras import require
from .measure import (
    EXPLICIT,
    LADDER,
    STIFF_DT,
    Case,
    OrderResult,
    Run,
    measure,
    order_study,
    reference,
    rms,
    simulate,
    slope,
    stiff_scene,
    stiff_study,
)
from .report import front_of, pareto, plot, reading, write_report

# The study's pieces, measuring and reporting, under the one name the command line, the tests
# and rustcloth.accuracy import them by.
__all__ = [
    "DEFAULT_OUT", "EXPLICIT", "LADDER", "STIFF_DT", "Case", "OrderResult", "Run",
    "build_parser", "front_of", "main", "measure", "order_study", "pareto", "plot", "reading",
    "reference", "rms", "simulate", "slope", "stiff_scene", "stiff_study", "write_report",
]


#: Where the study writes when --out is not given: a folder of the working directory's ``out``,
#: never the docs of whatever checkout the user stands in (``make accuracy`` passes --out docs).
DEFAULT_OUT = Path("out/accuracy")


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``rustcloth accuracy`` (matplotlib is needed only to run the study)."""
    parser = Parser(prog="rustcloth accuracy", description=__doc__)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="folder for accuracy.md and accuracy.png, created if missing "
                             "(the repository's own report: --out docs)")
    parser.add_argument("--quick", action="store_true",
                        help="a tiny study (8x8, three rungs of the ladder) to check the pipeline")
    return parser


def main(argv: list[str] | None = None) -> int:
    """``rustcloth accuracy``; returns the exit status (2: a bad argument, an unwritable
    folder or no matplotlib, said in one line)."""
    return guarded("rustcloth accuracy", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    writable_folder(args.out)
    require("rustcloth accuracy", "matplotlib")
    if args.quick:
        cases = [Case("hanging", True, 8, 0.05), Case("stretched", False, 8, 0.05)]
        ladder, stiff_n, stiff_seconds = LADDER[:3], 8, 0.1
    else:
        # Smooth motion that loads the springs from the start: the hanging cloth pivots about
        # its corners long before it buckles (about 0.5 s), the kicked sheet vibrates at once.
        cases = [Case(kind, damped, 24, t) for kind, t in (("hanging", 0.25), ("stretched", 0.1))
                 for damped in (False, True)]
        ladder, stiff_n, stiff_seconds = LADDER, 32, 0.5
    integrators: list[str] = list(INTEGRATORS)
    start = time.perf_counter()
    # One tick per case of the order study and one for the stiff study; their lines above it.
    bar = progress(len(cases) + 1, "part")

    def log(line: str) -> None:
        bar.write(line)
        bar.update()

    try:
        with warnings.catch_warnings():
            # Unstable settings and capped solves are part of what the study measures.
            warnings.simplefilter("ignore", RuntimeWarning)
            orders = order_study(cases, integrators, ladder, log)
            stiff, ratio = stiff_study(stiff_n, stiff_seconds, args.quick, log)
    finally:
        bar.close()
    elapsed = time.perf_counter() - start
    write_report(orders, stiff, ratio, integrators, args.out / "accuracy.md", elapsed)
    plot(orders, stiff, integrators, args.out / "accuracy.png")
    print(f"wrote {args.out / 'accuracy.md'} and {args.out / 'accuracy.png'} in {elapsed:.0f} s")
    return 0
