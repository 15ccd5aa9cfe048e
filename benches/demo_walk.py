"""The desktop demo walked scene by scene as a user meets it: the real glfw window in real
time (on whatever display is set, e.g. under ``xvfb-run``), each scene for a few seconds of
wall time, with a grab and drag and then a cut made through the window's own mouse handlers,
screenshots of the window, and the numbers a user feels: frames per second, how much of real
time the physics keeps, and how long the first frame takes to appear.

    xvfb-run -s "-screen 0 1280x800x24" python benches/demo_walk.py --out out/walk
    xvfb-run -s "-screen 0 1280x800x24" python benches/demo_walk.py --only tear curtain

Each scene runs in a subprocess of its own (a fresh window and GL context, as a user starting
``rustcloth demo NAME`` gets). Prints a Markdown table and writes, per scene,
``NAME_open.png`` (the first frame), ``NAME_still.png`` (before touching it),
``NAME_drag.png`` (holding a drag), ``NAME_cut.png`` (after a cut) and ``NAME_sheet.png``
(the four at half size, for looking at all of them at once), and ``walk.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent

# Wall-clock seconds since the window opened at which each thing happens.
STILL_AT = 4.0
GRAB_AT, DRAG_FOR, DRAG_SHOT_AT, RELEASE_AT = 4.5, 1.5, 6.5, 7.5
CUT_AT, CUT_FOR = 8.5, 0.6


def _screen_points(demo: Any, indices: Any) -> Any:
    import numpy as np

    v = demo.viewer
    w, h = v.pointer.size
    pos = v.sim.positions
    return np.array([v.camera.project(pos[k], w, h)[:2] for k in indices])


def _grab_particle(sim: Any, scene: str) -> int:
    """A lower corner for ``tear`` (what its description asks for), else the alive particle
    nearest the cloth's centroid."""
    import numpy as np

    if scene == "tear":
        return 0
    pos = sim.positions
    alive = np.flatnonzero(sim.alive)
    c = pos[alive].mean(axis=0)
    return int(alive[np.argmin(np.linalg.norm(pos[alive] - c, axis=1))])


def run_scene(scene: str, size: tuple[int, int], seconds: float, out: Path) -> dict[str, Any]:
    """One scene in the live window (this process); returns its numbers."""
    import glfw
    import numpy as np
    from PIL import Image

    t_start = time.perf_counter()
    from rustcloth.viewer.window import MAX_FRAME_S, Demo

    notices: list[str] = []
    demo = Demo(scene, size, on_notice=notices.append)
    t_built = time.perf_counter()
    v = demo.viewer
    shots: dict[str, Any] = {}
    frame_s: list[float] = []
    ratios: dict[str, float] = {}
    status: dict[str, str] = {}
    grab_px: Any = None
    drag_to: Any = None
    cut_path: Any = None
    phase = "open"
    gl_errors: list[str] = []
    last = time.perf_counter()
    opened = None
    first_frame = None
    sim_t0 = 0.0
    try:
        while True:
            glfw.poll_events()
            now = time.perf_counter()
            seconds_f = min(now - last, MAX_FRAME_S)
            last = now
            t = 0.0 if opened is None else now - opened
            if phase == "open" and t >= GRAB_AT:
                grab = _grab_particle(v.sim, scene)
                grab_px = _screen_points(demo, [grab])[0]
                w, h = v.pointer.size
                # Away from the cloth and a little up (down and out for tear's corner).
                off = np.array([-0.2 * w, 0.25 * h]) if scene == "tear" else \
                    np.array([0.15 * w, -0.15 * h])
                drag_to = grab_px + off
                v.pointer.move(*grab_px)
                demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0, *grab_px)
                status["grabbed"] = str(v.interaction.grabbed)
                phase = "drag"
            if phase == "drag":
                f = min(1.0, (t - GRAB_AT) / DRAG_FOR)
                v.pointer.move(*(grab_px + f * (drag_to - grab_px)))
                if t >= RELEASE_AT:
                    demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0, *v.pointer.pos)
                    phase = "released"
            if phase == "released" and t >= CUT_AT:
                pts = _screen_points(demo, np.flatnonzero(v.sim.alive))
                lo, hi = pts.min(axis=0), pts.max(axis=0)
                y = lo[1] + 0.6 * (hi[1] - lo[1])
                cut_path = (np.array([lo[0] - 10, y]), np.array([hi[0] + 10, y]))
                v.pointer.move(*cut_path[0])
                demo.mouse_button(glfw.MOUSE_BUTTON_RIGHT, glfw.PRESS, 0, *cut_path[0])
                phase = "cut"
            if phase == "cut":
                f = min(1.0, (t - CUT_AT) / CUT_FOR)
                v.pointer.move(*(cut_path[0] + f * (cut_path[1] - cut_path[0])))
                if f >= 1.0:
                    demo.mouse_button(glfw.MOUSE_BUTTON_RIGHT, glfw.RELEASE, 0, *v.pointer.pos)
                    phase = "done"
            f0 = time.perf_counter()
            v.frame(demo.ctx.screen, 0.0 if opened is None else seconds_f)
            # The demo's own GL errors, read before a screenshot: moderngl's read of the
            # window's framebuffer leaves GL_INVALID_OPERATION behind it on Mesa (the image
            # is whole), which reading ctx.error then clears.
            if (err := demo.ctx.error) != "GL_NO_ERROR":
                gl_errors.append(err)
            if opened is None:
                shots["open"] = demo.ctx.screen.read(components=3)
                _ = demo.ctx.error
            elif any(k not in shots and t >= at for k, at in
                     (("still", STILL_AT), ("drag", DRAG_SHOT_AT), ("cut", seconds - 0.3))):
                key = next(k for k, at in (("still", STILL_AT), ("drag", DRAG_SHOT_AT),
                                          ("cut", seconds - 0.3)) if k not in shots and t >= at)
                shots[key] = demo.ctx.screen.read(components=3)
                _ = demo.ctx.error
                ratios[key] = v.stepper.real_time_ratio()
                status[key] = str(v.status_lines()[0])
            glfw.swap_buffers(demo.window)
            done = time.perf_counter()
            if opened is None:
                opened = done
                first_frame = done - t_built
                sim_t0 = v.sim.time
            else:
                frame_s.append(done - f0)
            if t >= seconds:
                break
        wall = time.perf_counter() - opened
        w, h = demo.ctx.screen.size if hasattr(demo.ctx.screen, "size") else size
        report = {
            "scene": scene, "import_and_window_s": t_built - t_start,
            "first_frame_s": first_frame, "frames": len(frame_s),
            "fps": len(frame_s) / wall, "real_time": (v.sim.time - sim_t0) / wall,
            "render_ms": 1e3 * v.render_s, "ratios": ratios, "status": status,
            "notices": notices, "pieces": int(v.sim.pieces()),
            "cut": v.interaction.cut_count, "gl_errors": sorted(set(gl_errors)),
            "tier": v.renderer.tier, "scale": v.renderer.scale,
            "particles": int(v.sim.num_particles),
        }
    finally:
        demo.close()
    images = {}
    for key, data in shots.items():
        img = Image.frombytes("RGB", (w, h), data).transpose(Image.Transpose.FLIP_TOP_BOTTOM)
        img.save(out / f"{scene}_{key}.png")
        images[key] = img
    sheet = Image.new("RGB", (w, h), (0, 0, 0))
    for k, key in enumerate(("open", "still", "drag", "cut")):
        if key in images:
            sheet.paste(images[key].resize((w // 2, h // 2)), ((k % 2) * (w // 2),
                                                               (k // 2) * (h // 2)))
    sheet.save(out / f"{scene}_sheet.png")
    return report


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None, help="these scenes (default: all)")
    parser.add_argument("--seconds", type=float, default=12.0, help="wall seconds a scene")
    parser.add_argument("--size", default="1280x720")
    parser.add_argument("--out", type=Path, default=Path("out/walk"))
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    if args.child is not None:
        print(json.dumps(run_scene(args.child, size, args.seconds, args.out)))  # type: ignore[arg-type]
        return 0
    import rustcloth

    names = args.only or rustcloth.scenes()
    rows = []
    for name in names:
        proc = subprocess.run([sys.executable, __file__, "--child", name, "--seconds",
                               str(args.seconds), "--size", args.size, "--out", str(args.out)],
                              capture_output=True, text=True, env=os.environ)
        if proc.returncode != 0 or not proc.stdout.strip():
            rows.append({"scene": name, "failed": proc.stderr[-2000:]})
            print(f"{name}: FAILED\n{proc.stderr[-2000:]}", file=sys.stderr)
            continue
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        row["stderr"] = proc.stderr[-2000:]
        rows.append(row)
        print(f"| {name} | {row['fps']:.1f} | {100 * row['real_time']:.0f} % | "
              f"{row['first_frame_s']:.2f} s (+{row['import_and_window_s']:.2f} s) | "
              f"{row['pieces']} pieces, {row['cut']} cut | {row['notices']} |", flush=True)
    (args.out / "walk.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
