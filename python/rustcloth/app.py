"""The desktop demo (glfw window) and the headless renderer's command line.

``python -m rustcloth demo [SCENE]`` and ``python -m rustcloth render SCENE ...`` call
:func:`main_demo` and :func:`main_render`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from . import Simulation, load_scene, scenes
from .camera import Camera
from .render.context import APT_PACKAGES, GLUnavailable
from .render.interaction import Interaction, Pointer, ScriptPlayer, default_script
from .render.renderer import VIEWS, Renderer, default_camera

INTEGRATORS = ("explicit_euler", "symplectic_euler", "verlet", "rk4", "implicit_euler")
# At most this many fixed steps per frame: beyond it the sim runs slower than real time
# rather than spiralling (each frame taking longer, so needing even more steps).
MAX_STEPS_PER_FRAME = 200

HELP = [
    "left drag: grab and drag     right drag / shift+left: cut",
    "middle drag / alt+left: orbit    scroll: zoom",
    "space: pause   N: step   R: reset   1-9: scenes",
    "I: integrator   +/-: substeps   V: debug view   O: SSAO",
    "H: help   Esc: quit",
]


class DisplayUnavailable(RuntimeError):
    """No window system (no DISPLAY, or glfw cannot initialise)."""


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size must look like 640x480, got {text!r}") from None
    if w < 16 or h < 16 or w > 8192 or h > 8192:
        raise argparse.ArgumentTypeError(f"--size out of range: {text!r}")
    return w, h


def _make_sim(name: str) -> Simulation:
    """The built-in scene ``name``, or a clear error listing the available ones."""
    if name not in scenes():
        raise SystemExit(f"unknown scene {name!r}; available scenes: {', '.join(scenes())}")
    return Simulation(load_scene(name))


# -- the desktop demo ------------------------------------------------------------------------
class Demo:
    """A glfw window showing one simulation. :meth:`run` returns when the window closes,
    Esc is pressed or ``max_frames`` frames have been drawn."""

    def __init__(self, scene: str = "drape", size: tuple[int, int] = (1280, 720),
                 script: list[dict[str, Any]] | None = None, fixed_dt: float | None = None,
                 visible: bool = True) -> None:
        import glfw

        self.glfw = glfw
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            raise DisplayUnavailable("no display (DISPLAY is not set)")
        # glfw errors become our one-line messages below instead of Python warnings.
        errors: list[str] = []
        glfw.ERROR_REPORTING = "ignore"
        glfw.set_error_callback(lambda code, text: errors.append(
            text.decode(errors="replace") if isinstance(text, bytes) else str(text)))
        if not glfw.init():
            why = errors[-1] if errors else "glfw could not initialise the window system"
            raise DisplayUnavailable(f"no display ({why})")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        glfw.window_hint(glfw.VISIBLE, visible)
        self.window = glfw.create_window(size[0], size[1], "rustcloth", None, None)
        if not self.window:
            glfw.terminate()
            why = errors[-1] if errors else "Mesa's GL driver is missing or too old"
            raise GLUnavailable(
                f"no OpenGL 3.3 core context for the window ({why}); install the Debian "
                f"packages {APT_PACKAGES}"
            )
        glfw.make_context_current(self.window)
        glfw.swap_interval(0 if script else 1)
        import moderngl

        self.ctx = moderngl.create_context()
        self.fb_size = glfw.get_framebuffer_size(self.window)
        self.win_size = glfw.get_window_size(self.window)
        self.scene_name = scene
        self.sim = _make_sim(scene)
        self.renderer = Renderer(self.ctx, self.sim, self.fb_size)
        self.camera: Camera = default_camera(self.sim.scene.to_dict(),
                                             self.fb_size[0] / max(self.fb_size[1], 1))
        self._bind_interaction()
        self.script = ScriptPlayer(script) if script else None
        self.fixed_dt = fixed_dt
        self.paused = False
        self.show_help = False
        self.capped = False
        self.frames = 0
        self.fps = 0.0
        self.physics_ms = 0.0
        self.render_ms = 0.0
        self.message = ""
        self._overlay_at = 0.0
        for name, fn in (("set_key_callback", self.on_key),
                         ("set_mouse_button_callback", self.on_mouse_button),
                         ("set_cursor_pos_callback", self.on_cursor),
                         ("set_scroll_callback", self.on_scroll),
                         ("set_framebuffer_size_callback", self.on_resize)):
            getattr(glfw, name)(self.window, fn)

    def _bind_interaction(self) -> None:
        self.interaction = Interaction(self.sim, self.renderer.spacing)
        # Pointer coordinates are window pixels; the camera's aspect follows the framebuffer.
        self.pointer = Pointer(self.interaction, self.camera, self.win_size)

    # -- input -----------------------------------------------------------------------------
    def on_key(self, window: Any, key: int, scancode: int, action: int, mods: int) -> None:
        glfw = self.glfw
        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        if key == glfw.KEY_ESCAPE:
            glfw.set_window_should_close(window, True)
        elif key == glfw.KEY_SPACE:
            self.paused = not self.paused
        elif key == glfw.KEY_N:
            self.paused = True
            self.sim.step(1)
        elif key == glfw.KEY_R:
            self.interaction.clear()
            self.sim.reset()
            self.renderer.invalidate_topology()
        elif glfw.KEY_1 <= key <= glfw.KEY_9:
            names = scenes()
            k = key - glfw.KEY_1
            if k < len(names):
                self.load(names[k])
        elif key == glfw.KEY_I:
            self.cycle_integrator()
        elif key in (glfw.KEY_EQUAL, glfw.KEY_KP_ADD):
            self.sim.substeps = self.sim.substeps + 1
        elif key in (glfw.KEY_MINUS, glfw.KEY_KP_SUBTRACT):
            self.sim.substeps = max(1, self.sim.substeps - 1)
        elif key == glfw.KEY_V:
            self.renderer.view = VIEWS[(VIEWS.index(self.renderer.view) + 1) % len(VIEWS)]
        elif key == glfw.KEY_H:
            self.show_help = not self.show_help
        elif key == glfw.KEY_O:
            self.renderer.ssao = not self.renderer.ssao

    def cycle_integrator(self) -> None:
        current = self.sim.integrator
        start = INTEGRATORS.index(current) if current in INTEGRATORS else -1
        for k in range(1, len(INTEGRATORS) + 1):
            candidate = INTEGRATORS[(start + k) % len(INTEGRATORS)]
            try:
                self.sim.integrator = candidate
                return
            except (ValueError, KeyError):  # not built into this core yet
                continue

    def load(self, name: str) -> None:
        self.interaction.release()
        self.scene_name = name
        self.sim = _make_sim(name)
        self.renderer.set_simulation(self.sim)
        self.camera = default_camera(self.sim.scene.to_dict(),
                                     self.fb_size[0] / max(self.fb_size[1], 1))
        self._bind_interaction()

    def on_mouse_button(self, window: Any, button: int, action: int, mods: int) -> None:
        glfw = self.glfw
        x, y = glfw.get_cursor_pos(window) if self.script is None else self.pointer.pos
        self.mouse_button(button, action, mods, x, y)

    def mouse_button(self, button: int, action: int, mods: int, x: float, y: float) -> None:
        glfw = self.glfw
        if action == glfw.RELEASE:
            self.pointer.release()
            return
        if button == glfw.MOUSE_BUTTON_RIGHT or (
                button == glfw.MOUSE_BUTTON_LEFT and mods & glfw.MOD_SHIFT):
            if not self.pointer.cut_supported:
                self.message = "cutting is not available in this build"
            self.pointer.press("cut", x, y)
        elif button == glfw.MOUSE_BUTTON_MIDDLE or (
                button == glfw.MOUSE_BUTTON_LEFT and mods & glfw.MOD_ALT):
            self.pointer.press("orbit", x, y)
        elif button == glfw.MOUSE_BUTTON_LEFT:
            self.pointer.press("grab", x, y)

    def on_cursor(self, window: Any, x: float, y: float) -> None:
        if self.script is None:
            self.pointer.move(x, y)

    def on_scroll(self, window: Any, dx: float, dy: float) -> None:
        self.camera.zoom(0.9 ** dy)

    def on_resize(self, window: Any, width: int, height: int) -> None:
        if width > 0 and height > 0:
            self.fb_size = (width, height)
            self.win_size = self.glfw.get_window_size(window)
            self.pointer.size = self.win_size
            self.camera.aspect = width / height
            self.renderer.resize(self.fb_size)

    # -- loop ------------------------------------------------------------------------------
    def status_lines(self) -> list[str]:
        sim = self.sim
        flags = (" PAUSED" if self.paused else "") + (" CAPPED (slower than real time)"
                                                      if self.capped else "")
        lines = [
            f"{self.scene_name}  {self.fps:5.1f} fps  physics {self.physics_ms:.3f} ms/step  "
            f"render {self.render_ms:.1f} ms{flags}",
            f"{sim.num_particles} particles  {sim.integrator}  dt {sim.dt:g} s  "
            f"substeps {sim.substeps}  view {self.renderer.view}",
            f"effects: {', '.join(sim.effects)}",
        ]
        if self.message:
            lines.append(self.message)
        return lines + (HELP if self.show_help else ["H: help"])

    def run(self, max_frames: int | None = None) -> int:
        glfw = self.glfw
        last = time.perf_counter()
        fps_t0, fps_frames = last, 0
        try:
            while not glfw.window_should_close(self.window):
                if max_frames is not None and self.frames >= max_frames:
                    break
                now = time.perf_counter()
                frame_dt = self.fixed_dt if self.fixed_dt is not None else min(now - last, 0.25)
                last = now
                glfw.poll_events()
                if self.script is not None:
                    self._scripted_input(self.frames * (self.fixed_dt or 1 / 60))
                if not self.paused:
                    budget = MAX_STEPS_PER_FRAME * self.sim.dt
                    self.capped = frame_dt > budget
                    t0 = time.perf_counter()
                    steps = self.sim.advance(min(frame_dt, budget))
                    if steps:
                        self.physics_ms = 1e3 * (time.perf_counter() - t0) / steps
                t0 = time.perf_counter()
                self.renderer.highlight = self.interaction.grabbed
                self.renderer.sync_stroke(self.interaction)
                self.renderer.update()
                if now - self._overlay_at > 0.25:
                    from .render.overlay import text_panel

                    self.renderer.set_overlay(text_panel(self.status_lines()))
                    glfw.set_window_title(self.window, " | ".join(self.status_lines()[:2]))
                    self._overlay_at = now
                self.renderer.render(self.ctx.screen, self.camera)
                glfw.swap_buffers(self.window)
                self.render_ms = 1e3 * (time.perf_counter() - t0)
                self.frames += 1
                fps_frames += 1
                if now - fps_t0 >= 0.5:
                    self.fps = fps_frames / (now - fps_t0)
                    fps_t0, fps_frames = now, 0
        except KeyboardInterrupt:
            pass
        return 0

    def _scripted_input(self, t: float) -> None:
        """Scripted gestures go through the same mouse handlers as real glfw events."""
        assert self.script is not None
        self.script.update(t, _ScriptedMouse(self), self.renderer.positions)  # type: ignore[arg-type]

    def close(self) -> None:
        self.renderer.set_overlay(None)
        self.glfw.destroy_window(self.window)
        self.glfw.terminate()


class _ScriptedMouse:
    """What a :class:`ScriptPlayer` drives, turning its press/move/release into the demo's
    button and cursor handlers (a scripted cut is a right-button drag, an orbit a middle one)."""

    def __init__(self, demo: Demo) -> None:
        self.demo = demo
        self.size = demo.pointer.size
        self.camera = demo.camera

    @property
    def pos(self) -> tuple[float, float]:
        return self.demo.pointer.pos

    def press(self, mode: str, x: float, y: float) -> None:
        glfw = self.demo.glfw
        button = {"grab": glfw.MOUSE_BUTTON_LEFT, "cut": glfw.MOUSE_BUTTON_RIGHT,
                  "orbit": glfw.MOUSE_BUTTON_MIDDLE}[mode]
        self.demo.mouse_button(button, glfw.PRESS, 0, x, y)

    def move(self, x: float, y: float) -> None:
        self.demo.pointer.move(x, y)

    def release(self) -> None:
        glfw = self.demo.glfw
        self.demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0, *self.demo.pointer.pos)


def main_demo(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="rustcloth demo", description="the desktop demo")
    parser.add_argument("scene", nargs="?", default="drape", help=f"one of {', '.join(scenes())}")
    parser.add_argument("--size", type=_parse_size, default=None,
                        help="WxH window (default 1280x720; 640x480 for the headless fallback)")
    parser.add_argument("--frames", type=int, default=None, help="quit after N frames")
    parser.add_argument("--script", type=Path, help="JSON events to replay (see docs)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"),
                        help="where the headless fallback writes its frames")
    args = parser.parse_args(argv)
    if args.scene not in scenes():
        print(f"unknown scene {args.scene!r}; available scenes: {', '.join(scenes())}",
              file=sys.stderr)
        return 2
    script = json.loads(args.script.read_text()) if args.script else None
    try:
        demo = Demo(args.scene, args.size or (1280, 720), script=script,
                    fixed_dt=1 / 60 if script else None)
    except DisplayUnavailable as err:
        no_display = str(err)
    except GLUnavailable as err:
        print(err, file=sys.stderr)
        return 1
    else:
        try:
            return demo.run(args.frames)
        finally:
            demo.close()
    # Outside the handler, so an error in the fallback is not chained to the display error.
    print(f"{no_display}: rendering headless to {args.out} instead")
    w, h = args.size or (640, 480)
    return main_render([args.scene, "--out", str(args.out), "--gif",
                        "--frames", str(args.frames or 150), "--size", f"{w}x{h}",
                        "--demo-script"]
                       + (["--script", str(args.script)] if args.script else []))


# -- headless --------------------------------------------------------------------------------
def main_render(argv: list[str]) -> int:
    from .render.headless import write_outputs

    parser = argparse.ArgumentParser(prog="rustcloth render",
                                     description="render a scene offscreen through EGL")
    parser.add_argument("scene", help=f"one of {', '.join(scenes())}")
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--out", type=Path, default=None, help="directory (default out/SCENE)")
    parser.add_argument("--size", type=_parse_size, default=(640, 480), help="WxH")
    parser.add_argument("--gif", action="store_true", help="also write animation.gif")
    parser.add_argument("--mp4", action="store_true", help="also write animation.mp4")
    parser.add_argument("--script", type=Path, help="JSON list of {t, action, ...} events")
    parser.add_argument("--demo-script", action="store_true",
                        help="use the built-in grab, drag and cut script")
    parser.add_argument("--view", choices=VIEWS, default="lit")
    parser.add_argument("--ssao", action="store_true", help="screen-space ambient occlusion")
    args = parser.parse_args(argv)
    if args.scene not in scenes():
        print(f"unknown scene {args.scene!r}; available scenes: {', '.join(scenes())}",
              file=sys.stderr)
        return 2
    if args.frames < 1:
        print("--frames must be at least 1", file=sys.stderr)
        return 2
    sim = Simulation(load_scene(args.scene))
    script = None
    if args.script:
        try:
            script = json.loads(args.script.read_text(encoding="utf-8"))
            ScriptPlayer(script)
        except (OSError, ValueError) as err:
            print(f"bad --script {args.script}: {err}", file=sys.stderr)
            return 2
    elif args.demo_script:
        script = default_script(sim)
    out = args.out or Path("out") / args.scene
    try:
        written, stats = write_outputs(sim, out, args.size, args.frames, args.fps, script,
                                       gif=args.gif, mp4=args.mp4, view=args.view,
                                       ssao=args.ssao)
    except GLUnavailable as err:
        print(err, file=sys.stderr)
        return 1
    pngs = [p for p in written if p.suffix == ".png"]
    print(f"wrote {len(pngs)} PNG frames to {out}/frame_*.png")
    for p in written:
        if p.suffix != ".png":
            print(f"wrote {p}")
    print(stats.summary())
    return 0
