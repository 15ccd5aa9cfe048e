"""Picking, dragging and cutting from Python, against a numpy brute-force reference.

The reference below tests every particle box and every triangle in float64. The solver works
in float32, so "the same answer" means: the same particle or triangle, unless another one is
tied with it to within rounding, and the same distance to within rounding. (The Rust tests,
tests/picking.rs, check that the BVH and the Rust brute-force scan agree bit for bit.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import rustcloth
from conftest import small_scene, state_digest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from rustcloth import Simulation

TOL = 1e-4
G = np.array([0.0, -9.81, 0.0])

property_settings = settings(
    derandomize=True,
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


# ----- the reference ---------------------------------------------------------------------


def unit(direction) -> np.ndarray:
    d = np.asarray(direction, np.float32).astype(np.float64)
    return d / np.linalg.norm(d)


def particle_hits(sim, origin, direction, grow=0.0):
    """Per particle: entry distance of the ray into its box (inf for a miss, 0 from inside)
    and the distance from the ray to the particle. ``grow`` widens (or, < 0, shrinks) the
    boxes, to tell robust hits from marginal ones."""
    pos = sim.positions.astype(np.float64)
    o = np.asarray(origin, np.float32).astype(np.float64)
    d = unit(direction)
    r = sim.pick_radius + grow
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (pos - r - o) / d
        b = (pos + r - o) / d
    near = np.where(d > 0, a, b)
    far = np.where(d > 0, b, a)
    inside = (pos - r <= o) & (o <= pos + r)
    near = np.where(d == 0, np.where(inside, -np.inf, np.inf), near)
    far = np.where(d == 0, np.where(inside, np.inf, -np.inf), far)
    enter = np.maximum(near.max(axis=1), 0.0)
    hit = (enter <= far.min(axis=1)) & sim.alive
    t = np.where(hit, enter, np.inf)
    offset = np.linalg.norm(np.cross(pos - o, d), axis=1)
    return t, offset


def triangle_hits(sim, origin, direction, margin=0.0):
    """Per row of ``sim.triangles``: distance along the ray to the triangle (inf for a miss)
    and whether the triangle is well shaped (not nearly degenerate, where float32 and float64
    disagree). ``margin`` > 0 widens the triangles, < 0 shrinks them and drops badly shaped
    ones."""
    tris = sim.triangles
    pos = sim.positions.astype(np.float64)
    o = np.asarray(origin, np.float32).astype(np.float64)
    d = unit(direction)
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    e1, e2 = b - a, c - a
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tv = o - a
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        v = (qv @ d) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
        w = np.stack([1 - u - v, u, v], axis=1)
    well_shaped = np.abs(det) > 1e-3 * scale
    ok = well_shaped if margin < 0 else (det != 0)
    hit = ok & (w.min(axis=1) >= -margin) & (t >= -margin)
    return np.where(hit, t, np.inf), well_shaped


def assert_pick_matches_reference(sim, origin, direction):
    got = sim.pick(origin, direction)
    strict, offset = particle_hits(sim, origin, direction, grow=-TOL)
    loose, _ = particle_hits(sim, origin, direction, grow=TOL)
    if got is None:
        assert np.isinf(strict).all(), "the reference hits a particle the BVH missed"
        return
    index, distance = got
    assert sim.alive[index]
    assert np.isfinite(loose[index]), "the BVH hit a particle the reference misses"
    exact, _ = particle_hits(sim, origin, direction)
    if np.isfinite(exact[index]):  # else a hit within rounding of the box's edge
        assert abs(distance - exact[index]) < TOL * (1 + distance)
    best = strict.min()
    assert distance <= best + 10 * TOL * (1 + best)
    # Ties along the ray: when the ray starts inside several boxes (distance 0, exact in float32
    # as well), the particle nearest the ray wins. (Other near-ties are decided by float32
    # rounding, which a float64 reference cannot reproduce; tests/picking.rs checks them bit
    # for bit against the Rust brute force.)
    if distance == 0.0:
        tied = strict == 0.0
        assert offset[index] <= offset[tied].min(initial=np.inf) + 10 * TOL


def assert_pick_triangle_matches_reference(sim, origin, direction):
    got = sim.pick_triangle(origin, direction)
    strict, _ = triangle_hits(sim, origin, direction, margin=-TOL)
    loose, well_shaped = triangle_hits(sim, origin, direction, margin=TOL)
    if got is None:
        assert np.isinf(strict).all(), "the reference hits a triangle the BVH missed"
        return
    index, distance, bary = got
    assert distance <= strict.min() + 10 * TOL * (1 + distance)
    assert abs(sum(bary) - 1.0) < 1e-5
    if not well_shaped[index]:
        return  # a sliver: float32 rounding decides whether it is hit
    assert np.isfinite(loose[index])
    corners = sim.positions[sim.triangles[index]].astype(np.float64)
    point = np.asarray(bary) @ corners
    expected = np.asarray(origin, np.float32) + distance * unit(direction)
    assert np.linalg.norm(point - expected) < 1e-3 * (1 + distance)


# ----- strategies ------------------------------------------------------------------------

coord = st.floats(-1.0, 1.0, width=32)
vec3 = st.tuples(coord, coord, coord)
direction3 = vec3.filter(lambda v: math.hypot(*v) > 1e-3)


@st.composite
def deformed_cloths(draw):
    """A bare cloth with random positions: scattered, or the flat grid plus noise."""
    nx, ny = draw(st.integers(2, 9)), draw(st.integers(2, 9))
    sim = Simulation(small_scene(cloth={"nx": nx, "ny": ny, "pins": []}))
    n = nx * ny
    noise = hnp.arrays(np.float32, (n, 3), elements=coord)
    if draw(st.booleans()):
        sim.set_positions(draw(noise))
    else:
        sim.set_positions(sim.positions + 0.1 * draw(noise))
    for p in draw(st.lists(st.integers(0, n - 1), max_size=n // 2)):
        sim.cut(p)
    if draw(st.booleans()):
        sim.pick_radius = draw(st.floats(0.005, 0.3))
    return sim


@st.composite
def rays(draw, sim):
    """A ray from anywhere, aimed at a particle (plus a little) or anywhere at all."""
    origin = np.array(draw(vec3)) * 2.0
    if draw(st.booleans()):
        target = sim.positions[draw(st.integers(0, sim.num_particles - 1))]
        direction = target + 0.02 * np.array(draw(vec3)) - origin
        if np.linalg.norm(direction) < 1e-3:
            direction = np.array([0.0, 0.0, -1.0])
    else:
        direction = np.array(draw(direction3))
    return origin, direction


# ----- properties ------------------------------------------------------------------------


@property_settings
@given(data=st.data(), strategy=st.sampled_from(["auto", "bvh", "scan"]))
def test_pick_equals_a_brute_force_scan_on_random_deformed_cloths(data, strategy):
    sim = data.draw(deformed_cloths())
    sim.pick_strategy = strategy
    for _ in range(5):
        origin, direction = data.draw(rays(sim))
        assert_pick_matches_reference(sim, origin, direction)
        assert_pick_triangle_matches_reference(sim, origin, direction)


@property_settings
@given(data=st.data())
def test_after_the_cloth_moves_the_refitted_trees_still_answer_exactly(data):
    sim = data.draw(deformed_cloths())
    sim.pick_strategy = "bvh"
    origin, direction = data.draw(rays(sim))
    sim.pick(origin, direction)
    sim.pick_triangle(origin, direction)
    shift = data.draw(hnp.arrays(np.float32, (sim.num_particles, 3), elements=coord))
    sim.set_positions(sim.positions + 0.2 * shift)
    for _ in range(3):
        origin, direction = data.draw(rays(sim))
        assert_pick_matches_reference(sim, origin, direction)
        assert_pick_triangle_matches_reference(sim, origin, direction)
    stats = sim.bvh_stats()
    assert stats["particle_builds"] == stats["triangle_builds"] == 1
    assert stats["particle_refits"] == stats["triangle_refits"] == 1


def assert_topology_consistent(sim):
    alive = sim.alive
    assert alive.shape == (sim.num_particles,) and alive.dtype == np.bool_
    assert alive[sim.triangles].all(), "a triangle refers to a dead particle"
    # Every dead particle has no force on it and stays put.
    before = sim.positions[~alive].copy()
    sim.step(1)
    assert np.array_equal(sim.positions[~alive], before)


@property_settings
@given(
    ops=st.lists(
        st.one_of(
            st.tuples(st.just("cut"), st.integers(0, 47)),
            st.tuples(st.just("cut_ray"), st.integers(0, 47)),
            st.tuples(st.just("stroke"), st.lists(st.integers(0, 47), max_size=6)),
            st.tuples(st.just("step"), st.integers(1, 5)),
        ),
        max_size=25,
    )
)
def test_topology_stays_consistent_after_any_sequence_of_cuts(ops):
    sim = Simulation(small_scene())  # 8 x 6 in the xy plane: rays along -z see every particle
    front = np.array([0.0, 0.0, 3.0])
    for op, arg in ops:
        if op == "cut":
            sim.cut(arg)
        elif op == "cut_ray":
            hit = sim.cut_ray(sim.positions[arg] + front, [0, 0, -1])
            assert hit is None or not sim.alive[hit]
        elif op == "stroke":
            cut = sim.cut_stroke([(sim.positions[p] + front, (0, 0, -1)) for p in arg])
            assert len(set(cut)) == len(cut)
        else:
            sim.step(arg)
        assert_topology_consistent(sim)


# ----- cutting the cloth apart -----------------------------------------------------------


def hanging(nx=12, ny=10):
    """A vertical cloth hanging from its top corners, no air drag."""
    sim = Simulation(small_scene(air_drag=0.0, cloth={"nx": nx, "ny": ny}))
    sim.step(300)
    return sim


def pieces(sim):
    """Connected parts of the live cloth, by its triangles (each part a set of particles)."""
    parent = list(range(sim.num_particles))

    def root(p):
        while parent[p] != p:
            parent[p] = parent[parent[p]]
            p = parent[p]
        return p

    for a, b, c in sim.triangles:
        for q in (b, c):
            parent[root(int(q))] = root(int(a))
    groups: dict[int, set[int]] = {}
    for p in np.flatnonzero(sim.alive):
        groups.setdefault(root(int(p)), set()).add(int(p))
    return list(groups.values())


def stroke_over(sim, particles):
    return np.array([[sim.positions[p] + [0.0, 0.0, 2.0], [0.0, 0.0, -1.0]] for p in particles])


def acceleration(sim, piece, steps=50):
    idx = sorted(piece)
    v0 = sim.velocities[idx].astype(np.float64).mean(axis=0)
    sim.step(steps)
    v1 = sim.velocities[idx].astype(np.float64).mean(axis=0)
    return (v1 - v0) / (steps * sim.dt)


def test_a_cut_down_a_column_between_the_pins_splits_the_cloth_and_an_unpinned_piece_falls():
    sim = hanging()
    nx, ny, column = sim.nx, sim.ny, 5
    cut = sim.cut_stroke(stroke_over(sim, [j * nx + column for j in reversed(range(ny))]))
    assert cut == [j * nx + column for j in reversed(range(ny))]
    parts = pieces(sim)
    assert len(parts) == 2
    right_pin = ny * nx - 1
    right = next(p for p in parts if right_pin in p)
    assert all(p % nx > column for p in right)
    sim.unpin(right_pin)
    assert np.allclose(acceleration(sim, right), G, atol=0.01)


def test_a_cut_across_a_row_below_the_pinned_edge_drops_the_lower_piece():
    sim = hanging(10, 12)
    nx, row = sim.nx, sim.ny - 4
    assert len(sim.cut_stroke(stroke_over(sim, [row * nx + i for i in range(nx)]))) == nx
    parts = pieces(sim)
    assert len(parts) == 2
    lower = next(p for p in parts if 0 in p)
    assert lower == set(range(row * nx))
    assert not sim.pinned[sorted(lower)].any()
    assert np.allclose(acceleration(sim, lower), G, atol=0.01)


def test_cutting_every_particle_leaves_nothing_to_pick_and_stepping_works():
    sim = Simulation(small_scene())
    origin, down = [0.1, 1.0, 2.0], [0.0, 0.0, -1.0]
    assert sim.pick(origin, down) is not None
    assert sim.pick_triangle(origin, down) is not None
    for p in range(sim.num_particles):
        sim.cut(p)
    assert not sim.alive.any()
    assert sim.triangles.shape == (0, 3)
    assert sim.pick(origin, down) is None
    assert sim.pick_triangle(origin, down) is None
    assert sim.cut_ray(origin, down) is None
    assert sim.cut_stroke([(origin, down)]) == []
    sim.step(10)
    assert np.isfinite(sim.positions).all()


# ----- dragging --------------------------------------------------------------------------


def test_pick_finds_the_particle_under_the_cursor():
    sim = Simulation(small_scene())
    for p in (0, 9, 27, 47):
        index, distance = sim.pick(sim.positions[p] + [0.0, 0.0, 1.5], [0, 0, -2])
        assert index == p
        assert distance == pytest.approx(1.5 - sim.pick_radius, abs=1e-5)
    assert sim.pick([5.0, 5.0, 5.0], [0, 0, 1]) is None


def test_grab_drag_release():
    sim = Simulation(small_scene())
    p, neighbour = 2 * 8 + 3, 2 * 8 + 4
    target = sim.positions[p] + [0.0, 0.0, 0.2]
    start = sim.positions[neighbour].copy()
    sim.grab(p)
    assert sim.grabbed() == p
    assert sim.pinned[p]
    sim.drag_to(target)
    sim.step(200)
    assert np.allclose(sim.positions[p], target)
    assert sim.positions[neighbour][2] - start[2] > 0.05, "the neighbour follows"
    velocity = sim.velocities[p].copy()
    sim.release()
    assert sim.grabbed() is None
    assert not sim.pinned[p]
    assert np.array_equal(sim.velocities[p], velocity)
    # A pinned corner stays pinned after a grab and release.
    corner = sim.num_particles - 1
    sim.grab(corner)
    sim.drag_to(sim.positions[corner] + [0.05, 0.0, 0.0])
    sim.step(3)
    sim.release()
    assert sim.pinned[corner]
    where = sim.positions[corner].copy()
    sim.step(20)
    assert np.array_equal(sim.positions[corner], where)


def test_drag_and_release_without_a_grab_do_nothing(sim):
    before = state_digest(sim)
    sim.drag_to([0.0, 0.0, 0.0])
    sim.release()
    assert sim.grabbed() is None
    assert state_digest(sim) == before


def test_auto_scans_for_one_pick_per_frame_and_refits_for_more():
    sim = Simulation(small_scene())
    assert sim.pick_strategy == "auto"
    at, down = sim.positions[20] + [0.0, 0.0, 1.0], [0, 0, -1]
    for _ in range(3):
        sim.step(16)
        assert sim.pick(at, down)[0] == 20
    stats = sim.bvh_stats()
    assert (stats["particle_scans"], stats["particle_builds"]) == (3, 0)
    assert sim.pick(at, down)[0] == 20
    assert sim.bvh_stats()["particle_builds"] == 1
    sim.pick_strategy = "scan"
    assert sim.pick_strategy == "scan"
    with pytest.raises(ValueError, match="strategy"):
        sim.pick_strategy = "octree"


def test_the_pick_radius_is_a_property():
    sim = Simulation(small_scene())
    spacing = min(0.7 / 7, 0.5 / 5)
    assert sim.pick_radius == pytest.approx(spacing / 2)
    sim.pick_radius = 0.01
    assert sim.pick_radius == pytest.approx(0.01)
    with pytest.raises(ValueError, match="radius"):
        sim.pick_radius = -1.0


# ----- bad input -------------------------------------------------------------------------


@pytest.fixture
def stepped():
    sim = Simulation(small_scene())
    sim.step(20)
    sim.cut(5)
    return sim


AT, DOWN = [0.1, 1.0, 2.0], [0.0, 0.0, -1.0]
BAD_CALLS = [
    (lambda s: s.pick(AT, [0, 0, 0]), ValueError, "direction"),
    (lambda s: s.pick(AT, [0, math.nan, 1]), ValueError, "direction"),
    (lambda s: s.pick(AT, [math.inf, 0, 1]), ValueError, "direction"),
    (lambda s: s.pick(AT, [1e300, 0, 0]), ValueError, "direction"),  # inf in float32
    (lambda s: s.pick([math.nan, 0, 0], DOWN), ValueError, "origin"),
    (lambda s: s.pick([1e39, 0, 0], DOWN), ValueError, "origin"),
    (lambda s: s.pick(AT, [0, 1]), ValueError, "direction"),
    (lambda s: s.pick("here", DOWN), TypeError, "origin"),
    (lambda s: s.pick_triangle(AT, [0, 0, 0]), ValueError, "direction"),
    (lambda s: s.cut_ray(AT, [0, 0, 0]), ValueError, "direction"),
    (lambda s: s.cut_ray([math.inf, 0, 0], DOWN), ValueError, "origin"),
    (lambda s: s.cut_stroke([(AT, DOWN), (AT, [0, 0, 0])]), ValueError, "rays[1].direction"),
    (lambda s: s.cut_stroke([(AT, DOWN), (AT, DOWN, DOWN)]), ValueError, "rays[1]"),
    (lambda s: s.cut_stroke([(AT, DOWN), 3]), TypeError, "rays[1]"),
    (lambda s: s.cut_stroke(7), TypeError, "rays"),
    (lambda s: s.cut_stroke(np.zeros((4, 2, 3))), ValueError, "rays[0].direction"),
    (lambda s: s.grab(48), IndexError, "index 48"),
    (lambda s: s.grab(-1), IndexError, "index -1"),
    (lambda s: s.grab(2**70), IndexError, "index"),
    (lambda s: s.grab(1.5), TypeError, "index"),
    (lambda s: s.grab(5), ValueError, "cut"),
    (lambda s: s.drag_to([0, math.nan, 0]), ValueError, "target"),
    (lambda s: setattr(s, "pick_radius", 0.0), ValueError, "radius"),
    (lambda s: setattr(s, "pick_radius", math.nan), ValueError, "radius"),
]


@pytest.mark.parametrize(("action", "exception", "text"), BAD_CALLS)
def test_bad_calls_raise_and_leave_the_simulation_unchanged(stepped, action, exception, text):
    def snapshot(s):
        return (
            state_digest(s),
            s.topology_version,
            s.pinned.tobytes(),
            s.alive.tobytes(),
            s.grabbed(),
            s.pick_radius,
        )

    before = snapshot(stepped)
    with pytest.raises(exception) as info:
        action(stepped)
    assert isinstance(info.value, rustcloth.RustclothError)
    assert text in str(info.value), str(info.value)
    assert snapshot(stepped) == before


def test_cutting_twice_is_a_no_op(stepped):
    version = stepped.topology_version
    stepped.cut(5)
    assert stepped.topology_version == version
