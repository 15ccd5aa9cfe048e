"""The desktop demo: a glfw window (OpenGL 3.3 core) whose keys, buttons and cursor drive a
:class:`~.loop.Viewer`, which runs in real time."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import glfw
import moderngl

from ..render.context import APT_PACKAGES, GLUnavailable
from .keys import ALIASES, KEYS
from .loop import Viewer, ViewerInput, make_simulation

TITLE_PERIOD = 0.25
MAX_FRAME_S = 1.0
"""Longest wall time one frame may ask the physics for (after a stall, a window drag)."""


class DisplayUnavailable(RuntimeError):
    """No window system (no DISPLAY, or glfw cannot initialise)."""


def _key_codes() -> dict[int, str]:
    """glfw key code -> the key's name in :data:`~.keys.KEYS`."""
    codes = {getattr(glfw, f"KEY_{name}"): name for name in KEYS}
    for alias, name in ALIASES.items():
        code = getattr(glfw, f"KEY_{alias}", None)
        if code is not None:
            codes[code] = name
    return codes


class Demo:
    """A glfw window showing one simulation. :meth:`run` returns when the window closes,
    Esc is pressed or ``max_frames`` frames have been drawn.

    ``fixed_dt``: every frame advances exactly that much simulated time, however long it
    takes (tests); otherwise the physics keeps real time within half the frame.
    ``render_scale``: see :class:`~.loop.Viewer` (None: adapted to the frame time).
    ``tier``: the renderer's quality tier; None: ``software`` on a CPU rasteriser.
    """

    def __init__(self, scene: str = "drape", size: tuple[int, int] = (1280, 720),
                 script: list[dict[str, Any]] | None = None, fixed_dt: float | None = None,
                 visible: bool = True, lights: str = "studio", ssao: bool = False,
                 on_notice: Callable[[str], None] | None = None,
                 render_scale: float | None = None, tier: str | None = None) -> None:
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
        window = glfw.create_window(size[0], size[1], "rustcloth", None, None)
        if not window:
            glfw.terminate()
            why = errors[-1] if errors else "Mesa's GL driver is missing or too old"
            raise GLUnavailable(
                f"no OpenGL 3.3 core context for the window ({why}); install the Debian "
                f"packages {APT_PACKAGES}"
            )
        self.window = window
        glfw.make_context_current(window)
        glfw.swap_interval(0 if script else 1)
        self.ctx = moderngl.create_context()
        self.fixed_dt = fixed_dt
        self.scripted = script is not None
        fb_size = glfw.get_framebuffer_size(window)
        self.viewer = Viewer(self.ctx, make_simulation(scene), fb_size, name=scene,
                             realtime=fixed_dt is None, script=script, lights=lights,
                             ssao=ssao, on_notice=on_notice, render_scale=render_scale,
                             tier=tier)
        self.viewer.input = WindowInput(self)
        self.viewer.resize(fb_size, glfw.get_window_size(window))
        self._codes = _key_codes()
        self._names = {name: code for code, name in self._codes.items()}
        glfw.set_key_callback(window, self.on_key)
        glfw.set_mouse_button_callback(window, self.on_mouse_button)
        glfw.set_cursor_pos_callback(window, self.on_cursor)
        glfw.set_scroll_callback(window, self.on_scroll)
        glfw.set_framebuffer_size_callback(window, self.on_resize)

    # -- input -----------------------------------------------------------------------------
    def on_key(self, window: Any, key: int, scancode: int, action: int, mods: int) -> None:
        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        name = self._codes.get(key)
        if name is not None:
            self.viewer.key(name)
        if self.viewer.quit:
            glfw.set_window_should_close(window, True)

    def press_key(self, name: str) -> None:
        """A key press as glfw would report it (scripted ``key`` events come through here)."""
        code = self._names.get(ALIASES.get(name.upper(), name.upper()))
        if code is not None:
            self.on_key(self.window, code, 0, glfw.PRESS, 0)

    def on_mouse_button(self, window: Any, button: int, action: int, mods: int) -> None:
        pointer = self.viewer.pointer
        x, y = pointer.pos if self.scripted else glfw.get_cursor_pos(window)
        self.mouse_button(button, action, mods, x, y)

    def mouse_button(self, button: int, action: int, mods: int, x: float, y: float) -> None:
        pointer = self.viewer.pointer
        if action == glfw.RELEASE:
            pointer.release()
        elif button == glfw.MOUSE_BUTTON_LEFT and mods & glfw.MOD_CONTROL:
            pointer.press("collider", x, y)
        elif button == glfw.MOUSE_BUTTON_RIGHT or (
                button == glfw.MOUSE_BUTTON_LEFT and mods & glfw.MOD_SHIFT):
            pointer.press("cut", x, y)
        elif button == glfw.MOUSE_BUTTON_MIDDLE or (
                button == glfw.MOUSE_BUTTON_LEFT and mods & glfw.MOD_ALT):
            pointer.press("orbit", x, y)
        elif button == glfw.MOUSE_BUTTON_LEFT:
            pointer.press("grab", x, y)

    def on_cursor(self, window: Any, x: float, y: float) -> None:
        if not self.scripted:
            self.viewer.pointer.move(x, y)

    def on_scroll(self, window: Any, dx: float, dy: float) -> None:
        self.viewer.camera.zoom(0.9 ** dy)

    def on_resize(self, window: Any, width: int, height: int) -> None:
        if width > 0 and height > 0:
            self.viewer.resize((width, height), glfw.get_window_size(window))

    # -- loop ------------------------------------------------------------------------------
    def run(self, max_frames: int | None = None) -> int:
        """Draw frames until the window closes, Esc, or ``max_frames`` in all; returns 0."""
        viewer = self.viewer
        last = time.perf_counter()
        title_at = -1.0
        try:
            while not glfw.window_should_close(self.window):
                if max_frames is not None and viewer.frames >= max_frames:
                    break
                glfw.poll_events()
                now = time.perf_counter()
                seconds = self.fixed_dt if self.fixed_dt is not None else min(now - last,
                                                                                MAX_FRAME_S)
                last = now
                viewer.frame(self.ctx.screen, seconds)
                if viewer.quit:
                    glfw.set_window_should_close(self.window, True)
                if now - title_at > TITLE_PERIOD:
                    lines = [s if isinstance(s, str) else s[0] for s in viewer.status_lines()]
                    glfw.set_window_title(self.window, " | ".join(lines[:2]))
                    title_at = now
                glfw.swap_buffers(self.window)
        except KeyboardInterrupt:
            pass
        return 0

    def close(self) -> None:
        self.viewer.renderer.panels.clear()
        glfw.destroy_window(self.window)
        glfw.terminate()


class WindowInput(ViewerInput):
    """Scripted input as window events: presses and releases go through the glfw button
    handler (a scripted cut is a right-button drag, an orbit a middle one, a collider move a
    Ctrl + left one), keys through the key handler."""

    def __init__(self, demo: Demo) -> None:
        super().__init__(demo.viewer)
        self.demo = demo

    def press(self, mode: str, x: float, y: float) -> None:
        button, mods = {"grab": (glfw.MOUSE_BUTTON_LEFT, 0),
                        "cut": (glfw.MOUSE_BUTTON_RIGHT, 0),
                        "orbit": (glfw.MOUSE_BUTTON_MIDDLE, 0),
                        "collider": (glfw.MOUSE_BUTTON_LEFT, glfw.MOD_CONTROL)}[mode]
        self.demo.mouse_button(button, glfw.PRESS, mods, x, y)

    def release(self) -> None:
        self.demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0, *self.pos)

    def key(self, name: str) -> None:
        self.demo.press_key(name)
