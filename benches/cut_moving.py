"""A live cut across a moving cloth, scripted as the demo makes it: the viewer's own
gesture objects (``Pointer`` over ``Interaction``, the layout's camera) with the simulation
advanced by ``1 / fps`` after each frame's mouse move, no window. A straight stroke from 10 px
left of the cloth's on-screen box to 10 px right of it, at a height given as a share of the
box, over ``--stroke`` seconds. Prints springs cut and pieces for each height and frame rate,
and the same stroke with the cloth held still between frames. Mesh cloths too: ``flag_hole``
(an irregular mesh with a hole, hung from a pole) and ``delaunay_sheet`` (an irregular mesh
dropped over a ball) and ``mesh_hanging`` (``hanging`` as an irregular mesh) have flat rest
shapes, which the live stroke is held on.

    PYTHONPATH=python python benches/cut_moving.py [--scene hanging mesh_hanging flag_hole]
        [--settle 3] [--swept] [--digest]

``--digest`` adds to each run a hash of the cloth after it (piece labels, severed springs'
count, positions), to show two builds cut alike bit for bit. ``--cost 32 128`` instead times a
cutting frame (``sever_live_stroke``, CPU time on this thread): a straight stroke of 22 rays a
frame across the irregular ``hanging`` mesh of that size and the grid of that size, moving (the
cloth advanced between frames, not timed) and held still.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from typing import Any

import numpy as np
from rustcloth import Scene, Simulation
from rustcloth.render.renderer import layout_of
from rustcloth.viewer.interaction import Interaction, Pointer

SIZE = (1280, 800)


def jittered_square(n: int, seed: int = 0, jitter: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """An irregular triangulation of the ``hanging`` grid's 1 m square (y = 1.5, in x and z):
    ``n`` x ``n`` points, the interior ones jittered by up to ``jitter`` spacings, each quad
    split along its shorter diagonal."""
    rng = np.random.default_rng(seed)
    h = 1.0 / (n - 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    inner_i, inner_j = (i > 0) & (i < n - 1), (j > 0) & (j < n - 1)
    x = i * h - 0.5 + np.where(inner_i, rng.uniform(-jitter, jitter, i.shape) * h, 0)
    z = j * h - 0.5 + np.where(inner_j, rng.uniform(-jitter, jitter, j.shape) * h, 0)
    vertices = np.stack([x.ravel(), np.full(n * n, 1.5), z.ravel()], axis=1)
    triangles = []
    for jj in range(n - 1):
        for ii in range(n - 1):
            a = jj * n + ii
            b, c, d = a + 1, a + n, a + n + 1
            if np.sum((vertices[a] - vertices[d]) ** 2) <= np.sum((vertices[b] - vertices[c]) ** 2):
                triangles += [[a, d, b], [a, c, d]]
            else:
                triangles += [[a, c, b], [b, c, d]]
    return vertices, np.array(triangles, dtype=np.int64)


def mesh_hanging(n: int = 32) -> Scene:
    """``hanging`` as an irregular ``n`` x ``n`` mesh of the same material (stretch modulus
    ``2 (k_structural + 2 k_shear)``, bend ``8 k_bend``, the same mass), held by the same two
    corners, with three substeps a step (the mesh's stiffest spring is stiffer than the
    grid's)."""
    vertices, triangles = jittered_square(n)
    pins = [{"box": [[-0.51, 1.49, 0.49], [-0.49, 1.51, 0.51]]},
            {"box": [[0.49, 1.49, 0.49], [0.51, 1.51, 0.51]]}]
    return Simulation("hanging").scene.replace(substeps=3).with_cloth_mesh(
        vertices, triangles, pins=pins, density=1.024, stretch=2400.0, bend=160.0)


def simulation(scene: str | Scene) -> Simulation:
    """The scene by name (``mesh_hanging``: :func:`mesh_hanging`), or as given."""
    return Simulation(mesh_hanging() if scene == "mesh_hanging" else scene)


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


def live_stroke(scene: str | Scene, height: float, fps: float, *, settle: float = 3.0,
                stroke_s: float = 0.6, still: bool = False,
                swept: bool = False) -> tuple[int, int, Any, int]:
    """Springs cut and pieces after one stroke across ``scene`` at ``height`` (0 top, 1
    bottom of the cloth's on-screen box), the mouse moved once a frame at ``fps``; and how
    many times the stroke came onto the cloth."""
    sim = simulation(scene)
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


def digest(sim: Simulation) -> str:
    """A hash of the cloth as it is: which piece each particle is in, and where it is."""
    h = hashlib.sha256(np.asarray(sim.piece_labels()).tobytes())
    h.update(np.ascontiguousarray(sim.positions).tobytes())
    return h.hexdigest()[:12]


def frame_cost(n: int, mesh: bool, still: bool, frames: int = 12,
               rays_a_frame: int = 22) -> list[float]:
    """CPU seconds of each ``sever_live_stroke`` frame of a straight stroke across ``hanging``
    (``n`` x ``n``, the grid or the irregular mesh) at a third of its depth, from 10 cm off one
    edge to 10 cm off the other, looking straight down on it as it is laid out; the cloth
    advances 1/50 s between frames (untimed) unless ``still``."""
    scene = mesh_hanging(n) if mesh else Simulation("hanging").scene.replace(
        cloth={"nx": n, "ny": n})
    # Implicit Euler: the finer meshes are past symplectic Euler's stable step.
    sim = Simulation(scene.replace(integrator="implicit_euler"))
    xs = np.linspace(-0.6, 0.6, frames * rays_a_frame)
    times = []
    for k in range(frames):
        rays = [((float(x), 3.0, 0.17), (0.0, -1.0, 0.0))
                for x in xs[k * rays_a_frame:(k + 1) * rays_a_frame]]
        t0 = time.process_time()
        sim.sever_live_stroke(rays)
        times.append(time.process_time() - t0)
        if not still:
            sim.advance(0.02)
    sim.end_live_stroke()
    return times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", nargs="+", default=["hanging"])
    ap.add_argument("--settle", type=float, default=3.0)
    ap.add_argument("--stroke", type=float, default=0.6)
    ap.add_argument("--swept", action="store_true",
                    help="cut as the viewer did before: frame by frame, by the swept surface")
    ap.add_argument("--digest", action="store_true",
                    help="print a hash of the cloth after each run")
    ap.add_argument("--cost", type=int, nargs="+", metavar="N",
                    help="time a cutting frame on the N x N grid and mesh instead")
    args = ap.parse_args()
    if args.cost:
        for n in args.cost:
            for mesh in (False, True):
                for still in (False, True):
                    ms = 1e3 * np.array(frame_cost(n, mesh, still))
                    print(f"cost {n}x{n} {'mesh' if mesh else 'grid'} "
                          f"{'still' if still else 'moving'}: {ms.mean():.3f} ms a frame "
                          f"(first {ms[0]:.3f}, median {np.median(ms):.3f})")
        return 0
    for scene in args.scene:
        for still in (False, True):
            two, counts, slivers = 0, [], 0
            for fps in (60.0, 20.0, 8.0):
                for height in (0.3, 0.6, 0.85):
                    cut, pieces, sim, runs = live_stroke(scene, height, fps,
                                                         settle=args.settle,
                                                         stroke_s=args.stroke, still=still,
                                                         swept=args.swept)
                    two += pieces >= 2
                    counts.append(cut)
                    slivers += sum(1 for k in sizes(sim) if k < 3)
                    print(f"{scene} {'still' if still else 'moving'} fps {fps:4.0f} "
                          f"height {height:.2f}: {cut} springs cut, {pieces} pieces "
                          f"{sizes(sim)[:4]}, came on {runs} times"
                          + (f" digest {digest(sim)}" if args.digest else ""))
            print(f"{scene} {'still' if still else 'moving'}: two or more pieces in {two} of 9,"
                  f" springs cut {min(counts)}-{max(counts)}, slivers (pieces under 3 particles)"
                  f" {slivers}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
