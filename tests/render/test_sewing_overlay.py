"""The demo's overlay shows a garment's sewing: the largest seam gap, read from
``Simulation.seam_gap``, closing as the seams are drawn shut (offscreen EGL, no window)."""

from __future__ import annotations

import re
from typing import Any

import pytest
import rustcloth
from rustcloth.viewer.loop import Viewer

pytestmark = pytest.mark.render
SIZE = (96, 72)


def _seam_gap_mm(viewer: Viewer) -> float | None:
    first = viewer.status_lines()[0]
    text = first if isinstance(first, str) else first[0]
    found = re.search(r"seam gap (\d+\.\d) mm", text)
    return None if found is None else float(found.group(1))


def test_the_overlay_shows_the_seam_gap_closing(ctx: Any) -> None:
    # The skirt's side seams start 2 to 5 cm apart and close within its 0.2 s sewing time.
    sim = rustcloth.Simulation(rustcloth.load_scene("skirt"))
    fbo = ctx.simple_framebuffer(SIZE)
    viewer = Viewer(ctx, sim, SIZE, name="skirt", realtime=False)
    gap = sim.seam_gap()
    assert gap is not None and 0.04 < gap < 0.06, gap
    assert _seam_gap_mm(viewer) == round(1e3 * gap, 1)
    for _ in range(18):  # 0.3 s in frames of 1/60 s
        viewer.frame(fbo, 1 / 60)
    closed = sim.seam_gap()
    assert closed is not None and 0.0 <= closed < 0.003, closed
    assert _seam_gap_mm(viewer) == round(1e3 * closed, 1)


def test_a_cloth_without_seams_shows_no_seam_gap(ctx: Any) -> None:
    sim = rustcloth.Simulation(rustcloth.load_scene("hanging"))
    viewer = Viewer(ctx, sim, SIZE, name="hanging", realtime=False)
    assert sim.seam_gap() is None and _seam_gap_mm(viewer) is None
