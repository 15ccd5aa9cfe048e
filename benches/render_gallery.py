"""Regenerates the pictures in docs/ from the current renderer, offscreen through EGL: one
screenshot per built-in scene, a drag, a cut, a rollback on the overlay, the debug views, the
light presets, the two quality tiers side by side, and the README's GIF of a drag and a cut;
and the showcase: the scenes that do what their names say (a drag rips `tear`, `fold` stays
over its bar, `pile` piles, `flag` and `curtain` in the wind, `twist` winds into a rope) as one
contact sheet, and a GIF of the rip. (It sits beside render_times.py, which regenerates the
frame-time tables; neither is run by the tests.)

    python benches/render_gallery.py [--out docs] [--only showcase]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import rustcloth
from PIL import Image
from rustcloth.render import create_standalone_context
from rustcloth.render.constants import VIEWS
from rustcloth.render.lights import PRESET_NAMES
from rustcloth.viewer.headless import write_gif
from rustcloth.viewer.loop import Viewer

Frame = npt.NDArray[np.uint8]
SIZE = (960, 600)
FPS = 30.0


def run(ctx: Any, scene: str, seconds: float, size: tuple[int, int] = SIZE, *,
        script: list[dict[str, Any]] | None = None, keep: tuple[float, ...] = (),
        keys: dict[float, str] | None = None, title: str | None = None,
        hand: Callable[[rustcloth.Simulation, float], None] | None = None,
        **options: Any) -> dict[float, Frame]:
    """Run ``scene`` for ``seconds`` at FPS, returning the frames at the times in ``keep``
    (and the last one under ``seconds``); ``title`` replaces the overlay's status text;
    ``hand(sim, t)`` acts on the simulation through the API before the frame at time t."""
    sim = rustcloth.Simulation(rustcloth.load_scene(scene))
    viewer = Viewer(ctx, sim, size, name=scene, realtime=False, script=script,
                    overlay=title is not None or options.pop("overlay", False), **options)
    if title is not None:
        viewer.status_lines = lambda: [title]  # type: ignore[method-assign]
    fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4)])
    image = np.empty((size[1], size[0], 3), dtype=np.uint8)
    frames = round(seconds * FPS)
    wanted = {round(t * FPS): t for t in (*keep, seconds)}
    pending = dict(sorted((round(t * FPS), k) for t, k in (keys or {}).items()))
    out: dict[float, Frame] = {}
    for k in range(frames + 1):
        if k in pending:
            viewer.key(pending[k])
        if hand is not None:
            hand(sim, k / FPS)
        viewer.frame(fbo, 0.0 if k == 0 else 1.0 / FPS)
        if k in wanted:
            fbo.read_into(image, components=3)
            out[wanted[k]] = image[::-1].copy()
    fbo.release()
    return out


def montage(images: list[Frame], columns: int) -> Frame:
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    sheet = np.zeros((rows * h, columns * w, 3), dtype=np.uint8)
    for k, img in enumerate(images):
        r, c = divmod(k, columns)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = img
    return sheet


def _save(path: Path, frame: Frame) -> None:
    Image.fromarray(frame).save(path, optimize=True)
    print(f"wrote {path}", file=sys.stderr)


def _particle(scene: str, i: float, j: float) -> int:
    sim = rustcloth.Simulation(rustcloth.load_scene(scene))
    return round(j * (sim.ny - 1)) * sim.nx + round(i * (sim.nx - 1))


def drag_and_cut(scene: str) -> list[dict[str, Any]]:
    """Grab the middle of the free side, pull it towards the camera and up, let go; then cut
    across the cloth from side to side."""
    grab = _particle(scene, 0.5, 0.15)
    left, right = _particle(scene, 0.08, 0.55), _particle(scene, 0.92, 0.55)
    return [
        {"t": 0.8, "action": "grab", "particle": grab},
        {"t": 0.85, "action": "drag", "x": 0.62, "y": 0.35, "duration": 0.9},
        {"t": 2.2, "action": "release"},
        {"t": 2.9, "action": "cut", "duration": 0.8,
         "path": [{"particle": left}, {"particle": right}]},
    ]


def corner_drag(move: tuple[float, float, float], start: float, seconds: float
                ) -> Callable[[rustcloth.Simulation, float], None]:
    """A hand that grabs the lower-left corner at ``start`` (picked by a ray from the viewer's
    side), leads it by ``move`` (m) over ``seconds`` frame by frame, holds it a second and lets
    go: the drag that tests/test_grip.py rips `tear` with."""
    held: dict[str, Any] = {}

    def act(sim: rustcloth.Simulation, t: float) -> None:
        if t < start or held.get("released"):
            return
        if "from" not in held:
            hit = sim.pick(sim.positions[0] + [0.0, 0.0, 3.0], [0.0, 0.0, -1.0])
            assert hit is not None, "the corner is not under the ray"
            sim.grab(hit[0])
            held["from"] = sim.positions[hit[0]].copy()
        if t - start <= seconds + 1.0:
            sim.drag_to(held["from"] + np.asarray(move) * min(1.0, (t - start) / seconds))
        else:
            sim.release()
            held["released"] = True

    return act


def showcase(ctx: Any, out: Path) -> None:
    """The showcase scenes, each at a moment that shows what its name promises, as one contact
    sheet (showcase.png), and the rip of `tear` as a GIF (tear.gif)."""
    small = (480, 300)
    rip = corner_drag((-0.6, -0.6, 0.0), 0.5, 0.2)
    shots = [
        run(ctx, "tear", 1.4, small, hand=rip, title="tear: a drag rips it")[1.4],
        run(ctx, "fold", 5.0, small, title="fold: over the bar after 5 s")[5.0],
        run(ctx, "pile", 4.0, small, title="pile: dropped on a ball, piled")[4.0],
        run(ctx, "flag", 2.5, small, title="flag: in the wind")[2.5],
        run(ctx, "curtain", 2.5, small, title="curtain: in a draught")[2.5],
        run(ctx, "twist", 3.0, small, title="twist: winding into a rope")[3.0],
    ]
    _save(out / "showcase.png", montage(shots, 2))
    gif = run(ctx, "tear", 3.0, small, hand=corner_drag((-0.6, -0.6, 0.0), 0.5, 0.2),
              keep=tuple(k / 15.0 for k in range(45)))
    write_gif(out / "tear.gif", [gif[t] for t in sorted(gif)][::2], 15.0 / 2)
    print(f"wrote {out / 'tear.gif'}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("docs"), help="where to write")
    parser.add_argument("--only", choices=("showcase",), default=None,
                        help="only these pictures (default: all)")
    args = parser.parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    ctx = create_standalone_context()
    showcase(ctx, out)
    if args.only == "showcase":
        ctx.release()
        return 0

    for scene, t in (("drape", 3.0), ("hanging", 2.5), ("freefall", 1.6), ("curtain", 2.5)):
        _save(out / f"screenshot_{scene}.png", run(ctx, scene, t)[t])

    # A drag and a cut, mid-gesture, and the GIF of both.
    script = drag_and_cut("hanging")
    shots = run(ctx, "hanging", 3.4, script=script, keep=(1.7, 3.4))
    _save(out / "screenshot_drag.png", shots[1.7])
    _save(out / "screenshot_cut.png", shots[3.4])
    gif = run(ctx, "hanging", 5.0, (480, 300), script=script,
              keep=tuple(k / 15.0 for k in range(75)))
    write_gif(out / "demo.gif", [gif[t] for t in sorted(gif)][::2], 15.0 / 2)
    print(f"wrote {out / 'demo.gif'}", file=sys.stderr)

    # explicit_euler in hanging diverges; the overlay says what the viewer did about it.
    start = rustcloth.load_scene("hanging").to_dict()["integrator"]
    presses = (rustcloth.INTEGRATORS.index("explicit_euler")
               - rustcloth.INTEGRATORS.index(start)) % len(rustcloth.INTEGRATORS)
    keys = {0.5 + 0.1 * k: "I" for k in range(presses)}  # ... -> explicit_euler
    shot = run(ctx, "hanging", 2.5, keys=keys, overlay=True)
    _save(out / "screenshot_rollback.png", shot[2.5])

    # Every view with its legend, and every light preset, as contact sheets.
    small = (480, 300)
    views = []
    for view in VIEWS:
        views.append(run(ctx, "drape", 2.0, small, view=view, title=f"view: {view}")[2.0])
    _save(out / "screenshot_views.png", montage(views, 2))
    lights = [run(ctx, "curtain", 2.0, small, lights=name, title=f"lights: {name}")[2.0]
              for name in PRESET_NAMES]
    _save(out / "screenshot_lights.png", montage(lights, 2))
    tiers = [run(ctx, "drape", 3.0, small, tier=tier, title=f"tier: {tier}")[3.0]
             for tier in ("full", "software")]
    _save(out / "screenshot_tiers.png", montage(tiers, 2))
    ctx.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
