"""The viewer: one simulation, its renderer, camera, gestures, physics pacing, divergence
recovery and overlay, and the one frame loop body the desktop demo and headless rendering
both run (:meth:`Viewer.frame`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import moderngl

from .. import INTEGRATORS, Simulation, load_scene, scenes
from ..camera import Camera
from ..drivers import driver_for
from ..errors import ParameterError
from ..render.constants import VIEWS
from ..render.overlay import Line, legend, text_panel
from ..render.renderer import Renderer
from ..render.tiers import TIERS, auto_tier
from .interaction import Interaction, Pointer
from .keys import KEYS, command_for, scene_key_help
from .physics import MIN_BUDGET_S, FramePhysics, Stepper
from .script import ScriptInput, ScriptPlayer

RENDER_TARGET_S = 0.040
"""Live, the 3D passes draw at a lower resolution (scaled up by the last pass) while a frame
takes longer than this to render, and go back up when there is room."""
SCALE_STEP, MIN_SCALE, SCALE_PERIOD = 0.85, 0.5, 1.0
NOTICE_SECONDS = 8.0
"""How long a notice stays on the overlay (viewer clock)."""
OVERLAY_PERIOD = 0.25
"""Seconds between overlay refreshes when running live."""
OVERLAY_MAX_WIDTH = 720
"""Overlay text wraps at this many pixels (or the window's width), so a long notice is a
short block in the corner, not a band across the window."""
WARNING = (255, 170, 60)
KEY_LABELS = {"SPACE": "Space", "EQUAL": "+", "MINUS": "-", "ESCAPE": "Esc"}
MOUSE_HELP = [
    "left drag: grab and drag      right drag / shift + left drag: cut",
    "middle drag / alt + left drag: orbit      scroll: zoom",
    "ctrl + left drag: move a collider (it pushes the cloth; a turning one stops turning)",
]


def make_simulation(name: str) -> Simulation:
    """A built-in scene by name, or a scene TOML file by path."""
    return Simulation(load_scene(name))


class Viewer:
    """Everything on screen for one simulation at a time. :meth:`frame` runs one frame into
    any framebuffer; the commands (:meth:`command`) are what keys do.

    ``realtime``: physics keeps up with the frames' wall time within a budget (the demo);
    otherwise every frame advances exactly the simulated time it is given (headless, tests).
    ``render_scale``: the 3D passes' share of the output resolution, each way; None: 1 when
    offline, adapted to :data:`RENDER_TARGET_S` when live.
    ``make_sim`` builds the simulation for a scene name (keys 1..9); ``on_notice`` hears
    every notice the overlay shows (the demo prints them). ``tier``: the renderer's quality
    tier (:data:`~rustcloth.render.renderer.TIERS`), None for the one the context calls for
    (``software`` on a CPU rasteriser).
    """

    def __init__(self, ctx: moderngl.Context, sim: Any, size: tuple[int, int], *,
                 name: str = "scene", realtime: bool = True,
                 script: list[dict[str, Any]] | None = None, view: str = "lit",
                 ssao: bool = False, lights: str = "studio", overlay: bool = True,
                 make_sim: Callable[[str], Any] = make_simulation,
                 on_notice: Callable[[str], None] | None = None,
                 render_scale: float | None = None, tier: str | None = "full") -> None:
        self.ctx = ctx
        self.size = size
        self.pointer_size = size
        self.realtime = realtime
        self.overlay = overlay
        self.make_sim = make_sim
        self.on_notice = on_notice
        self.renderer = Renderer(ctx, sim, size, lights=lights,
                                 tier=auto_tier(ctx) if tier is None else tier)
        self.renderer.view = view
        self.renderer.ssao = ssao
        self.auto_scale = realtime and render_scale is None
        if render_scale is not None:
            self.renderer.resize(size, render_scale)
        self._scaled_at = time.perf_counter()
        self.script = ScriptPlayer(script) if script else None
        self.input: ScriptInput = ViewerInput(self)
        self.clock = 0.0
        self.frames = 0
        self.fps = 0.0
        self.render_s = 0.0
        self.last_physics = FramePhysics()
        self.paused = False
        self.show_help = False
        self.show_details = False
        self.quit = False
        self.notices: list[tuple[str, float, bool]] = []
        self._fps_at, self._fps_frames = time.perf_counter(), 0
        self._overlay_at = -1.0
        self._bind(sim, name)

    def _bind(self, sim: Any, name: str) -> None:
        """Start showing ``sim``: camera, gestures and stepping for it."""
        self.sim = sim
        self.name = name
        # The scene's own settings, which C turns back on (the defaults where it had none).
        self.scene_self_collision = sim.self_collision
        self.stepper = Stepper(sim, driver_for(name, sim))
        layout = self.renderer.layout
        self.camera: Camera = layout.camera(self.size[0] / max(self.size[1], 1))
        self.interaction = Interaction(sim)
        self.pointer = Pointer(self.interaction, self.camera, self.pointer_size)
        self._overlay_at = -1.0
        self._pieces_at: tuple[int, int] | None = None

    # -- the frame -------------------------------------------------------------------------
    def frame(self, target: moderngl.Framebuffer, seconds: float) -> None:
        """One frame of ``seconds`` (wall time when live, simulated time offline): the
        script's input due by now, the physics, the upload, the passes into ``target``."""
        self.clock += seconds
        if self.script is not None:
            self.script.update(self.clock, self.input, self.renderer.positions)
        if not self.paused:
            self.interaction.pose_collider()
            budget = max(MIN_BUDGET_S, self.render_s) if self.realtime else None
            self._physics(self.stepper.run(seconds, budget))
        t0 = time.perf_counter()
        r = self.renderer
        r.highlight = self.interaction.grabbed
        r.sync_stroke(self.interaction.stroke(), self.interaction.stroke_version)
        r.update()
        self._refresh_overlay()
        r.render(target, self.camera)
        if self.realtime:
            # llvmpipe draws at the flush: wait for it, or the swap would take the time and
            # the physics budget (and the render scale) would go by the queuing alone.
            self.ctx.finish()
        elapsed = time.perf_counter() - t0
        self.render_s = elapsed if self.frames == 0 else 0.8 * self.render_s + 0.2 * elapsed
        self.frames += 1
        self._count_fps()
        if self.auto_scale:
            self._adapt_scale()

    def _adapt_scale(self) -> None:
        """Trade resolution for frame rate, at most once per :data:`SCALE_PERIOD`, in the
        full tier. The software tier stays at full resolution: on a CPU rasteriser scaling
        the image up is a textured full-screen pass that costs about what drawing fewer
        pixels saves (at 1280x720 on llvmpipe a 70 % frame cost more than a full one)."""
        r = self.renderer
        if r.tier == "software":
            if r.scale < 1.0:
                r.resize(self.size, 1.0)
            return
        now = time.perf_counter()
        if now - self._scaled_at < SCALE_PERIOD:
            return
        scale = r.scale
        if self.render_s > RENDER_TARGET_S and scale > MIN_SCALE:
            scale = max(MIN_SCALE, scale * SCALE_STEP)
        elif self.render_s < 0.5 * RENDER_TARGET_S and scale < 1.0:
            scale = min(1.0, scale / SCALE_STEP)
        if scale != r.scale:
            r.resize(self.size, scale)
            self._scaled_at = now

    def _physics(self, report: FramePhysics) -> None:
        self.last_physics = report
        for text in report.notices:
            self.notify(text, warning=True)
        if report.notices:
            # A remedy may have let go of the grab or reset the scene.
            if self.sim.grabbed() is None:
                self.interaction.drag_point = None
            self.renderer.invalidate_topology()

    def _count_fps(self) -> None:
        self._fps_frames += 1
        now = time.perf_counter()
        if now - self._fps_at >= 0.5:
            self.fps = self._fps_frames / (now - self._fps_at)
            self._fps_at, self._fps_frames = now, 0

    def resize(self, size: tuple[int, int], pointer_size: tuple[int, int] | None = None) -> None:
        """The output is now ``size`` pixels; the pointer's window pixels ``pointer_size``."""
        self.size = size
        self.pointer_size = pointer_size or size
        self.pointer.size = self.pointer_size
        self.camera.aspect = size[0] / max(size[1], 1)
        self.renderer.resize(size)  # at the scale it had
        self._overlay_at = -1.0

    # -- notices and the overlay -----------------------------------------------------------
    def notify(self, text: str, warning: bool = False) -> None:
        """Show ``text`` on the overlay for a while (and tell ``on_notice``)."""
        self.notices.append((text, self.clock + NOTICE_SECONDS, warning))
        self.notices = self.notices[-4:]
        self._overlay_at = -1.0
        if self.on_notice is not None:
            self.on_notice(text)

    def _pieces(self) -> int:
        """The cloth's pieces, counted again only after a cut or a tear (an O(n) pass)."""
        version = self.sim.topology_version
        if self._pieces_at is None or self._pieces_at[0] != version:
            self._pieces_at = (version, self.sim.pieces())
        return self._pieces_at[1]

    def status_lines(self) -> list[Line]:
        sim, r = self.sim, self.renderer
        physics = self.last_physics
        if self.paused:
            state = "PAUSED"
        elif self.realtime and self.stepper.real_time_ratio() < 0.97:
            state = f"SLOW: physics at {100 * self.stepper.real_time_ratio():.0f} % of real time"
        else:
            state = "real time" if self.realtime else ""
        per_step = 1e3 * physics.seconds / physics.steps if physics.steps else 0.0
        scale = f" at {100 * r.scale:.0f} % scale" if r.scale < 1.0 else ""
        substeps = f"substeps {sim.substeps}"
        if self.stepper.recovery.raised:
            substeps += f" (raised from {self.stepper.recovery.chosen_substeps})"
        # One line unless asked (D): what a person watching needs, and what changed without
        # their asking (a raised substep count, a SLOW or PAUSED state).
        raised = f"  {substeps}" if self.stepper.recovery.raised else ""
        tier = "  software tier (Q)" if r.tier == "software" else ""
        gap = sim.seam_gap()  # how far a garment's sewing has come
        seams = "" if gap is None else f"  seam gap {1e3 * gap:.1f} mm"
        # The rate is counted over half a second of frames: until then there is none to show
        # (a "0.0 fps" on the opening frame reads as a frozen window).
        fps = f"{self.fps:.1f}" if self.fps > 0.0 else "--"
        lines: list[Line] = [
            f"{self.name}  t = {sim.time:.2f} s  {fps} fps{tier}{raised}{seams}  "
            f"H help  D details  {state}".rstrip()]
        if self.show_details:
            ssao = "on" if r.ssao else "off"
            if r.ssao and r.tier == "software" and r.view == "lit":
                ssao = "on (drawn in the full tier only)"
            lines += [
                f"render {1e3 * self.render_s:.1f} ms{scale} ({r.tier} tier)  physics "
                f"{1e3 * physics.seconds:.1f} ms/frame ({physics.steps} steps, "
                f"{per_step:.2f} ms/step)",
                f"{sim.num_particles} particles  {self._pieces()} pieces  {sim.integrator}  "
                f"dt {sim.dt:g} s  {substeps}  self-collision "
                f"{'off' if sim.self_collision is None else 'on'} (C)  "
                f"view {r.view}  lights {r.lights.name}  SSAO {ssao}",
                f"effects: {', '.join(sim.effects)}",
            ]
        lines += [(text, WARNING) if warn else text
                  for text, until, warn in self.notices if until >= self.clock]
        if not self.show_help:
            return lines
        names = scenes()
        keys = [f"{KEY_LABELS.get(k, k)}: {h}" for k, (_, h) in KEYS.items() if h]
        scene_keys = scene_key_help(names)
        return lines + MOUSE_HELP + ["   ".join(keys[i:i + 4]) for i in range(0, len(keys), 4)] \
            + [scene_keys]

    def _refresh_overlay(self) -> None:
        if not self.overlay:
            return
        now = time.perf_counter()
        if self.realtime and 0.0 <= now - self._overlay_at < OVERLAY_PERIOD:
            return
        self._overlay_at = now
        self.renderer.set_panel("status", text_panel(
            self.status_lines(), max_width=min(self.size[0], OVERLAY_MAX_WIDTH)))
        self.renderer.set_panel("legend", legend(self.renderer.view), "bottom-left")

    # -- commands (keys) -------------------------------------------------------------------
    def key(self, name: str) -> None:
        """Run what key ``name`` does (names as in :data:`~.keys.KEYS`); others do nothing."""
        cmd = command_for(name)
        if cmd is not None:
            self.command(cmd)

    def command(self, name: str) -> None:
        if name.startswith("scene_"):
            self.load_scene_number(int(name.removeprefix("scene_")))
        else:
            getattr(self, f"_cmd_{name}")()
        self._overlay_at = -1.0

    def _cmd_toggle_pause(self) -> None:
        self.paused = not self.paused
        self.stepper.forget()

    def _cmd_single_step(self) -> None:
        self.paused = True
        self._physics(self.stepper.step_once())

    def _cmd_reset(self) -> None:
        self.interaction.clear()
        self.pointer.mode = None
        self.sim.reset()
        self.renderer.invalidate_topology()
        self.stepper.forget()
        self.stepper.recovery.checkpoint = None
        self.stepper.recovery.after_steps()

    def _cmd_next_integrator(self) -> None:
        sim = self.sim
        current = sim.integrator
        k = INTEGRATORS.index(current) if current in INTEGRATORS else -1
        sim.integrator = INTEGRATORS[(k + 1) % len(INTEGRATORS)]
        self.stepper.recovery.chose_integrator(current)
        limit = sim.stable_dt()
        if limit is not None and limit < sim.dt:
            need = -(-sim.substeps * sim.dt // limit)
            self.notify(f"{sim.integrator}: estimated unstable at dt = {sim.dt:g} s with "
                        f"{sim.substeps} substeps (needs {need:.0f}); if it diverges the "
                        "viewer rolls back and steps in")

    def _cmd_more_substeps(self) -> None:
        self.stepper.recovery.chose_substeps(self.sim.substeps + 1)

    def _cmd_fewer_substeps(self) -> None:
        self.stepper.recovery.chose_substeps(max(1, self.sim.substeps - 1))

    def _cmd_toggle_self_collision(self) -> None:
        sim = self.sim
        if sim.self_collision is not None:
            sim.self_collision = None
            self.notify("self-collision off: layers pass through each other")
            return
        try:
            sim.self_collision = self.scene_self_collision or True
        except ParameterError as err:
            self.notify(f"self-collision stays off: {err}", warning=True)
            return
        self.notify("self-collision on")

    def _cmd_next_view(self) -> None:
        r = self.renderer
        r.view = VIEWS[(VIEWS.index(r.view) + 1) % len(VIEWS)]

    def _cmd_toggle_ssao(self) -> None:
        r = self.renderer
        r.ssao = not r.ssao
        if r.ssao and r.tier == "software":
            self.notify("SSAO is drawn in the full tier only: Q switches tiers")

    def _cmd_next_tier(self) -> None:
        r = self.renderer
        r.tier = TIERS[(TIERS.index(r.tier) + 1) % len(TIERS)]
        self.notify(f"{r.tier} tier: " + ("deferred, SSAO and FXAA" if r.tier == "full" else
                    "one forward pass lit per vertex, no SSAO or FXAA (for GL without a GPU)"))

    def _cmd_toggle_details(self) -> None:
        self.show_details = not self.show_details

    def _cmd_next_lights(self) -> None:
        self.renderer.cycle_lights()

    def _cmd_toggle_help(self) -> None:
        self.show_help = not self.show_help

    def _cmd_quit(self) -> None:
        self.quit = True

    def load_scene_number(self, k: int) -> None:
        """Key ``k`` (1-based): the ``k``-th built-in scene, if there is one."""
        names = scenes()
        if 1 <= k <= len(names):
            self.load(names[k - 1])
        else:
            self.notify(f"no scene {k}: {scene_key_help(names)}")

    def load(self, name: str) -> None:
        """Show the scene ``name`` (a built-in name or a TOML path) from its start."""
        self.interaction.clear()
        sim = self.make_sim(name)
        self.renderer.set_simulation(sim)
        self._bind(sim, name)


class ViewerInput:
    """Scripted input straight into the viewer's pointer and keys (headless runs)."""

    def __init__(self, viewer: Viewer) -> None:
        self.viewer = viewer

    @property
    def size(self) -> tuple[int, int]:
        return self.viewer.pointer.size

    @property
    def camera(self) -> Camera:
        return self.viewer.camera

    @property
    def pos(self) -> tuple[float, float]:
        return self.viewer.pointer.pos

    def press(self, mode: str, x: float, y: float) -> None:
        self.viewer.pointer.press(mode, x, y)

    def move(self, x: float, y: float) -> None:
        self.viewer.pointer.move(x, y)

    def release(self) -> None:
        self.viewer.pointer.release()

    def key(self, name: str) -> None:
        self.viewer.key(name)
