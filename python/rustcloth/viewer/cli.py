"""The command lines of the desktop demo and of headless rendering: :func:`main_demo` and
:func:`main_render` (the ``rustcloth`` dispatcher calls them with the arguments after the
command's name), with their parsers :func:`demo_parser` and :func:`render_parser`.

This module imports no optional extra when it loads (OpenGL, glfw, Pillow come in after the
arguments are parsed, each checked first), so ``--help`` works before the viewer extra is
installed; ``rustcloth.render`` and ``rustcloth.viewer`` load their OpenGL modules lazily for
the same reason.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from .. import Scene, load_scene, scenes
from .._cli import USER_ERRORS, Parser, describe, guarded, positive, positive_int, writable_folder
from .._extras import require
from ..render.constants import VIEWS
from ..render.lights import PRESET_NAMES
from ..render.tiers import TIERS
from .script import ScriptPlayer, default_script

#: Modules of the viewer extra each command cannot start without.
DEMO_NEEDS = ("moderngl", "glfw", "PIL")
RENDER_NEEDS = ("moderngl", "PIL", "imageio")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must look like 640x480, not {text!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"must be 16..8192 pixels each way, not {text!r}")
    return w, h


def _scale(text: str) -> float | None:
    if text == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be 'auto' or a number, not {text!r}") from None
    if not 0.25 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be between 0.25 and 1, not {text!r}")
    return value


def _scene(parser: argparse.ArgumentParser, name: str) -> Scene:
    """The scene ``name`` (built-in or a TOML path), or a one-line error (exit status 2)."""
    try:
        return load_scene(name)
    except USER_ERRORS as err:
        parser.error(f"scene {name!r}: {describe(err)}")


def _script(parser: argparse.ArgumentParser, path: Path | None) -> list[dict[str, Any]] | None:
    if path is None:
        return None
    try:
        events: list[dict[str, Any]] = json.loads(path.read_text(encoding="utf-8"))
        ScriptPlayer(events)
    except (OSError, ValueError) as err:
        parser.error(f"--script {path}: {describe(err)}")
    return events


def _add_look(parser: argparse.ArgumentParser, tier: str) -> None:
    parser.add_argument("--lights", choices=PRESET_NAMES, default=PRESET_NAMES[0],
                        help="light preset (L cycles them in the demo)")
    parser.add_argument("--ssao", action="store_true",
                        help="screen-space ambient occlusion (O toggles it in the demo; "
                             "full tier only)")
    parser.add_argument("--tier", choices=("auto", *TIERS), default=tier,
                        help="rendering quality: full (deferred, for a GPU), software (one "
                             "forward pass lit per vertex, for GL without a GPU such as "
                             "llvmpipe), auto: software when GL_RENDERER names a CPU "
                             "rasteriser (Q switches in the demo)")


def _tier(name: str) -> str | None:
    return None if name == "auto" else name


def _notice(text: str) -> None:
    print(f"notice: {text}", flush=True)


# -- the desktop demo ------------------------------------------------------------------------
def demo_parser() -> argparse.ArgumentParser:
    """The parser of ``rustcloth demo``."""
    parser = Parser(prog="rustcloth demo", description="The interactive demo in a window.")
    parser.add_argument("scene", nargs="?", default="drape",
                        help=f"a built-in scene ({', '.join(scenes())}) or a TOML scene file")
    parser.add_argument("--size", type=_size, default="1280x720", help="window size, WxH")
    parser.add_argument("--frames", type=positive_int, default=None,
                        help="quit after this many frames (default: when the window closes)")
    parser.add_argument("--script", type=Path, default=None,
                        help="JSON list of scripted events to replay (docs/rendering.md)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"),
                        help="where the headless fallback writes its frames without a display")
    parser.add_argument("--render-scale", type=_scale, default="auto", metavar="auto|0.25..1",
                        help="share of the window's resolution the 3D passes draw, each way "
                             "(auto: lowered while a frame takes over 40 ms to render)")
    _add_look(parser, "auto")
    return parser


def main_demo(argv: list[str]) -> int:
    """``rustcloth demo``: the glfw window, or headless frames when there is no display."""
    return guarded("rustcloth demo", lambda: _demo(argv))


def _demo(argv: list[str]) -> int:
    parser = demo_parser()
    args = parser.parse_args(argv)
    require("rustcloth demo", *DEMO_NEEDS)
    _scene(parser, args.scene)
    script = _script(parser, args.script)
    from ..render.context import GLUnavailable
    from .window import Demo, DisplayUnavailable

    try:
        demo = Demo(args.scene, args.size, script=script, lights=args.lights, ssao=args.ssao,
                    on_notice=_notice, render_scale=args.render_scale,
                    tier=_tier(args.tier))
    except DisplayUnavailable as err:
        no_display = str(err)
    except GLUnavailable as err:
        # Exit status 1, not a usage error's 2: the machine lacks OpenGL. The message keeps its
        # lines, the packages to install.
        print(f"rustcloth demo: error: {err}", file=sys.stderr)
        return 1
    else:
        try:
            start = time.perf_counter()
            rc = demo.run(args.frames)
            v = demo.viewer
            wall = time.perf_counter() - start
            print(f"demo: {v.frames} frames in {wall:.1f} s ({v.frames / max(wall, 1e-9):.1f} "
                  f"fps), t = {v.sim.time:.2f} s simulated, {v.interaction.cut_count} "
                  f"springs cut ({v.sim.pieces()} pieces), {v.sim.integrator} with "
                  f"{v.sim.substeps} substeps")
            return rc
        finally:
            demo.close()
    # Outside the handler, so an error in the fallback is not chained to the display error.
    print(f"{no_display}: rendering headless to {args.out} instead")
    return main_render([args.scene, "--out", str(args.out), "--gif",
                        "--frames", str(args.frames or 150), "--size", "640x480",
                        "--lights", args.lights, "--overlay", "--tier", args.tier]
                       + (["--ssao"] if args.ssao else [])
                       + (["--script", str(args.script)] if args.script else ["--demo-script"]))


# -- headless --------------------------------------------------------------------------------
def render_parser() -> argparse.ArgumentParser:
    """The parser of ``rustcloth render``."""
    parser = Parser(prog="rustcloth render",
                    description="Render a scene offscreen through EGL: PNG frames, optionally a "
                                "GIF and an MP4.")
    parser.add_argument("scene", help=f"a built-in scene ({', '.join(scenes())}) or a TOML "
                                      "scene file")
    parser.add_argument("--frames", type=positive_int, default=120,
                        help="frames to render (the first at t = 0)")
    parser.add_argument("--fps", type=positive, default=30.0,
                        help="frames per simulated second")
    parser.add_argument("--out", type=Path, default=None,
                        help="output directory (default: out/SCENE)")
    parser.add_argument("--size", type=_size, default="640x480", help="image size, WxH")
    parser.add_argument("--gif", action="store_true", help="also write animation.gif")
    parser.add_argument("--mp4", action="store_true",
                        help="also write animation.mp4 (needs the video extra)")
    parser.add_argument("--script", type=Path, default=None,
                        help="JSON list of scripted events to replay (docs/rendering.md)")
    parser.add_argument("--demo-script", action="store_true",
                        help="the built-in cut, grab and drag, spread over the run")
    parser.add_argument("--view", choices=VIEWS, default="lit", help="what to show")
    parser.add_argument("--overlay", action="store_true",
                        help="draw the status text and the debug view's legend")
    _add_look(parser, "full")
    return parser


def main_render(argv: list[str]) -> int:
    """``rustcloth render``: frames offscreen through EGL, as PNGs and optionally a GIF."""
    return guarded("rustcloth render", lambda: _render(argv))


def _render(argv: list[str]) -> int:
    parser = render_parser()
    args = parser.parse_args(argv)
    if args.script is not None and args.demo_script:
        parser.error("--script and --demo-script: choose one")
    out = args.out or Path("out") / Path(args.scene).stem
    writable_folder(out)
    require("rustcloth render", *RENDER_NEEDS)
    if args.mp4:
        require("rustcloth render --mp4", "imageio_ffmpeg")
    scene = _scene(parser, args.scene)
    script = _script(parser, args.script)
    from .. import Simulation
    from ..render.context import GLUnavailable
    from .headless import write_outputs

    sim = Simulation(scene)
    covered = (args.frames - 1) / args.fps
    if args.demo_script:
        span = float(max(scene.cloth["size"]))
        script = default_script(sim.nx, sim.ny, sim.positions, span, covered)
    elif script is not None and ScriptPlayer(script).end > covered + 1e-9:
        print(f"warning: the script runs to t = {ScriptPlayer(script).end:g} s but "
              f"{args.frames} frames at {args.fps:g} fps end at t = {covered:.3g} s; "
              "what comes later never happens", file=sys.stderr)
    try:
        written, stats = write_outputs(
            sim, out, args.size, args.frames, args.fps, script, gif=args.gif, mp4=args.mp4,
            name=Path(args.scene).stem, view=args.view, ssao=args.ssao, lights=args.lights,
            overlay=args.overlay, on_notice=_notice, tier=_tier(args.tier))
    except GLUnavailable as err:
        print(f"rustcloth render: error: {err}", file=sys.stderr)
        return 1
    pngs = [p for p in written if p.suffix == ".png"]
    print(f"wrote {len(pngs)} PNG frames to {out}/frame_*.png")
    for p in written:
        if p.suffix != ".png":
            print(f"wrote {p}")
    print(stats.summary())
    return 0
