"""The viewer loop without a window: divergence recovery, physics pacing, the overlay's text,
keys, gestures and scripts, on the real simulation and an offscreen EGL context."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import rustcloth
from rustcloth.viewer.headless import render_frames
from rustcloth.viewer.loop import Viewer
from rustcloth.viewer.physics import Stepper
from rustcloth.viewer.script import ScriptPlayer, default_script

pytestmark = pytest.mark.render
SIZE = (96, 72)


def _viewer(ctx: Any, scene: str = "hanging", **kw: Any) -> tuple[Viewer, Any]:
    sim = rustcloth.Simulation(rustcloth.load_scene(scene))
    fbo = ctx.simple_framebuffer(SIZE)
    return Viewer(ctx, sim, SIZE, name=scene, realtime=False, **kw), fbo


def _text(viewer: Viewer) -> str:
    return "\n".join(s if isinstance(s, str) else s[0] for s in viewer.status_lines())


def _to_integrator(viewer: Viewer, name: str) -> None:
    for _ in rustcloth.INTEGRATORS:
        if viewer.sim.integrator == name:
            return
        viewer.key("I")
    raise AssertionError(f"I never reached {name}")


def test_explicit_euler_diverges_rolls_back_and_keeps_running(ctx: Any) -> None:
    """Cycling integrators with I reaches explicit_euler, which diverges within a second on
    the demo's cloth: the viewer rolls back and keeps running rather than closing the demo."""
    viewer, fbo = _viewer(ctx)
    for _ in range(5):
        viewer.frame(fbo, 1 / 30)
    _to_integrator(viewer, "explicit_euler")
    for _ in range(60):  # two seconds: explicit Euler at 2 substeps gives out in one
        viewer.frame(fbo, 1 / 30)
        if any("diverged" in n for n, _, _ in viewer.notices):
            break
    notice = next(n for n, _, _ in viewer.notices if "diverged" in n)
    assert notice.startswith("explicit_euler diverged at t = ")
    assert "put back the cloth of t = " in notice or "rolled back" in notice
    assert "raised substeps 2 -> 68" in notice  # the stability estimate for hanging
    assert notice in _text(viewer)  # on the overlay
    # It keeps running, and the cloth stays sane.
    for _ in range(20):
        viewer.frame(fbo, 1 / 30)
    assert viewer.sim.integrator == "explicit_euler" and viewer.sim.substeps == 68
    assert "raised from 2" in _text(viewer)
    p = viewer.sim.positions
    assert np.isfinite(p).all() and (np.abs(p) < 10.0).all()
    assert viewer.sim.max_stretch() < 2.0
    # The person's next integrator gets the person's substeps back.
    viewer.key("I")
    assert viewer.sim.substeps == 2


def test_explicit_euler_is_caught_and_recovered_with_self_collision_on(ctx: Any) -> None:
    """With self-collision the pass held explicit Euler's runaway cloth apart instead of
    letting it reach infinity: the cloth boiled on and the viewer never said a word. The core
    now fails such a step as "unresolved"; the viewer goes back to a checkpoint from before the
    runaway (its velocities, not its springs, were wild) and switches integrator."""
    viewer, fbo = _viewer(ctx, "fold")
    for _ in range(5):
        viewer.frame(fbo, 1 / 30)
    _to_integrator(viewer, "explicit_euler")
    for _ in range(30):
        viewer.frame(fbo, 1 / 30)
        if any("diverged" in n for n, _, _ in viewer.notices):
            break
    notice = next(n for n, _, _ in viewer.notices if "diverged" in n)
    assert notice.startswith("explicit_euler diverged at t = ")
    assert "moved faster than the step resolves" in notice
    assert "put back the cloth of t = " in notice
    for _ in range(20):
        viewer.frame(fbo, 1 / 30)
    assert sum("diverged" in n for n, _, _ in viewer.notices) == 1  # the checkpoint held
    assert viewer.sim.integrator != "explicit_euler"
    v = viewer.sim.velocities
    assert np.isfinite(v).all() and (np.abs(v) < 10.0).all()


def test_a_violent_drag_that_diverges_is_recovered(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx, "freefall")
    sim = viewer.sim
    # The recovery is what is tested; self-collision through a diverging drag would cost most
    # of the suite's time for this one test, and its retries are tested in the Rust suite
    # (self_collision_holds_through_the_watchdogs_substep_retries).
    sim.self_collision = None
    _to_integrator(viewer, "explicit_euler")
    sim.substeps = 18  # what the estimate says it needs here: stable until the drag
    viewer.notices.clear()
    viewer.frame(fbo, 1 / 30)
    sim.grab(sim.num_particles // 2)
    for k in range(30):
        sim.drag_to([0.0, 1.2, 2.0 * (-1) ** k])  # 2 m back and forth every frame
        viewer.frame(fbo, 1 / 30)
        if viewer.notices:
            break
    notices = [n for n, _, _ in viewer.notices]
    assert any("while dragging" in n for n in notices), notices
    for _ in range(10):
        viewer.frame(fbo, 1 / 30)
    assert np.isfinite(sim.positions).all() and sim.max_stretch() < 1000.0


def test_recovery_ladder_ends_in_a_stable_integrator(ctx: Any) -> None:
    viewer, _ = _viewer(ctx)
    rec = viewer.stepper.recovery
    err = rustcloth.SimulationDiverged("test", step=1, particle=3, reason="non_finite",
                                       substeps=2)
    viewer.sim.integrator = "rk4"
    rec.chose_integrator("symplectic_euler")
    said = [rec.handle(err) for _ in range(5)]
    assert "raised substeps 2 -> 4" in said[0]
    assert any("switched to symplectic_euler" in s for s in said)
    assert viewer.sim.integrator in ("symplectic_euler", "implicit_euler")


def test_budgeted_stepping_falls_behind_rather_than_spiralling(ctx: Any) -> None:
    sim = rustcloth.Simulation(rustcloth.load_scene("freefall"))
    stepper = Stepper(sim)
    exact = stepper.run(0.1, None)
    assert exact.steps == 100 and stepper.owed < sim.dt
    starved = stepper.run(0.5, 0.0)  # no time at all: nothing runs, the debt is dropped
    assert starved.steps == 0 and stepper.owed <= sim.dt
    assert stepper.real_time_ratio() < 0.5


def test_overlay_is_one_line_until_asked_and_says_paused_alone_ssao_state_and_scene_keys(
        ctx: Any) -> None:
    viewer, fbo = _viewer(ctx)
    viewer.frame(fbo, 1 / 30)
    assert len(viewer.status_lines()) == 1  # the details wait for D
    assert "SSAO" not in _text(viewer) and "D details" in _text(viewer)
    viewer.key("D")
    assert len(viewer.status_lines()) > 1
    assert "SSAO off" in _text(viewer)
    viewer.key("O")
    assert "SSAO on" in _text(viewer)
    viewer.key("SPACE")
    first = _text(viewer).splitlines()[0]
    assert first.endswith("PAUSED") and "SLOW" not in first and "CAPPED" not in first
    steps = viewer.sim.steps
    viewer.frame(fbo, 1 / 30)
    assert viewer.sim.steps == steps  # paused
    viewer.key("N")
    assert viewer.sim.steps == steps + 1
    viewer.key("H")
    names = rustcloth.scenes()
    # Keys 1..9 name the first nine scenes; the rest are named as loading by name.
    assert "1..9: " + ", ".join(names[:9]) in _text(viewer)
    assert all(name in _text(viewer) for name in names[9:])
    viewer.key("2")
    assert viewer.name == rustcloth.scenes()[1]
    # Keys 1..9 load the first nine built-in scenes; a number past the last says so.
    viewer.key("9")
    assert viewer.name == names[8]
    viewer.load_scene_number(len(names) + 1)
    assert f"no scene {len(names) + 1}" in viewer.notices[-1][0]
    viewer.key("L")
    assert viewer.renderer.lights.name == "neon"


def test_the_opening_frame_shows_no_frame_rate_until_one_is_measured(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx)
    viewer.frame(fbo, 0.0)
    first = _text(viewer).splitlines()[0]
    assert "-- fps" in first and "0.0 fps" not in first
    viewer.fps = 12.34  # what the half-second count sets once it has frames to count
    assert "12.3 fps" in _text(viewer).splitlines()[0]


def test_cut_line_goes_away_on_release(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx, "curtain")
    viewer.frame(fbo, 1 / 30)
    w, h = SIZE
    viewer.pointer.press("cut", 0.2 * w, 0.35 * h)
    viewer.pointer.move(0.8 * w, 0.35 * h)
    viewer.frame(fbo, 1 / 30)
    assert viewer.interaction.cut_count > 0 and len(viewer.interaction.stroke()) > 0
    assert viewer.renderer.stroke_count > 0
    viewer.pointer.release()
    viewer.frame(fbo, 1 / 30)
    assert len(viewer.interaction.stroke()) == 0 and viewer.renderer.stroke_count == 0


def test_grab_uses_the_core_and_release_restores_pins(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx)
    viewer.frame(fbo, 1 / 30)
    sim = viewer.sim
    corner = int(np.flatnonzero(sim.pinned)[0])
    x, y, _ = viewer.camera.project(sim.positions[corner], *SIZE)
    viewer.pointer.press("grab", x, y)
    assert sim.grabbed() == viewer.interaction.grabbed is not None
    viewer.pointer.move(x + 10, y - 10)
    viewer.frame(fbo, 1 / 30)
    viewer.pointer.release()
    assert sim.grabbed() is None
    assert sim.pinned[corner]  # a particle the scene pinned stays pinned


def test_default_script_fits_the_run() -> None:
    """The built-in script ends within the run it is made for, so that a short render
    (`render --frames 60`: 1.97 s at 30 fps) shows its drag."""
    sim = rustcloth.Simulation(rustcloth.load_scene("drape"))
    for duration in (59 / 30, 4.0, 10.0):
        script = default_script(sim.nx, sim.ny, sim.positions, 1.6, duration)
        assert ScriptPlayer(script).end <= duration
        actions = [e["action"] for e in script]
        assert actions == ["cut", "grab", "drag", "release"]


def test_scripted_headless_render_is_replayable_and_moves(ctx: Any) -> None:
    frames = []
    for _ in range(2):
        sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
        script = default_script(sim.nx, sim.ny, sim.positions, 1.0, 39 / 15)
        images, stats = render_frames(sim, SIZE, 40, 15.0, script, progress=False, ctx=ctx)
        frames.append(np.stack(images))
    assert stats.frames == 40 and stats.steps == math.floor(39 / 15 / 0.001 + 1e-6)
    assert np.array_equal(frames[0], frames[1])
    assert not np.array_equal(frames[0][0], frames[0][-1])  # the cloth did move


def _leg_under_the_cursor(viewer: Viewer) -> tuple[int, float, float]:
    """A tablecloth front leg (collider 1, at +x +z, the camera's side) and its pixel."""
    centre = viewer.sim.collider_poses()[0][1]
    x, y, _ = viewer.camera.project(centre, *SIZE)
    return 1, x, y


def test_ctrl_drag_moves_the_collider_under_the_cursor_in_the_camera_plane(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx, "tablecloth")
    viewer.key("H")
    assert "ctrl + left drag: move a collider" in _text(viewer)  # the help says so
    viewer.frame(fbo, 1 / 30)
    sim = viewer.sim
    k, x, y = _leg_under_the_cursor(viewer)
    start, rotations = (a.copy() for a in sim.collider_poses())
    viewer.pointer.press("collider", x, y)
    assert viewer.interaction.collider == k and sim.grabbed() is None  # not the cloth
    grabbed_at = viewer.interaction.collider_point
    viewer.pointer.move(x + 12, y - 6)
    viewer.frame(fbo, 1 / 30)
    moved = sim.collider_poses()[0][k] - start[k]
    # The grabbed point follows the cursor's ray on the plane facing the camera through it.
    aim = viewer.camera.drag_plane_point(viewer.pointer.ray(x + 12, y - 6), grabbed_at)
    np.testing.assert_allclose(moved, aim - grabbed_at, atol=1e-5)
    assert np.linalg.norm(moved) > 0.05
    assert abs(float(moved @ viewer.camera.forward)) < 1e-5
    np.testing.assert_array_equal(sim.collider_poses()[1][k], rotations[k])
    others = [j for j in range(len(start)) if j != k]
    np.testing.assert_array_equal(sim.collider_poses()[0][others], start[others])
    # Let go: it stays where it was put.
    viewer.pointer.release()
    assert viewer.interaction.collider is None
    held = sim.collider_poses()[0][k].copy()
    viewer.frame(fbo, 1 / 30)
    np.testing.assert_array_equal(sim.collider_poses()[0][k], held)


def test_ctrl_drag_off_every_collider_moves_nothing(ctx: Any) -> None:
    viewer, fbo = _viewer(ctx, "tablecloth")
    viewer.frame(fbo, 1 / 30)
    start = viewer.sim.collider_poses()[0].copy()
    viewer.pointer.press("collider", 2.0, 2.0)  # the sky, top left
    assert viewer.interaction.collider is None
    viewer.pointer.move(40.0, 30.0)
    viewer.frame(fbo, 1 / 30)
    np.testing.assert_array_equal(viewer.sim.collider_poses()[0], start)


def test_ctrl_left_button_is_the_collider_gesture(ctx: Any) -> None:
    glfw = pytest.importorskip("glfw")
    from rustcloth.viewer.window import Demo

    viewer, _ = _viewer(ctx, "tablecloth")
    demo = Demo.__new__(Demo)  # the button handler alone: no window
    demo.viewer = viewer
    k, x, y = _leg_under_the_cursor(viewer)
    demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, glfw.MOD_CONTROL, x, y)
    assert viewer.pointer.mode == "collider" and viewer.interaction.collider == k
    demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, glfw.MOD_CONTROL, x, y)
    assert viewer.interaction.collider is None
    demo.mouse_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0, x, y)
    assert viewer.pointer.mode == "grab" and viewer.interaction.collider is None


def test_a_long_notice_wraps_into_a_block_instead_of_spanning_the_window(ctx: Any) -> None:
    # The orange divergence notice used to wrap only at the window's width: on a 1280-pixel
    # window it was a band across the whole picture.
    from rustcloth.viewer.loop import OVERLAY_MAX_WIDTH

    size = (1280, 720)
    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    viewer = Viewer(ctx, sim, size, name="hanging", realtime=False)
    fbo = ctx.simple_framebuffer(size)
    viewer.notify("explicit_euler diverged at t = 0.900 s (springs at 1.9e+05 times their rest "
                  "length at 2 substeps): the steps before it were already unstable, so put "
                  "back the cloth of t = 0.833 s, and raised substeps 2 -> 68", warning=True)
    viewer.frame(fbo, 1 / 30)
    width, height = viewer.renderer.panels["status"].texture.size
    assert width <= OVERLAY_MAX_WIDTH and width < 0.6 * size[0]
    assert height > 3 * 13  # wrapped onto several lines, all of it kept


def test_c_turns_self_collision_off_and_on_and_the_step_follows(ctx: Any) -> None:
    """C toggles the pile's self-collision live. Off, the viewer's cloth steps exactly as a
    simulation of the scene without ``[self_collision]`` from the same state; on again, with
    the scene's own settings, exactly as the scene does; the details and the help say so."""
    viewer, fbo = _viewer(ctx, "pile")
    sim = viewer.sim
    # Into its folds, where the pass has pairs to act on (at its display-frame steps the cloth
    # first meets itself after about half a second).
    viewer.frame(fbo, 1.0)
    own = sim.self_collision
    assert own is not None and "self_collision" in sim.effects

    def reference(settings: Any) -> rustcloth.Simulation:
        state = sim.get_state()
        return rustcloth.Simulation.from_state(
            {**state, "scene": {**state["scene"], "self_collision": settings}})

    def follows(ref: rustcloth.Simulation) -> None:
        start = sim.steps
        viewer.frame(fbo, 0.3)
        ref.step(sim.steps - start)
        assert sim.steps > start and np.array_equal(sim.positions, ref.positions)

    with_pass, without = reference(own), reference(None)
    viewer.key("C")
    assert sim.self_collision is None and "self_collision" not in sim.effects
    assert "self-collision off" in viewer.notices[-1][0]
    viewer.key("D")
    assert "self-collision off (C)" in _text(viewer)
    follows(without)
    with_pass.step(without.steps - with_pass.steps)
    assert not np.array_equal(with_pass.positions, without.positions), "the pass did nothing"
    back_on = reference(own)
    viewer.key("C")
    assert sim.self_collision == own and "self-collision on (C)" in _text(viewer)
    follows(back_on)
    viewer.key("H")
    assert "C: self-collision on / off" in _text(viewer)


def test_c_says_why_when_the_cloth_cannot_take_self_collision(ctx: Any) -> None:
    # A cloth 1 mm between particles: the default gap (2 mm) would start it in contact.
    sim = rustcloth.Simulation(rustcloth.Scene(cloth={"nx": 4, "ny": 4, "size": [0.003, 0.003]}))
    viewer = Viewer(ctx, sim, SIZE, name="tiny", realtime=False)
    before = sim.get_state()
    viewer.key("C")
    assert sim.self_collision is None and "self_collision" not in sim.effects
    text, _, warning = viewer.notices[-1]
    assert warning and "self-collision stays off" in text and "self_collision.thickness" in text
    assert np.array_equal(sim.positions, before["positions"])
