"""The demo and headless entry points: scripted interaction, outputs, and bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.render

# Drives the real glfw demo for 120 frames (2 s at a fixed 1/60 s) with scripted gestures that
# go through the demo's mouse handlers, then reports what the cloth did. Runs in a subprocess:
# a glfw context made current here would displace the tests' EGL context.
DEMO_DRIVER = textwrap.dedent("""
    import json, sys
    import numpy as np
    from rustcloth import app
    scene, out = sys.argv[1], sys.argv[2]
    sim0 = app.Simulation(app.load_scene(scene))
    nx, ny = sim0.nx, sim0.ny
    size = max(sim0.scene.to_dict()["cloth"]["size"])
    grab = (ny // 2) * nx + nx // 2
    start = sim0.positions[grab]
    target = (start + np.array([0.5, 0.2, 0.3]) * size).tolist()
    row = (3 * ny) // 4
    script = [
        {"t": 0.1, "action": "grab", "particle": grab},
        {"t": 0.15, "action": "drag", "world": target, "duration": 0.5},
        {"t": 1.0, "action": "release"},
        {"t": 1.2, "action": "cut", "duration": 0.4,
         "path": [{"particle": row * nx + 1}, {"particle": row * nx + nx - 2}]},
    ]
    demo = app.Demo(scene, (320, 240), script=script, fixed_dt=1 / 60)
    demo.run(60)
    # The pick takes the front-most particle under the cursor: usually `grab`, but the cloth
    # has been falling for 0.1 s, so judge by what was grabbed and where.
    grabbed = demo.interaction.grabbed
    moved = demo.sim.positions[grabbed] - demo.interaction.grab_point
    # Where the cursor's ray meets the drag plane through the grabbed particle.
    aim = demo.camera.drag_plane_point(demo.pointer.ray(*demo.pointer.pos),
                                       demo.interaction.grab_point)
    miss = float(np.linalg.norm(demo.sim.positions[grabbed] - aim))
    demo.run(120)
    report = {
        "frames": demo.frames, "grabbed": grabbed, "moved": moved.tolist(),
        "wanted": (np.array(target) - start).tolist(), "miss": miss, "size": size,
        "alive": int(demo.sim.alive.sum()), "n": demo.sim.num_particles,
        "topology": demo.sim.topology_version, "cut": demo.interaction.cut_count,
        "stroke": int(len(demo.interaction.stroke())), "error": demo.ctx.error,
        "title": demo.status_lines()[0],
    }
    demo.close()
    print(json.dumps(report))
""")


def _run_python(code: str, *args: str, env: dict[str, str] | None = None,
                timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})


def test_demo_runs_120_frames_with_scripted_grab_drag_and_cut(make_real: Any, xdisplay: str,
                                                               tmp_path: Path) -> None:
    if make_real("hanging") is None:
        pytest.skip("the compiled core is not built into the venv")
    proc = _run_python(DEMO_DRIVER, "hanging", str(tmp_path), env={"DISPLAY": xdisplay})
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["frames"] == 120 and report["error"] == "GL_NO_ERROR"
    # The drag: mid-drag the grabbed particle sits under the cursor (on the camera-facing
    # plane through where it was grabbed), well away from where it was grabbed.
    assert report["grabbed"] is not None
    assert report["miss"] < 0.05 * report["size"]
    assert np.linalg.norm(report["moved"]) > 0.2 * report["size"]
    # The cut: particles removed along the stroke, new topology, stroke kept for highlighting.
    assert 0 < report["cut"] and report["alive"] < report["n"]
    assert report["topology"] > 0 and report["stroke"] > 0
    assert "fps" in report["title"]


def test_keys_and_closing_the_window_mid_run(make_real: Any, xdisplay: str) -> None:
    if make_real("hanging") is None:
        pytest.skip("the compiled core is not built into the venv")
    code = textwrap.dedent("""
        import glfw
        from rustcloth import app, scenes
        demo = app.Demo("hanging", (160, 120))
        demo.run(2)
        def key(k):
            demo.on_key(demo.window, k, 0, glfw.PRESS, 0)
        key(glfw.KEY_V); assert demo.renderer.view == "position"
        integrator = demo.sim.integrator
        key(glfw.KEY_I); assert demo.sim.integrator != integrator
        substeps = demo.sim.substeps
        key(glfw.KEY_EQUAL); assert demo.sim.substeps == substeps + 1
        key(glfw.KEY_MINUS); assert demo.sim.substeps == substeps
        key(glfw.KEY_SPACE); assert demo.paused
        steps = demo.sim.steps
        key(glfw.KEY_N); assert demo.sim.steps == steps + 1
        key(glfw.KEY_R); assert demo.sim.steps == 0
        key(glfw.KEY_2); assert demo.scene_name == scenes()[1]
        key(glfw.KEY_H); assert demo.show_help
        demo.on_scroll(demo.window, 0.0, 1.0)
        demo.run(5)
        demo.glfw.set_window_should_close(demo.window, True)
        rc = demo.run(1000)
        demo.close()
        print("rc", rc, demo.frames)
    """)
    proc = _run_python(code, env={"DISPLAY": xdisplay})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split()[-3:] == ["rc", "0", "5"]  # stopped at once, no more frames
    assert "Traceback" not in proc.stderr


def test_scripted_headless_render_is_replayable(make_real: Any, ctx: Any, standin_cls: Any) -> None:
    from rustcloth.render.headless import render_frames
    from rustcloth.render.interaction import default_script

    frames = []
    for _ in range(2):
        sim = make_real("hanging") or standin_cls(amp=0.05)
        script = default_script(sim)
        images, stats = render_frames(sim, (96, 72), 40, 15.0, script, progress=False, ctx=ctx)
        frames.append(np.stack(images))
    assert stats.frames == 40
    assert np.array_equal(frames[0], frames[1])
    assert not np.array_equal(frames[0][0], frames[0][-1])  # the cloth did move


def test_render_cli_writes_pngs_and_gif(make_real: Any, tmp_path: Path, capsys: Any) -> None:
    if make_real("freefall") is None:
        pytest.skip("the compiled core is not built into the venv")
    from rustcloth import app

    rc = app.main_render(["freefall", "--frames", "4", "--out", str(tmp_path), "--gif",
                          "--size", "64x48"])
    out = capsys.readouterr().out
    assert rc == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        f"frame_{k:04d}.png" for k in range(4)]
    assert (tmp_path / "animation.gif").stat().st_size > 0
    assert "4/4 frames" in out and "physics" in out and str(tmp_path) in out


def test_unknown_scene_lists_the_available_ones(capsys: Any) -> None:
    from rustcloth import app, scenes

    assert app.main_render(["nope"]) == 2
    err = capsys.readouterr().err
    assert "nope" in err and all(name in err for name in scenes())


def test_no_gl_context_gives_one_clear_message(make_real: Any, monkeypatch: Any, capsys: Any,
                                               tmp_path: Path) -> None:
    if make_real("freefall") is None:
        pytest.skip("the compiled core is not built into the venv")
    import moderngl
    from rustcloth import app

    def fail(*args: Any, **kwargs: Any) -> None:
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_context", fail)
    assert app.main_render(["freefall", "--frames", "1", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "OpenGL 3.3" in err and "libegl-mesa0" in err and "Traceback" not in err


def test_demo_without_display_falls_back_to_headless(make_real: Any, tmp_path: Path) -> None:
    if make_real("hanging") is None:
        pytest.skip("the compiled core is not built into the venv")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from rustcloth import app; "
         "sys.exit(app.main_demo(sys.argv[1:]))", "hanging", "--frames", "6",
         "--size", "64x48", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    first = proc.stdout.splitlines()[0]
    assert first.startswith("no display") and str(tmp_path) in first
    assert (tmp_path / "animation.gif").exists() and (tmp_path / "frame_0005.png").exists()
