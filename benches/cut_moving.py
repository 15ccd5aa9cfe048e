"""A live cut across a moving cloth, scripted as the demo makes it: the viewer's own
gesture objects (``Pointer`` over ``Interaction``, the layout's camera) with the simulation
advanced by ``1 / fps`` after each frame's mouse move, no window. A straight stroke from 10 px
left of the cloth's on-screen box to 10 px right of it, at a height given as a share of the
box, over ``--stroke`` seconds. Prints springs cut and pieces for each height and frame rate,
and the same stroke with the cloth held still between frames.

    PYTHONPATH=python python benches/cut_moving.py [--scene hanging] [--settle 3] [--swept]
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np
from rustcloth import Simulation
from rustcloth.render.renderer import layout_of
from rustcloth.viewer.interaction import Interaction, Pointer

SIZE = (1280, 800)


class Picked:
    """The simulation, counting how many times the stroke came onto the cloth (runs of rays
    that hit it, as each frame's rays meet it before they cut)."""

    def __init__(self, sim: Simulation, swept: bool = False) -> None:
        self.sim, self.runs, self._on = sim, 0, False
        self.swept = swept
        """Cut as the viewer did before ``sever_live_stroke``: each frame's rays with the last
        frame's last ray, by the surface they sweep through the cloth as it is then."""
        self._last: Any = None

    def end_live_stroke(self) -> None:
        self._last = None
        self.sim.end_live_stroke()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.sim, name)

    def sever_live_stroke(self, rays: Any) -> int:
        for origin, direction in rays:
            on = self.sim.pick_triangle(origin, direction) is not None
            self.runs += on and not self._on
            self._on = on
        if not self.swept:
            return int(self.sim.sever_live_stroke(rays))
        stroke = rays if self._last is None else [self._last, *rays]
        self._last = rays[-1]
        return int(self.sim.sever_stroke(stroke)) if len(stroke) >= 2 else 0


def live_stroke(scene: str, height: float, fps: float, *, settle: float = 3.0,
                stroke_s: float = 0.6, still: bool = False,
                swept: bool = False) -> tuple[int, int, Any, int]:
    """Springs cut and pieces after one stroke across ``scene`` at ``height`` (0 top, 1
    bottom of the cloth's on-screen box), the mouse moved once a frame at ``fps``; and how
    many times the stroke came onto the cloth."""
    sim = Simulation(scene)
    camera = layout_of(sim).camera(SIZE[0] / SIZE[1])
    picked = Picked(sim, swept)
    interaction = Interaction(picked)  # type: ignore[arg-type]
    pointer = Pointer(interaction, camera, SIZE)
    sim.advance(settle)
    pos = sim.positions[sim.alive]
    px = np.array([camera.project(p, *SIZE)[:2] for p in pos])
    lo, hi = px.min(axis=0), px.max(axis=0)
    y = lo[1] + height * (hi[1] - lo[1])
    start, end = np.array([lo[0] - 10, y]), np.array([hi[0] + 10, y])
    frames = max(1, round(stroke_s * fps))
    pointer.press("cut", *start)
    if not still:
        sim.advance(1.0 / fps)
    for k in range(1, frames + 1):
        pointer.move(*(start + k / frames * (end - start)))
        if not still:
            sim.advance(1.0 / fps)
    pointer.release()
    return interaction.cut_count, sim.pieces(), sim, picked.runs


def sizes(sim: Simulation) -> list[int]:
    """Particles in each piece, largest first."""
    labels = sim.piece_labels()
    counts = np.unique(labels[sim.alive], return_counts=True)[1]
    return sorted(counts.tolist(), reverse=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="hanging")
    ap.add_argument("--settle", type=float, default=3.0)
    ap.add_argument("--stroke", type=float, default=0.6)
    ap.add_argument("--swept", action="store_true",
                    help="cut as the viewer did before: frame by frame, by the swept surface")
    args = ap.parse_args()
    for still in (False, True):
        two = 0
        for fps in (60.0, 20.0, 8.0):
            for height in (0.3, 0.6, 0.85):
                cut, pieces, sim, runs = live_stroke(args.scene, height, fps, settle=args.settle,
                                             stroke_s=args.stroke, still=still,
                                                  swept=args.swept)
                two += pieces >= 2
                print(f"{'still' if still else 'moving'} fps {fps:4.0f} height {height:.2f}: "
                      f"{cut} springs cut, {pieces} pieces {sizes(sim)}, came on {runs} times")
        print(f"{'still' if still else 'moving'}: two or more pieces in {two} of 9")
    return 0


if __name__ == "__main__":
    sys.exit(main())
