"""The desktop demo under Xvfb and the two command lines: scripted input through the window's
own handlers, surviving divergence, outputs, and bad input."""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rustcloth

pytestmark = pytest.mark.render

# Drives the real glfw demo (2 s at a fixed 1/60 s per frame) with scripted gestures that go
# through the window's mouse handlers, then reports what the cloth did. Runs in a subprocess:
# a glfw context made current here would displace the tests' EGL context.
DEMO_DRIVER = textwrap.dedent("""
    import json, sys
    import numpy as np
    import rustcloth
    from rustcloth.viewer.window import Demo
    scene = sys.argv[1]
    sim0 = rustcloth.Simulation(rustcloth.load_scene(scene))
    nx, ny = sim0.nx, sim0.ny
    size = 1.0
    grab = (ny // 2) * nx + nx // 2
    start = sim0.positions[grab]
    target = (start + np.array([0.5, 0.2, -0.3]) * size).tolist()
    row = (3 * ny) // 4
    script = [
        {"t": 0.1, "action": "grab", "particle": grab},
        {"t": 0.15, "action": "drag", "world": target, "duration": 0.5},
        {"t": 1.0, "action": "release"},
        {"t": 1.2, "action": "cut", "duration": 0.4,
         "path": [{"particle": row * nx + 1}, {"particle": row * nx + nx - 2}]},
    ]
    demo = Demo(scene, (320, 240), script=script, fixed_dt=1 / 60)
    v = demo.viewer
    demo.run(50)  # mid-drag (it ends at 0.65 s; the release comes at 1.0 s)
    # The pick takes the front-most particle under the cursor: usually `grab`, but the cloth
    # has been falling for 0.1 s, so judge by what was grabbed and where.
    grabbed = v.interaction.grabbed
    moved = v.sim.positions[grabbed] - v.interaction.drag_point
    # Where the cursor's ray meets the drag plane through the grabbed particle.
    aim = v.camera.drag_plane_point(v.pointer.ray(*v.pointer.pos), v.interaction.drag_point)
    miss = float(np.linalg.norm(v.sim.positions[grabbed] - aim))
    demo.run(120)
    report = {
        "frames": v.frames, "grabbed": grabbed, "moved": moved.tolist(),
        "wanted": (np.array(target) - start).tolist(), "miss": miss, "size": size,
        "alive": int(v.sim.alive.sum()), "n": v.sim.num_particles,
        "topology": v.sim.topology_version, "cut": v.interaction.cut_count,
        "released": v.sim.grabbed() is None, "error": demo.ctx.error,
        "title": v.status_lines()[0],
    }
    demo.close()
    print(json.dumps(report))
""")


def _run_python(code: str, *args: str, env: dict[str, str] | None = None,
                timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})


def test_demo_runs_with_scripted_grab_drag_and_cut(xdisplay: str) -> None:
    proc = _run_python(DEMO_DRIVER, "hanging", env={"DISPLAY": xdisplay})
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["frames"] == 120 and report["error"] == "GL_NO_ERROR"
    # The drag: mid-drag the grabbed particle sits under the cursor (on the camera-facing
    # plane through where it was grabbed), well away from where it was grabbed.
    assert report["grabbed"] is not None
    assert report["miss"] < 0.05 * report["size"]
    assert np.linalg.norm(report["moved"]) > 0.2 * report["size"]
    # The cut: springs severed along the stroke, no particle removed (a cut keeps the mass),
    # new topology; the grab was let go.
    assert 0 < report["cut"] and report["alive"] == report["n"]
    assert report["topology"] > 0 and report["released"]
    assert "fps" in report["title"]


def test_demo_survives_every_integrator_a_drag_and_a_cut(xdisplay: str, tmp_path: Path) -> None:
    """The demo as a person runs it (real time, `python -m rustcloth demo`), driven by
    synthetic key presses and mouse gestures through the window's handlers: I through every
    integrator (explicit_euler diverges), then a drag and a cut, then Esc."""
    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    nx, ny = sim.nx, sim.ny
    middle = (ny // 2) * nx + nx // 2
    row = (2 * ny) // 3
    presses = len(rustcloth.INTEGRATORS)  # round to the start again
    events: list[dict[str, Any]] = [
        {"t": 0.4 + 0.4 * k, "action": "key", "key": "I"} for k in range(presses - 1)]
    t = 0.4 * presses + 5.0  # explicit_euler, last in the cycle, gets 5 s to diverge
    events += [
        {"t": t, "action": "key", "key": "I"},
        {"t": t + 0.5, "action": "grab", "particle": middle},
        {"t": t + 0.6, "action": "drag", "x": 0.7, "y": 0.3, "duration": 0.8},
        {"t": t + 1.6, "action": "release"},
        {"t": t + 2.0, "action": "cut", "duration": 0.6,
         "path": [{"particle": row * nx + 1}, {"particle": row * nx + nx - 2}]},
        {"t": t + 3.5, "action": "key", "key": "ESCAPE"},
    ]
    script = tmp_path / "events.json"
    script.write_text(json.dumps(events))
    proc = subprocess.Popen(
        [sys.executable, "-m", "rustcloth", "demo", "hanging", "--size", "320x240",
         "--script", str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "DISPLAY": xdisplay, "PYTHONUNBUFFERED": "1"})
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(s) for s in proc.stdout or []],
                     daemon=True).start()
    seen: list[str] = []
    alive_after_divergence = False
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                line = lines.get(timeout=0.5)
            except queue.Empty:
                continue
            seen.append(line.rstrip())
            if "diverged" in line:
                time.sleep(1.0)
                alive_after_divergence = proc.poll() is None
        rc = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    while not lines.empty():
        seen.append(lines.get().rstrip())
    err = proc.stderr.read() if proc.stderr else ""
    assert rc == 0, err[-3000:]
    assert "Traceback" not in err
    # The overlay's notice (printed as it is shown): what happened and what was done.
    diverged = [s for s in seen if s.startswith("notice: explicit_euler diverged")]
    assert diverged, seen
    assert "rolled back" in diverged[0] or "put back the cloth" in diverged[0]
    assert "raised substeps" in diverged[0] or "switched to" in diverged[0]
    assert alive_after_divergence
    summary = next(s for s in seen if s.startswith("demo: "))
    cut = int(summary.split(" springs cut")[0].rsplit(" ", 1)[1])
    assert cut > 0 and "symplectic_euler" in summary, summary


def test_keys_and_closing_the_window_mid_run(xdisplay: str) -> None:
    code = textwrap.dedent("""
        import glfw
        from rustcloth import scenes
        from rustcloth.viewer.window import Demo
        demo = Demo("hanging", (160, 120))
        v = demo.viewer
        demo.run(2)
        def key(k):
            demo.on_key(demo.window, k, 0, glfw.PRESS, 0)
        key(glfw.KEY_V); assert v.renderer.view == "position"
        integrator = v.sim.integrator
        key(glfw.KEY_I); assert v.sim.integrator != integrator
        substeps = v.sim.substeps
        key(glfw.KEY_EQUAL); assert v.sim.substeps == substeps + 1
        key(glfw.KEY_KP_SUBTRACT); assert v.sim.substeps == substeps
        key(glfw.KEY_SPACE); assert v.paused
        steps = v.sim.steps
        key(glfw.KEY_N); assert v.sim.steps == steps + 1
        key(glfw.KEY_R); assert v.sim.steps == 0
        key(glfw.KEY_2); assert v.name == scenes()[1]
        key(glfw.KEY_H); assert v.show_help
        key(glfw.KEY_L); assert v.renderer.lights.name == "neon"
        demo.on_scroll(demo.window, 0.0, 1.0)
        demo.run(5)
        glfw.set_window_should_close(demo.window, True)
        rc = demo.run(1000)
        demo.close()
        print("rc", rc, v.frames)
    """)
    proc = _run_python(code, env={"DISPLAY": xdisplay})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split()[-3:] == ["rc", "0", "5"]  # stopped at once, no more frames
    assert "Traceback" not in proc.stderr


def test_render_cli_writes_pngs_and_gif(tmp_path: Path, capsys: Any) -> None:
    from rustcloth.viewer.cli import main_render

    rc = main_render(["freefall", "--frames", "4", "--out", str(tmp_path), "--gif",
                      "--size", "64x48", "--overlay"])
    out = capsys.readouterr().out
    assert rc == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        f"frame_{k:04d}.png" for k in range(4)]
    assert (tmp_path / "animation.gif").stat().st_size > 0
    assert "4 frames: physics" in out and str(tmp_path) in out


def test_render_cli_takes_a_scene_toml_and_warns_about_a_script_past_the_end(
        tmp_path: Path, capsys: Any) -> None:
    from rustcloth.viewer.cli import main_render

    toml = tmp_path / "mine.toml"
    toml.write_text(rustcloth.load_scene("hanging").replace(cloth={"nx": 12, "ny": 12}).to_toml())
    script = tmp_path / "late.json"
    script.write_text(json.dumps([{"t": 5.0, "action": "release"}]))
    rc = main_render([str(toml), "--frames", "3", "--size", "32x24", "--script", str(script),
                      "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert rc == 0 and len(list((tmp_path / "out").glob("frame_*.png"))) == 3
    assert "the script runs to t = 5 s" in captured.err and "never happens" in captured.err


@pytest.mark.parametrize("argv, words", [
    (["nope"], ["nope", *rustcloth.scenes()]),
    (["drape", "--size", "big"], ["--size", "640x480"]),
    (["drape", "--frames", "0"], ["--frames", "at least 1"]),
    (["drape", "--view", "x-ray"], ["--view", "shadow map"]),
    (["drape", "--script", "a.json", "--demo-script"], ["choose one"]),
])
def test_bad_render_arguments_exit_2_with_one_line(argv: list[str], words: list[str],
                                                   capsys: Any) -> None:
    from rustcloth.viewer.cli import main_render

    assert main_render(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("rustcloth render: error: ")
    assert all(w in err[-1] for w in words), err[-1]


def test_no_gl_context_gives_one_clear_message(monkeypatch: Any, capsys: Any,
                                               tmp_path: Path) -> None:
    import moderngl
    from rustcloth.viewer.cli import main_render

    def fail(*args: Any, **kwargs: Any) -> None:
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_context", fail)
    assert main_render(["freefall", "--frames", "1", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "OpenGL 3.3" in err and "libegl-mesa0" in err and "Traceback" not in err


def test_demo_without_display_falls_back_to_headless(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from rustcloth import app; "
         "sys.exit(app.main_demo(sys.argv[1:]))", "hanging", "--frames", "6",
         "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    first = proc.stdout.splitlines()[0]
    assert first.startswith("no display") and str(tmp_path) in first
    assert (tmp_path / "animation.gif").exists() and (tmp_path / "frame_0005.png").exists()


def test_the_gif_keeps_smooth_gradients_smooth(tmp_path: Path) -> None:
    # The GIF's first frame showed bands of flat colour across the sky: each frame went
    # through a 256-colour palette without dithering. A sky-like gradient of far more than
    # 256 colours, written and read back, must match the source over small areas (the
    # dither's noise averages out) much better than plain quantisation does.
    from PIL import Image
    from rustcloth.viewer.headless import write_gif

    h, w = 120, 320
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    frame = np.stack([40 + 120 * x / w, 60 + 100 * y / h, 200 - 60 * (x + y) / (w + h)],
                     axis=-1).round().astype(np.uint8)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 1000
    path = tmp_path / "gradient.gif"
    write_gif(path, [frame, frame[::-1].copy()], 30.0)
    with Image.open(path) as gif:
        assert gif.n_frames == 2
        back = np.asarray(gif.convert("RGB"), dtype=np.float64)
    plain = np.asarray(Image.fromarray(frame).quantize(colors=256, dither=Image.Dither.NONE)
                       .convert("RGB"), dtype=np.float64)

    def area_error(img: np.ndarray) -> float:
        # Mean error of 8x8 block means: what banding is, and what dithering fixes.
        d = (img - frame).reshape(h // 8, 8, w // 8, 8, 3).mean(axis=(1, 3))
        return float(np.abs(d).mean())

    assert np.abs(back - frame).max() < 40  # every pixel near its colour
    assert area_error(back) < 0.6 * area_error(plain), (area_error(back), area_error(plain))
