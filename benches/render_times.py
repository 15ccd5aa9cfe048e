"""Frame time per render pass on this machine's GL: the renderer as it was before the
software tier (``--before``, taken out of git into a temporary package), and this tree's
renderer in its full and its software tier, measured in one run and interleaved frame by
frame (so all three see the same machine load).

All draw the same simulation state each frame (``drape`` with its cloth at ``--grid`` x
``--grid`` particles, stepping 1/60 s between frames, so the cloth moves), through the
headless EGL path, timed with ``ctx.finish()`` at each pass boundary (no read-back), by
wall clock and by the CPU time of the whole process (alternate frames).

    python benches/render_times.py                             # print the tables (~2 min)
    python benches/render_times.py --write docs/rendering.md   # and replace them there
    python benches/render_times.py --before none --section render-times-gpu \
        --write docs/rendering.md   # on a GPU machine without git: the two tiers only
    python benches/render_times.py --before REV --before-tier software \
        --section render-times-software --write docs/rendering.md   # a tier against itself
"""

from __future__ import annotations

import argparse
import importlib
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from io import BytesIO
from pathlib import Path
from typing import Any

import rustcloth
from rustcloth.render import Renderer, create_standalone_context

ROOT = Path(__file__).resolve().parent.parent
BEFORE = "6be6c0e"
GROUPS = ("shadow", "geometry", "fill", "lighting", "forward", "post")
SECTION = "render-times"


def load_before(rev: str, into: Path) -> Any:
    """The renderer package as it was at ``rev``, importable as ``rustcloth_before.render``."""
    paths = ["python/rustcloth/render", "python/rustcloth/shaders", "python/rustcloth/camera.py"]
    data = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, *paths],
                          check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(into, filter="data")
    pkg = into / "rustcloth_before"
    (into / "python" / "rustcloth").rename(pkg)
    (pkg / "__init__.py").write_text("")
    sys.path.insert(0, str(into))
    renderer = importlib.import_module("rustcloth_before.render.renderer")
    shaders = importlib.import_module("rustcloth_before.render.shaders")
    shaders.SHADER_DIR = pkg / "shaders"  # it looked them up in the installed package
    return renderer


class PassClock:
    """Time per pass group, each pass closed with ``ctx.finish()``: wall time, or the CPU
    time of the whole process (llvmpipe's threads included), which other load on the
    machine disturbs far less."""

    def __init__(self, ctx: Any, now: Callable[[], float]) -> None:
        self.ctx = ctx
        self.now = now
        self.totals: dict[str, float] = defaultdict(float)
        self._t = self._t0 = 0.0

    def start(self) -> None:
        self.ctx.finish()
        self._t = self._t0 = self.now()

    def ended(self, name: str) -> None:
        """Pass ``name`` is over (the renderer's ``pass_timer``)."""
        self.ctx.finish()
        now = self.now()
        self.totals[_group(name)] += now - self._t
        self._t = now

    def stop(self) -> None:
        self.ctx.finish()
        self.totals["total"] += self.now() - self._t0


def _group(name: str) -> str:
    return {"debug": "lighting", "fxaa": "post", "copy": "post", "stroke": "post",
            "overlay": "post"}.get(name, name)


Result = dict[str, dict[str, dict[str, float]]]
"""clock ("wall", "cpu") -> renderer -> pass group -> ms per frame."""


def drape(grid: int) -> rustcloth.Scene:
    """The built-in ``drape`` with its cloth at ``grid`` x ``grid`` particles."""
    data = rustcloth.load_scene("drape").to_dict()
    data["cloth"]["nx"] = data["cloth"]["ny"] = grid
    return rustcloth.Scene.from_dict(data)


def measure(size: tuple[int, int], ssao: bool, frames: int, before_mod: Any, grid: int,
            paused: bool = False, before_tier: str | None = None) -> Result:
    """Mean ms per pass group for each renderer, interleaved (the order rotates every
    frame), by wall clock and by CPU time (alternate frames)."""
    ctx = create_standalone_context()
    sim = rustcloth.Simulation(drape(grid))
    sim.advance(0.5)
    color = ctx.renderbuffer(size, 4)
    target = ctx.framebuffer(color_attachments=[color])
    renderers: dict[str, Any] = {}
    if before_mod is not None:
        old_tier = {} if before_tier is None else {"tier": before_tier}
        renderers["before"] = before_mod.Renderer(ctx, sim, size, **old_tier)
    for tier in ("full", "software"):
        renderers[tier] = Renderer(ctx, sim, size, tier=tier)
    names = list(renderers)
    clocks = {clock: {name: PassClock(ctx, now) for name in names}
              for clock, now in (("wall", time.perf_counter), ("cpu", time.process_time))}
    for r in renderers.values():
        r.ssao = ssao
    camera = renderers["full"].layout.camera(size[0] / size[1])
    for k in range(frames * 2 + 3):
        if k == 3:  # warmed up
            for group in clocks.values():
                for c in group.values():
                    c.totals.clear()
        order = names[k % len(names):] + names[:k % len(names)]
        for name in order:
            clock = clocks["cpu" if k % 2 else "wall"][name]
            r = renderers[name]
            r.pass_timer = clock.ended
            r.update()
            clock.start()
            r.render(target, camera)
            clock.stop()
        if not paused:
            sim.advance(1.0 / 60.0)
    ctx.release()
    return {clock: {name: {g: 1e3 * c.totals.get(g, 0.0) / frames for g in (*GROUPS, "total")}
                    for name, c in group.items()}
            for clock, group in clocks.items()}


def table(results: list[tuple[str, Result]], clock: str) -> str:
    """One row per renderer and case; the last column is the ratio to the first renderer
    measured (the old one, or the full tier when the old one was left out)."""
    base = next(iter(results[0][1][clock]))
    head = ("| output | configuration | renderer | " + " | ".join(GROUPS)
            + " | total ms | frames/s | / " + base + " |")
    rows = [head, "|" + " --- |" * (len(GROUPS) + 6)]
    for label, result in results:
        size, config = label.split(" ", 1)
        r = result[clock]
        for which in r:
            cells = [f"{r[which][g]:.1f}" if r[which][g] else "-" for g in GROUPS]
            total = r[which]["total"]
            rows.append(f"| {size} | {config} | {which} | " + " | ".join(cells)
                        + f" | **{total:.1f}** | {1e3 / total:.1f} | "
                        + f"{total / r[base]['total']:.2f} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--before", default=BEFORE,
                        help="git revision of the old renderer, or 'none' to leave it out")
    parser.add_argument("--before-tier", default=None,
                        help="the old renderer's tier (it must have tiers), else its default")
    parser.add_argument("--frames", type=int, default=10, help="measured frames per case")
    parser.add_argument("--grid", type=int, default=64, help="cloth particles each way")
    parser.add_argument("--write", type=Path, default=None,
                        help="replace the text between the section's markers in this file")
    parser.add_argument("--section", default=SECTION,
                        help="the markers' name: <!-- NAME:start --> ... <!-- NAME:end -->")
    args = parser.parse_args(argv)
    start, end = f"<!-- {args.section}:start -->", f"<!-- {args.section}:end -->"
    cases = [((1280, 720), False, False, "lit"), ((1280, 720), False, True, "lit, paused"),
             ((1280, 720), True, False, "lit + SSAO (software: ignored)"),
             ((640, 480), False, False, "lit")]
    with tempfile.TemporaryDirectory() as tmp:
        before = None if args.before == "none" else load_before(args.before, Path(tmp))
        load0 = os.getloadavg()[0]
        results = []
        for size, ssao, paused, config in cases:
            label = f"{size[0]}x{size[1]} {config}"
            results.append((label, measure(size, ssao, args.frames, before, args.grid,
                                           paused=paused, before_tier=args.before_tier)))
            print(f"measured {label}", file=sys.stderr)
        load1 = os.getloadavg()[0]
    ctx = create_standalone_context()
    gl = ctx.info["GL_RENDERER"]
    ctx.release()
    old = ("" if before is None
           else f"the renderer before the software tier (`{args.before}`) and "
           if args.before_tier is None
           else f"the renderer at `{args.before}` in its {args.before_tier} tier (before) and ")
    command = " ".join(["python benches/render_times.py", *(argv or sys.argv[1:])])
    text = (f"Measured by `{command}` on "
            f"{gl}, {os.cpu_count()} cores (load average {load0:.1f} at the start, "
            f"{load1:.1f} at the end, from other work on the machine); `drape` with a "
            f"{args.grid} x {args.grid} cloth at t = 0.5 s, stepping 1/60 s between frames "
            f"(paused: not stepping); {old}this renderer's full and software tiers, "
            f"interleaved frame by frame, each "
            f"pass closed with `ctx.finish()`, the upload not counted; ms per frame, mean of "
            f"{args.frames} frames. Passes: shadow map; G-buffer (geometry); fill light and "
            f"SSAO at half size; lighting; the software tier's forward pass (surfaces, lit "
            f"per vertex, and the sky); post: FXAA or the software tier's copy. frames/s is "
            f"1000 / total; the last column is the ratio to the first renderer in the same run.\n\n"
            f"Wall time (what a person waits for, but it moves with the machine's other "
            f"load):\n\n{table(results, 'wall')}\n\n"
            f"CPU time of the process, the GL driver's threads included (what the frame "
            f"costs the CPU, much steadier under other load; on llvmpipe with both cores "
            f"free a frame's wall time approaches half of it):\n\n{table(results, 'cpu')}")
    print(text)
    if args.write is not None:
        doc = args.write.read_text(encoding="utf-8")
        if start not in doc or end not in doc:
            raise SystemExit(f"{args.write} has no {start} ... {end} section")
        head, rest = doc.split(start, 1)
        _, tail = rest.split(end, 1)
        args.write.write_text(f"{head}{start}\n{text}\n{end}{tail}", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
