"""Command line: ``python -m rustcloth COMMAND``.

    demo [SCENE]        the desktop demo (headless progress when no renderer/display)
    run [SCENE]         simulate headless and print per-second progress and a summary
    render SCENE ...    render frames offscreen (see ``render --help``)
    accuracy [--quick]  the accuracy-versus-time study: docs/accuracy.md and .png
    scenes              list the built-in scenes
"""

from __future__ import annotations

import argparse
import sys
import time

from . import Simulation, load_scene, scenes
from .errors import RustclothError


def run_headless(scene_name: str, seconds: float, integrator: str | None = None) -> int:
    """Simulate ``seconds`` of a scene, printing time, energy and stretch once per simulated
    second, then a summary with the per-pass profile."""
    scene = load_scene(scene_name)
    if integrator:
        scene = scene.replace(integrator=integrator)
    sim = Simulation(scene)
    print(f"{scene_name}: {sim.num_particles} particles ({sim.nx}x{sim.ny}), "
          f"{sim.integrator}, dt={sim.dt:g} s x {sim.substeps} substeps")
    print(f"effects: {', '.join(sim.effects)}")
    header = ("time [s]", "energy [J]", "kinetic [J]", "max stretch", "wall [s]")
    print("{:>9} {:>12} {:>12} {:>12} {:>9}".format(*header))
    start = time.perf_counter()
    e0 = sim.energy()
    for _ in range(max(1, round(seconds))):
        try:
            sim.advance(1.0)
        except RustclothError as err:
            print(f"stopped: {err}")
            return 1
        e = sim.energy()
        print(f"{sim.time:9.2f} {e.total:12.5f} {e.kinetic:12.5f} {sim.max_stretch():12.2%} "
              f"{time.perf_counter() - start:9.3f}")
    wall = time.perf_counter() - start
    profile = sim.profile()
    e = sim.energy()
    print(f"\nsummary: {sim.steps} steps in {wall:.3f} s wall = {sim.steps / wall:,.0f} steps/s, "
          f"{sim.time / wall:.1f}x real time")
    print(f"energy {e0.total:.5f} J -> {e.total:.5f} J, max stretch {sim.max_stretch():.2%}, "
          f"lowest point y = {sim.positions[:, 1].min():.4f} m")
    print(profile)
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(prog="rustcloth", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=["demo", "run", "render", "accuracy", "scenes"])
    args, rest = parser.parse_known_args(argv[:1])
    rest = argv[1:]
    try:
        if args.command == "accuracy":
            from . import accuracy

            return accuracy.main(rest)
        if args.command == "scenes":
            print("\n".join(scenes()))
            return 0
        if args.command in ("demo", "render"):
            try:
                from . import app
            except ImportError as err:  # the renderer is optional at run time
                if args.command == "render":
                    print(f"rendering is unavailable: {err}", file=sys.stderr)
                    return 1
                print(f"renderer unavailable ({err}); running headless instead")
                return run_headless(rest[0] if rest else "drape", 5.0)
            return app.main_demo(rest) if args.command == "demo" else app.main_render(rest)
        sub = argparse.ArgumentParser(prog="rustcloth run")
        sub.add_argument("scene", nargs="?", default="drape", help=f"one of {scenes()}")
        sub.add_argument("--seconds", type=float, default=5.0)
        sub.add_argument("--integrator", default=None)
        opts = sub.parse_args(rest)
        return run_headless(opts.scene, opts.seconds, opts.integrator)
    except RustclothError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
