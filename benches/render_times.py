"""Frame time per render pass, before and after the renderer changes of issue 18, measured in
one run and interleaved frame by frame (so both see the same machine load).

"Before" is the renderer as it was at ``--before`` (default: the commit this work started
from), taken out of git into a temporary package; "after" is the one in this tree. Both draw
the same simulation state each frame (``drape``, stepping 1/60 s between frames, so the
cloth moves), through the headless EGL path, timed with ``ctx.finish()`` at each pass
boundary (no read-back).

    python benches/render_times.py                        # print the tables
    python benches/render_times.py --write docs/rendering.md   # and replace them there
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
BEFORE = "f63df6d"
GROUPS = ("shadow", "geometry", "fill", "lighting", "post")
START, END = "<!-- render-times:start -->", "<!-- render-times:end -->"


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


class _Boundary:
    """A framebuffer stand-in: its ``use()`` marks where the old renderer's next pass starts
    (the old ``render`` is one method; its passes begin where it binds a framebuffer)."""

    def __init__(self, fbo: Any, name: str, mark: Callable[[str], None]) -> None:
        self._fbo, self._name, self._mark = fbo, name, mark

    def use(self) -> None:
        self._mark(self._name)
        self._fbo.use()

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._fbo, attr)


class PassClock:
    """Time per pass, each pass closed with ``ctx.finish()``: wall time, or the CPU time of
    the whole process (llvmpipe's threads included), which other load on the machine
    disturbs far less."""

    def __init__(self, ctx: Any, now: Callable[[], float]) -> None:
        self.ctx = ctx
        self.now = now
        self.totals: dict[str, float] = defaultdict(float)
        self._open: str | None = None
        self._t = self._t0 = 0.0

    def start(self) -> None:
        self.ctx.finish()
        self._open, self._t = None, self.now()
        self._t0 = self._t

    def begin(self, name: str | None) -> None:
        """The pass in progress is over and ``name`` begins (the old renderer's marks)."""
        self.ctx.finish()
        now = self.now()
        if self._open is not None:
            self.totals[self._open] += now - self._t
        self._open, self._t = name, now

    def ended(self, name: str) -> None:
        """Pass ``name`` is over (the new renderer's ``pass_timer``)."""
        self.ctx.finish()
        now = self.now()
        self.totals[_group(name)] += now - self._t
        self._t = now

    def stop(self) -> None:
        self.begin(None)
        self.totals["total"] += self._t - self._t0


def _group(name: str) -> str:
    return {"debug": "lighting", "fxaa": "post", "stroke": "post", "overlay": "post"}.get(
        name, name)


Result = dict[str, dict[str, dict[str, float]]]
"""clock ("wall", "cpu") -> renderer ("before", "after") -> pass group -> ms per frame."""


def measure(size: tuple[int, int], ssao: bool, frames: int, before_mod: Any,
            paused: bool = False, scale: float = 1.0) -> Result:
    """Mean ms per pass group for the old and the new renderer, interleaved, by wall clock
    and by CPU time (alternate frames)."""
    ctx = create_standalone_context()
    sim = rustcloth.Simulation(rustcloth.load_scene("drape"))
    sim.advance(0.5)
    clocks = {"before": PassClock(ctx, time.perf_counter),
              "after": PassClock(ctx, time.perf_counter)}
    cpu = {"before": PassClock(ctx, time.process_time),
           "after": PassClock(ctx, time.process_time)}
    color = ctx.renderbuffer(size, 4)
    target = ctx.framebuffer(color_attachments=[color])

    old = before_mod.Renderer(ctx, sim, size)
    old.ssao = ssao
    old_cam = before_mod.default_camera(sim.scene.to_dict(), size[0] / size[1])
    using = {"before": clocks["before"]}

    def mark(name: str | None) -> None:
        using["before"].begin(name)

    for attr, name in (("shadow_fbo", "shadow"), ("gbuffer", "geometry"), ("ao_fbo", "fill"),
                       ("lit_fbo", "lighting")):
        setattr(old, attr, _Boundary(getattr(old, attr), name, mark))
    old_target = _Boundary(target, "post", mark)
    new = Renderer(ctx, sim, size)
    new.resize(size, scale)
    new.ssao = ssao
    new_cam = new.layout.camera(size[0] / size[1])

    def draw(which: str, by_cpu: bool) -> None:
        clock = (cpu if by_cpu else clocks)[which]
        using[which] = clock
        new.pass_timer = clock.ended
        if which == "before":
            old.update()
            clock.start()
            old.render(old_target, old_cam)
        else:
            new.update()
            clock.start()
            new.render(target, new_cam)
        clock.stop()

    for k in range(2 * frames + 3):
        if k == 3:  # warmed up
            for c in (*clocks.values(), *cpu.values()):
                c.totals.clear()
        for which in ("before", "after") if k % 2 == 0 else ("after", "before"):
            draw(which, by_cpu=k % 4 >= 2)
        if not paused:
            sim.advance(1.0 / 60.0)
    out = {name: {w: {g: 1e3 * c.totals.get(g, 0.0) / frames for g in (*GROUPS, "total")}
                  for w, c in group.items()}
           for name, group in (("wall", clocks), ("cpu", cpu))}
    ctx.release()
    return out


def table(results: list[tuple[str, Result]], clock: str) -> str:
    head = "| output | configuration | renderer | " + " | ".join(GROUPS) + " | total ms |"
    rows = [head, "|" + " --- |" * (len(GROUPS) + 4)]
    for label, result in results:
        size, config = label.split(" ", 1)
        r = result[clock]
        for which in ("before", "after"):
            cells = [f"{r[which][g]:.1f}" if r[which][g] else "-" for g in GROUPS]
            rows.append(f"| {size} | {config} | {which} | " + " | ".join(cells)
                        + f" | **{r[which]['total']:.1f}** |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--before", default=BEFORE, help="git revision of the old renderer")
    parser.add_argument("--frames", type=int, default=20, help="measured frames per case")
    parser.add_argument("--write", type=Path, default=None,
                        help=f"replace the text between {START} and {END} in this file")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        before = load_before(args.before, Path(tmp))
        load0 = os.getloadavg()[0]
        results = []
        for size in ((640, 480), (1280, 720)):
            for ssao in (False, True):
                label = f"{size[0]}x{size[1]} {'lit + SSAO' if ssao else 'lit'}"
                results.append((label, measure(size, ssao, args.frames, before)))
                print(f"measured {label}", file=sys.stderr)
            label = f"{size[0]}x{size[1]} lit, paused"
            results.append((label, measure(size, False, args.frames, before, paused=True)))
            print(f"measured {label}", file=sys.stderr)
            label = f"{size[0]}x{size[1]} lit (after: at 70 % scale, as the live demo when slow)"
            results.append((label, measure(size, False, args.frames, before, scale=0.7)))
            print(f"measured {label}", file=sys.stderr)
        load1 = os.getloadavg()[0]
    ctx = create_standalone_context()
    gl = ctx.info["GL_RENDERER"]
    ctx.release()
    text = (f"Measured by `python benches/render_times.py --write docs/rendering.md` on "
            f"{gl}, {os.cpu_count()} cores (load average {load0:.1f} at the start, "
            f"{load1:.1f} at the end); `drape` at t = 0.5 s, stepping 1/60 s between frames "
            f"(paused: not stepping); before and after interleaved frame by frame, each "
            f"pass closed with `ctx.finish()`, the upload not counted; ms per frame, mean "
            f"of {args.frames} frames. Before: `{args.before}`.\n\n"
            f"Wall time (what a person waits for, but it moves with the machine's other "
            f"load):\n\n{table(results, 'wall')}\n\n"
            f"CPU time of the process, llvmpipe's threads included (what the frame costs, "
            f"much steadier under other load):\n\n{table(results, 'cpu')}")
    print(text)
    if args.write is not None:
        doc = args.write.read_text(encoding="utf-8")
        if START not in doc or END not in doc:
            raise SystemExit(f"{args.write} has no {START} ... {END} section")
        head, rest = doc.split(START, 1)
        _, tail = rest.split(END, 1)
        args.write.write_text(f"{head}{START}\n{text}\n{END}{tail}", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
