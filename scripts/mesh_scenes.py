"""Writes the built-in mesh cloth scenes (scenes/round_tablecloth.toml, scenes/flag_hole.toml,
scenes/delaunay_sheet.toml) with their meshes inline: point sets triangulated by Delaunay
(Bowyer-Watson, below), so the springs follow no grid. Deterministic: the same script writes
the same files. Run ``python scripts/mesh_scenes.py`` from the repository root, then rebuild
(the built-in scenes are embedded)."""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from pathlib import Path

Point = tuple[float, float]
Triangle = tuple[int, int, int]
Inside = Callable[[float, float], bool]


def circumcircle(a: Point, b: Point, c: Point) -> tuple[float, float, float]:
    """Centre and squared radius of the circle through ``a``, ``b``, ``c``."""
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    a2, b2, c2 = a[0] ** 2 + a[1] ** 2, b[0] ** 2 + b[1] ** 2, c[0] ** 2 + c[1] ** 2
    ux = (a2 * (b[1] - c[1]) + b2 * (c[1] - a[1]) + c2 * (a[1] - b[1])) / d
    uy = (a2 * (c[0] - b[0]) + b2 * (a[0] - c[0]) + c2 * (b[0] - a[0])) / d
    return ux, uy, (a[0] - ux) ** 2 + (a[1] - uy) ** 2


def delaunay(points: list[Point], seed: int, inside: Inside) -> list[Triangle]:
    """Bowyer-Watson: each point in turn (in a shuffled order, so that runs of cocircular points
    do not come together) removes the triangles whose circumcircle holds it and fans the
    hole's rim to it. Returns the counter-clockwise triangles of ``points`` (indices) whose
    centroid is ``inside(x, y)``: the shape's outline points must be close enough together
    that its edges are Delaunay edges (no other point within half their length), which the
    callers' spacing guarantees, so nothing near the far-away enclosing triangle is kept."""
    span = max(max(abs(x), abs(y)) for x, y in points) * 100 + 1
    pts = [*points, (-span, -span), (span, -span), (0.0, span)]
    n = len(points)
    tris: dict[Triangle, tuple[float, float, float]] = {}
    first = (n, n + 1, n + 2)
    tris[first] = circumcircle(*(pts[k] for k in first))
    order = list(range(n))
    random.Random(seed).shuffle(order)
    for p in order:
        x, y = pts[p]
        bad = [t for t, (cx, cy, r2) in tris.items() if (x - cx) ** 2 + (y - cy) ** 2 < r2]
        edges: dict[tuple[int, int], int] = {}
        for t in bad:
            for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                key = (min(e), max(e))
                edges[key] = edges.get(key, 0) + 1
            del tris[t]
        for t in bad:
            for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                if edges[(min(a, b), max(a, b))] == 1:
                    new = (a, b, p)  # the rim keeps the removed triangle's winding: ccw
                    tris[new] = circumcircle(*(pts[k] for k in new))

    def kept(t: Triangle) -> bool:
        if max(t) >= n:
            return False
        x = sum(points[k][0] for k in t) / 3
        y = sum(points[k][1] for k in t) / 3
        return inside(x, y)

    out = [t for t in tris if kept(t)]
    assert all(area(points, t) > 1e-9 for t in out), min(area(points, t) for t in out)
    return out


def check_area(points: list[Point], tris: list[Triangle], expected: float, within: float) -> None:
    """The triangles tile the shape once: their areas sum to its area (a polygonal circle's
    falls short of the circle's by about ``within``)."""
    total = sum(area(points, t) for t in tris)
    assert abs(total / expected - 1) < within, f"{total} m^2, not {expected} m^2"


def area(points: list[Point], t: Triangle) -> float:
    (ax, ay), (bx, by), (cx, cy) = (points[k] for k in t)
    return 0.5 * ((bx - ax) * (cy - ay) - (cx - ax) * (by - ay))


def dart_throwing(rng: random.Random, inside: Inside, box: tuple[float, float, float, float],
                  spacing: float, fixed: list[Point]) -> list[Point]:
    """Random points in ``box`` where ``inside(x, y)`` holds, none closer than ``spacing`` to
    another or to the ``fixed`` points (which come first): an irregular, even spread."""
    points = list(fixed)
    cell = spacing / math.sqrt(2)
    grid: dict[tuple[int, int], list[Point]] = {}
    for q in points:
        grid.setdefault((int(q[0] // cell), int(q[1] // cell)), []).append(q)
    x0, y0, x1, y1 = box
    for _ in range(int(40 * (x1 - x0) * (y1 - y0) / spacing**2)):
        x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
        if not inside(x, y):
            continue
        i, j = int(x // cell), int(y // cell)
        around = ((i + di, j + dj) for di in range(-2, 3) for dj in range(-2, 3))
        near = (q for key in around for q in grid.get(key, []))
        if all((x - q[0]) ** 2 + (y - q[1]) ** 2 >= spacing**2 for q in near):
            points.append((x, y))
            grid.setdefault((i, j), []).append((x, y))
    return points


def ring(cx: float, cy: float, r: float, spacing: float) -> list[Point]:
    k = max(6, round(2 * math.pi * r / spacing))
    return [(cx + r * math.cos(2 * math.pi * i / k), cy + r * math.sin(2 * math.pi * i / k))
            for i in range(k)]


def square_outline(x0: float, y0: float, x1: float, y1: float, spacing: float) -> list[Point]:
    nx, ny = round((x1 - x0) / spacing), round((y1 - y0) / spacing)
    out = [(x0 + (x1 - x0) * i / nx, y0) for i in range(nx)]
    out += [(x1, y0 + (y1 - y0) * j / ny) for j in range(ny)]
    out += [(x1 - (x1 - x0) * i / nx, y1) for i in range(nx)]
    out += [(x0, y1 - (y1 - y0) * j / ny) for j in range(ny)]
    return out


def mesh_toml(vertices: list[tuple[float, float, float]], triangles: list[Triangle]) -> str:
    v = ",\n".join(f"  [{x:.6f}, {y:.6f}, {z:.6f}]" for x, y, z in vertices)
    t = ",\n".join(f"  [{a}, {b}, {c}]" for a, b, c in triangles)
    return f"vertices = [\n{v},\n]\ntriangles = [\n{t},\n]\n"


def used_only(points: list[Point], tris: list[Triangle]) -> tuple[list[Point], list[Triangle]]:
    """Drops the points no triangle uses (a mesh cloth refuses them), renumbering the rest."""
    used = sorted({k for t in tris for k in t})
    index = {k: i for i, k in enumerate(used)}
    return [points[k] for k in used], [(index[a], index[b], index[c]) for a, b, c in tris]


def round_tablecloth() -> str:
    rng = random.Random(1)
    spacing, radius = 0.045, 0.8
    outline = ring(0.0, 0.0, radius, spacing)
    pts = dart_throwing(rng, lambda x, y: x * x + y * y < (radius - 0.6 * spacing) ** 2,
                        (-radius, -radius, radius, radius), spacing, outline)
    tris = delaunay(pts, 7, lambda x, y: x * x + y * y < radius**2)
    check_area(pts, tris, math.pi * radius**2, 0.01)
    pts, tris = used_only(pts, tris)
    # In the xz plane at 0.95 m: (x, y) -> (x, 0.95, -y) turns counter-clockwise from +z into
    # counter-clockwise from +y (normals up).
    vertices = [(x, 0.95, -y) for x, y in pts]
    return HEAD_TABLECLOTH + mesh_toml(vertices, tris)


def flag_hole() -> str:
    rng = random.Random(2)
    spacing, (w, h), (hx, hy, hr) = 0.035, (1.2, 0.8), (0.55, 0.0, 0.14)
    fixed = square_outline(0.0, -h / 2, w, h / 2, spacing) + ring(hx, hy, hr, spacing)
    pts = dart_throwing(
        rng,
        lambda x, y: (x - hx) ** 2 + (y - hy) ** 2 > (hr + 0.6 * spacing) ** 2
        and 0.6 * spacing < x < w - 0.6 * spacing and abs(y) < h / 2 - 0.6 * spacing,
        (0.0, -h / 2, w, h / 2), spacing, fixed)
    tris = delaunay(pts, 7, lambda x, y: 0 < x < w and abs(y) < h / 2
                    and (x - hx) ** 2 + (y - hy) ** 2 > hr**2)
    check_area(pts, tris, w * h - math.pi * hr**2, 0.01)
    pts, tris = used_only(pts, tris)
    # A gentle wave across it (3 cm, 60 cm long), as a flag has, so that it folds as it falls
    # rather than hang flat in its own plane.
    vertices = [(0.05 + x, 2.0 + y, 0.03 * math.sin(2 * math.pi * x / 0.6)) for x, y in pts]
    return HEAD_FLAG + mesh_toml(vertices, tris)


def delaunay_sheet() -> str:
    rng = random.Random(3)
    spacing = 0.04
    fixed = square_outline(-0.5, -0.5, 0.5, 0.5, spacing)
    pts = dart_throwing(rng, lambda x, y: max(abs(x), abs(y)) < 0.5 - 0.6 * spacing,
                        (-0.5, -0.5, 0.5, 0.5), spacing, fixed)
    tris = delaunay(pts, 7, lambda x, y: max(abs(x), abs(y)) < 0.5)
    check_area(pts, tris, 1.0, 1e-9)
    pts, tris = used_only(pts, tris)
    vertices = [(x, 0.5, -y) for x, y in pts]
    return HEAD_SHEET + mesh_toml(vertices, tris)


def scene_toml(comment: str, air_drag: float, floor_thickness: float, middle: str, pins: str,
               material: tuple[float, float, float, float]) -> str:
    """A scene file: ``comment``, symplectic Euler at 1 ms in two substeps under gravity, the
    floor, ``middle`` (colliders, passes), the cloth's ``pins`` line and its ``material``
    (density, stretch, bend, damping); the mesh's vertices and triangles follow."""
    density, stretch, bend, damping = material
    return f"""{comment}integrator = "symplectic_euler"
dt = 0.001
substeps = 2
gravity = [0.0, -9.81, 0.0]
air_drag = {air_drag}

[floor]
height = 0.0
friction = 0.5
thickness = {floor_thickness}

{middle}
[cloth]
{pins}

[cloth.mesh]
density = {density}
stretch = {stretch}
bend = {bend}
damping = {damping}
"""


HEAD_TABLECLOTH = scene_toml(
    """\
# A round tablecloth (an 80 cm disc, an irregular Delaunay mesh: scripts/mesh_scenes.py writes
# this file) dropped onto a round table: a cylinder top on one central leg. It lands flat,
# falls over the rim all round and folds into soft pleats.
""", 0.0002, 0.005, """\
# The top: 50 cm in radius, 4 cm thick, its upper face at 0.77 m; and its leg.
[[colliders]]
shape = "cylinder"
radius = 0.5
half_height = 0.02
center = [0.0, 0.75, 0.0]
friction = 0.5
thickness = 0.008

[[colliders]]
shape = "cylinder"
radius = 0.05
half_height = 0.365
center = [0.0, 0.365, 0.0]
thickness = 0.008

# A drag can fold the cloth over itself on the table: the layers are kept apart.
[self_collision]
thickness = 0.003
""", "pins = []", (0.4, 1200.0, 80.0, 0.12))

HEAD_FLAG = scene_toml(
    """\
# A flag with a round hole, on a pole, in still air (an irregular Delaunay mesh:
# scripts/mesh_scenes.py writes this file): its edge along the pole is pinned, and it falls
# and swings against the pole and hangs, the hole stretched by its weight.
""", 0.0005, 0.005, """\
# The pole: a capsule 2.5 cm in radius, its axis 3 cm to the left of the flag's edge.
[[colliders]]
shape = "capsule"
radius = 0.025
half_height = 1.2
center = [0.02, 1.2, 0.0]
friction = 0.3
thickness = 0.005

# A drag can fold the flag over itself or through its hole: the layers are kept apart.
[self_collision]
thickness = 0.003
""", """\
# The vertices along the pole (the flag's left edge, x = 0.05 m).
pins = [{ box = [[0.049, 1.5, -0.01], [0.051, 2.5, 0.01]] }]""", (0.15, 480.0, 16.0, 0.03))

HEAD_SHEET = scene_toml(
    """\
# A 1 m sheet of an irregular Delaunay triangulation (random points at least 4 cm apart:
# scripts/mesh_scenes.py writes this file) dropped over a ball: no grid lines to fold along,
# so it folds where the ball and its weight put the folds. Self-collision keeps its folds apart.
""", 0.0002, 0.004, """\
[[spheres]]
center = [0.0, 0.15, 0.0]
radius = 0.15
friction = 0.4
thickness = 0.004

[self_collision]
thickness = 0.003
friction = 0.3
iterations = 4
""", "pins = []", (0.3, 600.0, 40.0, 0.06))


def main() -> None:
    scenes = Path(__file__).resolve().parent.parent / "scenes"
    for name, text in [("round_tablecloth", round_tablecloth()), ("flag_hole", flag_hole()),
                       ("delaunay_sheet", delaunay_sheet())]:
        (scenes / f"{name}.toml").write_text(text)
        print(f"scenes/{name}.toml: {text.count(chr(10))} lines")


if __name__ == "__main__":
    main()
