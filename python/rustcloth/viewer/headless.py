"""Offscreen rendering through EGL: the viewer's frames as numbered PNGs, optionally a GIF or
an MP4, with scripted interaction; every frame advances exactly 1 / fps of simulated time, so
the same script gives the same frames."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import moderngl
import numpy as np
import numpy.typing as npt
from PIL import Image

from .._cli import progress as progress_bar
from ..render.context import create_standalone_context
from .loop import Viewer

Frame = npt.NDArray[np.uint8]


@dataclass
class RenderStats:
    frames: int
    physics_s: float
    render_s: float
    steps: int

    def summary(self) -> str:
        n = max(self.frames, 1)
        return (f"{self.frames} frames: physics {1e3 * self.physics_s / n:.2f} ms/frame "
                f"({self.steps} steps), rendering {1e3 * self.render_s / n:.2f} ms/frame "
                "(incl. read-back)")


def render_frames(
    sim: Any, size: tuple[int, int], frames: int, fps: float,
    script: list[dict[str, Any]] | None, *, name: str = "scene", view: str = "lit",
    ssao: bool = False, lights: str = "studio", overlay: bool = False, progress: bool = True,
    sink: Callable[[int, Frame], None] | None = None, ctx: moderngl.Context | None = None,
    on_notice: Callable[[str], None] | None = None, tier: str | None = "full",
) -> tuple[list[Frame], RenderStats]:
    """Simulate and render ``frames`` frames at ``fps`` offscreen; returns RGB frames (rows top
    to bottom) unless ``sink`` (called with each frame index and image) takes them. Uses
    ``ctx`` if given, else a standalone EGL context of its own. ``tier``: the renderer's
    quality tier (None: the one the context calls for)."""
    own = ctx is None
    if ctx is None:
        ctx = create_standalone_context()
    try:
        viewer = Viewer(ctx, sim, size, name=name, realtime=False, script=script, view=view,
                        ssao=ssao, lights=lights, overlay=overlay, on_notice=on_notice,
                        tier=tier)
        w, h = size
        color = ctx.renderbuffer(size, 4)
        fbo = ctx.framebuffer(color_attachments=[color])
        out: list[Frame] = []
        physics = render = 0.0
        steps = 0
        image = np.empty((h, w, 3), dtype=np.uint8)
        bar = progress_bar(frames, "frame") if progress else None
        for k in range(frames):
            t0 = time.perf_counter()
            viewer.frame(fbo, 0.0 if k == 0 else 1.0 / fps)
            fbo.read_into(image, components=3)
            elapsed = time.perf_counter() - t0
            physics += viewer.last_physics.seconds
            render += elapsed - viewer.last_physics.seconds
            steps += viewer.last_physics.steps if k else 0
            frame = image[::-1].copy()
            if sink is not None:
                sink(k, frame)
            else:
                out.append(frame)
            if bar is not None:
                bar.update()
        if bar is not None:
            bar.close()
        err = ctx.error
        if err != "GL_NO_ERROR":
            raise RuntimeError(f"OpenGL error while rendering: {err}")
        return out, RenderStats(frames, physics, render, steps)
    finally:
        if own:
            ctx.release()


def gif_frame(frame: Frame) -> Image.Image:
    """One RGB frame as a GIF frame: a palette of its own 256 colours (median cut) and
    Floyd-Steinberg dithering into it, so a smooth gradient (the sky, the floor's fog) shows
    as fine noise, not as bands of flat colour."""
    image = Image.fromarray(frame)
    palette = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                             dither=Image.Dither.NONE)
    return image.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG)


def write_gif(path: Path, frames: list[Frame], fps: float) -> None:
    """An animated GIF, looping, each frame with its own palette (:func:`gif_frame`)."""
    images = [gif_frame(f) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:],
                   duration=round(1000.0 / fps), loop=0, optimize=False)


def write_outputs(
    sim: Any, out_dir: Path, size: tuple[int, int], frames: int, fps: float,
    script: list[dict[str, Any]] | None, *, gif: bool, mp4: bool, **options: Any,
) -> tuple[list[Path], RenderStats]:
    """Render to ``out_dir/frame_0000.png`` ... plus ``animation.gif``/``.mp4`` when asked;
    ``options`` go to :func:`render_frames`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    keep: list[Frame] = []

    def sink(k: int, frame: Frame) -> None:
        path = out_dir / f"frame_{k:04d}.png"
        Image.fromarray(frame).save(path)
        written.append(path)
        if gif or mp4:
            keep.append(frame)

    _, stats = render_frames(sim, size, frames, fps, script, sink=sink, **options)
    if gif:
        path = out_dir / "animation.gif"
        write_gif(path, keep, fps)
        written.append(path)
    if mp4:
        import imageio.v3 as iio

        path = out_dir / "animation.mp4"
        try:
            iio.imwrite(path, np.stack(keep), fps=fps, codec="libx264")
            written.append(path)
        except Exception as err:  # the ffmpeg plugin is optional
            reason = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            print(f"MP4 skipped ({reason}); it needs the imageio-ffmpeg package",
                  file=sys.stderr)
    return written, stats
