"""The command line, ``rustcloth COMMAND`` or ``python -m rustcloth COMMAND``.

``run`` and ``scenes`` live here. ``demo``, ``render``, ``accuracy`` and ``sweep`` belong to other
modules (:data:`DELEGATED`): each gets the arguments after its name, parses its own options
(with the parser and argument types of :mod:`rustcloth._cli`) and returns an exit code. Those
modules import no optional extra when they load, so every command's ``--help`` works before
its extra is installed; the extra is checked after the arguments are parsed. Exit codes: 0
done, 1 the simulation diverged, 2 a bad argument, an unusable scene or file, or a missing
optional dependency (said in one line, naming the extra), 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from . import INTEGRATORS, __version__, export, load_scene, scenes
from ._cli import USER_ERRORS, Parser, describe, fail, guarded, positive, progress, writable_folder
from ._limits import MAX_STEPS
from .errors import SimulationDiverged, StabilityWarning
from .simulation import Simulation

__all__ = ["DELEGATED", "MAX_STEPS", "Delegate", "UsageError", "build_parser", "main",
           "run_headless"]

#: Where ``demo`` and ``render`` live: the one line to change if they move.
APP_MODULE = "rustcloth.app"


@dataclass(frozen=True)
class Delegate:
    """A sub-command another module owns: ``module.function(argv) -> int``. The module imports
    no optional extra when it loads (the function checks for its extra after parsing)."""

    module: str
    function: str
    help: str


DELEGATED: dict[str, Delegate] = {
    "demo": Delegate(APP_MODULE, "main_demo",
                     "the interactive desktop demo (needs the viewer extra)"),
    "render": Delegate(APP_MODULE, "main_render",
                       "render a scene offscreen to PNG frames, a GIF or an MP4 (needs the viewer "
                       "extra, and video for MP4)"),
    "accuracy": Delegate("rustcloth.accuracy", "main",
                         "the integrators' accuracy-versus-cost study (needs the study extra)"),
    "sweep": Delegate("rustcloth.sweep", "main", "parameter sweeps (the ray extra runs them on a "
                      "Ray cluster)"),
}


class UsageError(ValueError):
    """A bad command-line value found after parsing (it depends on the scene)."""


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``rustcloth`` and of its ``run`` and ``scenes`` sub-commands."""
    parser = Parser(
        prog="rustcloth",
        description="Real-time mass-spring cloth: simulate, export, render and study.",
        epilog="examples:\n"
               "  rustcloth run drape --seconds 3\n"
               "  rustcloth run my_scene.toml --export out/cloth.usd\n"
               "  rustcloth demo hanging\n"
               "  rustcloth render drape --frames 120 --gif\n"
               "Each command's options: rustcloth COMMAND --help.")
    parser.add_argument("--version", action="version", version=f"rustcloth {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                     parser_class=Parser)
    run = commands.add_parser(
        "run", help="simulate a scene without a window: progress, a summary, optional export",
        description="Simulate a scene without a window. Prints time, energy and stretch once\n"
                    "per simulated second, then a summary with the time per pass; with --export,\n"
                    "writes the run (USD, OBJ sequence) or its last frame (OBJ, PLY, glTF).")
    run.add_argument("scene", nargs="?", default="drape",
                     help="a built-in scene (rustcloth scenes lists them) or a TOML scene file")
    run.add_argument("--seconds", type=positive, default=5.0, metavar="S",
                     help=f"simulated seconds, run in whole steps of the scene's dt (at most "
                          f"{MAX_STEPS:,} steps)")
    run.add_argument("--integrator", choices=INTEGRATORS, default=None, metavar="NAME",
                     help=f"time integrator: {', '.join(INTEGRATORS)} (default: the scene's)")
    run.add_argument("--export", type=Path, default=None, metavar="PATH",
                     help="write the run to PATH: .usd, .usda or .usdc, one USD file of the whole "
                          "run (usd extra); a name with #### such as out/cloth_####.obj, one OBJ "
                          "per frame; .obj, .ply or .glb, the last frame (export extra) "
                          "(default: no export)")
    run.add_argument("--fps", type=positive, default=30.0,
                     help="frames per simulated second written by --export to USD or an OBJ "
                          "sequence (at most one frame per step)")
    commands.add_parser("scenes", help="list the built-in scenes",
                        description="List the built-in scenes, one name a line.")
    for name, delegate in DELEGATED.items():
        # Listed for the help only: main() hands these their arguments before parsing.
        commands.add_parser(name, help=delegate.help, add_help=False)
    return parser


# -- run ---------------------------------------------------------------------------------------
def _plan_export(path: Path | None) -> str | None:
    """What --export writes ("run" or "frame"), checked before the run starts so that a bad
    path or a missing extra costs no simulation."""
    if path is None:
        return None
    suffix = path.suffix.lower()
    if suffix in export.USD_FORMATS:
        export.check_required(path)
        mode = "run"
    elif suffix not in export.MESH_FORMATS:
        raise UsageError(f"--export {path}: the suffix must be one of "
                         f"{', '.join(export.USD_FORMATS + export.MESH_FORMATS)}")
    elif export.is_sequence(path) and suffix != ".obj":
        raise UsageError(f"--export {path}: a sequence (####) is written as .obj only")
    else:
        # Everything writing it needs (trimesh, and Pillow, which trimesh loads only then).
        export.check_required(path)
        mode = "run" if export.is_sequence(path) else "frame"
    writable_folder(path.parent)
    return mode


def _step_at(seconds: float, dt: float) -> int:
    """The step that ends nearest to ``seconds`` (round half up: frames at most one per step
    never share a step)."""
    return math.floor(seconds / dt + 0.5)


def run_headless(scene_name: str, seconds: float, integrator: str | None = None,
                 export_path: Path | None = None, fps: float = 30.0) -> int:
    """Simulate ``seconds`` of a scene (a built-in name or a TOML path), printing time, energy
    and stretch once per simulated second, then a summary with the per-pass profile; with
    ``export_path``, record the run or write its last frame. Returns the exit code."""
    mode = _plan_export(export_path)
    scene = load_scene(scene_name)
    if integrator:
        scene = scene.replace(integrator=integrator)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StabilityWarning)
        sim = Simulation(scene)
    for warning in caught:  # one line each, without the source line
        print(f"warning: {warning.message}", file=sys.stderr)
    dt = sim.dt
    wanted = seconds / dt
    if not wanted <= MAX_STEPS:
        raise UsageError(f"--seconds {seconds:g} is more than {MAX_STEPS:,} steps of dt = {dt:g} "
                         f"s (at most {MAX_STEPS * dt:g} s of this scene)")
    total = max(1, _step_at(seconds, dt))
    if mode == "run" and fps * dt > 1.0:
        raise UsageError(f"--fps {fps:g} asks for more than one frame per step of dt = {dt:g} s "
                         f"(at most {1 / dt:g})")
    title = Path(scene_name).stem if str(scene_name).endswith(".toml") else scene_name
    print(f"{title}: {sim.num_particles} particles ({sim.nx}x{sim.ny}), {sim.integrator}, "
          f"dt={dt:g} s x {sim.substeps} substeps, {total:,} steps")
    print(f"effects: {', '.join(sim.effects)}")
    header = ("time [s]", "energy [J]", "kinetic [J]", "max stretch", "wall [s]")
    print("{:>9} {:>12} {:>12} {:>12} {:>9}".format(*header))

    rec = export.recorder(export_path, fps) if mode == "run" and export_path else None
    chunk = max(1, total // 200)  # steps between progress-bar updates
    start = time.perf_counter()
    e0 = sim.energy()
    done, frames, second, status = 0, 0, 1, 0
    bar = progress(total, "step")
    try:
        # Step to the nearest of: the end, the next progress update, the next whole simulated
        # second (a row of the table), the next recorded frame (frame k at k / fps seconds).
        if rec is not None:
            rec.add(sim)
            frames = 1
        while done < total:
            marks = [total, done + chunk, _step_at(second, dt)]
            if rec is not None:
                marks.append(_step_at(frames / fps, dt))
            target = min(m for m in marks if m > done)
            sim.step(target - done)
            bar.update(target - done)
            done = target
            if rec is not None and done == _step_at(frames / fps, dt):
                rec.add(sim)
                frames += 1
            on_second = done == _step_at(second, dt)
            second += on_second
            if on_second or done == total:
                e = sim.energy()
                bar.write(f"{sim.time:9.2f} {e.total:12.5f} {e.kinetic:12.5f} "
                           f"{sim.max_stretch():12.2%} {time.perf_counter() - start:9.3f}")
    except SimulationDiverged as err:
        print(f"stopped: {err}")
        status = 1
    except KeyboardInterrupt:
        print(f"interrupted at t = {sim.time:g} s")
        status = 130
    finally:
        bar.close()
        if rec is not None:
            rec.close()
    if isinstance(rec, export.UsdRecorder):
        print(f"wrote {rec.path}: {rec.frames} frames at {fps:g} fps")
    elif isinstance(rec, export.ObjSequenceRecorder) and rec.paths:
        print(f"wrote {len(rec.paths)} OBJ files at {fps:g} fps: {rec.paths[0]} ... "
              f"{rec.paths[-1]}")
    if status:
        return status
    if mode == "frame" and export_path is not None:
        export.export(sim, export_path)
        print(f"wrote {export_path}: the frame at t = {sim.time:g} s")
    wall = time.perf_counter() - start
    e = sim.energy()
    print(f"\nsummary: {sim.steps} steps in {wall:.3f} s wall = {sim.steps / wall:,.0f} steps/s, "
          f"{sim.time / wall:.1f}x real time")
    print(f"energy {e0.total:.5f} J -> {e.total:.5f} J, max stretch {sim.max_stretch():.2%}, "
          f"lowest point y = {sim.positions[:, 1].min():.4f} m")
    print(sim.profile())
    return 0


# -- dispatch ----------------------------------------------------------------------------------
def _delegate(command: str, argv: list[str]) -> int:
    d = DELEGATED[command]
    prog = f"rustcloth {command}"
    try:
        module = importlib.import_module(d.module)
    except ModuleNotFoundError as err:
        if err.name != d.module:
            raise
        return fail(prog, f"not available in this installation ({d.module} is missing)")
    return int(getattr(module, d.function)(argv))


def _main(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "scenes":
        print("\n".join(scenes()))
        return 0
    try:
        return run_headless(args.scene, args.seconds, args.integrator, args.export, args.fps)
    except UsageError as err:  # a command-line value, as argparse words its own errors
        return fail("rustcloth run", f"{err} (see rustcloth run --help)")
    except USER_ERRORS as err:  # about the scene or the export, which the line names
        return fail("rustcloth run", f"{args.scene}: {describe(err)}")


def main(argv: list[str] | None = None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``) and return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        return guarded(f"rustcloth {argv[0]}", lambda: _delegate(argv[0], argv[1:]))
    # argparse reports its own errors under the right name; the rest can only come from `run`.
    return guarded("rustcloth run", lambda: _main(argv))
