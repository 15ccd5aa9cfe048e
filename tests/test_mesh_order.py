"""A mesh cloth whose vertices are numbered in a scattered order (as a file or a Delaunay
triangulation of dart-thrown points may number them) lists its springs and grows its multigrid
aggregates in a local order inside the solver; everything the user sees keeps the file's
numbering: positions, pins by index, export."""

from __future__ import annotations

import numpy as np
import pytest
import rustcloth
from test_mesh_cloth import jittered_square

N = 20


def numbered_at_random(n: int = N) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``jittered_square(n)`` with its vertices renumbered at random: the shuffled vertices and
    triangles, ``old`` (the row-order vertex numbered ``k``) and ``new`` (its inverse)."""
    vertices, triangles = jittered_square(n)
    old = np.random.default_rng(5).permutation(n * n)
    new = np.empty_like(old)
    new[old] = np.arange(n * n)
    return vertices[old], new[triangles], old, new


def hang(vertices: np.ndarray, triangles: np.ndarray, pins: list[int], integrator: str,
         steps: int) -> rustcloth.Simulation:
    dt = 1 / 60 if integrator == "implicit_euler" else 2e-4
    scene = rustcloth.Scene(integrator=integrator, dt=dt).with_cloth_mesh(
        vertices, triangles, pins=pins, stretch=600.0, bend=80.0
    )
    sim = rustcloth.Simulation(scene)
    sim.step(steps)
    return sim


@pytest.mark.parametrize(("integrator", "steps", "tolerance"),
                         [("symplectic_euler", 300, 1e-5), ("implicit_euler", 20, 1e-4)])
def test_a_mesh_numbered_at_random_moves_as_the_same_mesh_in_row_order(
    integrator: str, steps: int, tolerance: float
) -> None:
    # The same cloth twice, numbered row by row and at random: the solver's spring list and
    # aggregates differ, so the sums differ in their order (and implicit Euler's CG stops at
    # its tolerance from a different preconditioner), but the motion is the same.
    vertices, triangles = jittered_square(N)
    shuffled, shuffled_triangles, _, new = numbered_at_random()
    pins = [N * N - N, N * N - 1]
    ordered = hang(vertices, triangles, pins, integrator, steps)
    scattered = hang(shuffled, shuffled_triangles, [int(new[v]) for v in pins], integrator, steps)
    want, got = ordered.positions, scattered.positions[new]
    assert np.isfinite(got).all() and (np.abs(got) < 3).all()
    assert want[:, 1].min() < 0.5 - 0.01  # it fell and hangs
    assert np.abs(got - want).max() < tolerance, np.abs(got - want).max()


def test_pins_by_index_hold_the_same_vertices_on_a_mesh_numbered_at_random() -> None:
    shuffled, triangles, old, new = numbered_at_random()
    pins = [int(new[N * N - N]), int(new[N * N - 1]), int(new[N // 2])]
    sim = hang(shuffled, triangles, pins, "symplectic_euler", 200)
    assert set(np.flatnonzero(sim.pinned)) == set(pins)
    np.testing.assert_array_equal(sim.positions[pins], shuffled[pins].astype(np.float32))
    free = np.setdiff1d(np.arange(N * N), pins)
    assert (sim.positions[free, 1] < shuffled[free, 1] - 1e-4).all()


def test_export_keeps_the_files_vertex_order_on_a_mesh_numbered_at_random(tmp_path) -> None:
    trimesh = pytest.importorskip("trimesh")
    shuffled, triangles, _, new = numbered_at_random()
    sim = hang(shuffled, triangles, [int(new[N * N - N]), int(new[N * N - 1])],
               "symplectic_euler", 50)
    np.testing.assert_array_equal(sim.to_mesh().triangles, triangles)
    sim.export(tmp_path / "out.obj")
    back = trimesh.load(tmp_path / "out.obj", force="mesh", process=False, maintain_order=True)
    np.testing.assert_array_equal(np.asarray(back.faces), triangles)
    assert np.allclose(np.asarray(back.vertices), sim.positions, atol=1e-5)


def test_a_mesh_numbered_at_random_takes_about_the_iterations_of_row_order() -> None:
    # Greedy aggregation in a scattered numbering's order grew ragged aggregates: a third
    # more CG iterations a solve than in row order on the stiff 16k drape.
    def iterations(vertices: np.ndarray, triangles: np.ndarray, pins: list[int]) -> float:
        scene = rustcloth.Scene(integrator="implicit_euler", dt=1 / 60,
                                preconditioner="multigrid").with_cloth_mesh(
            vertices, triangles, pins=pins, stretch=1500.0, bend=200.0, density=0.5)
        sim = rustcloth.Simulation(scene)
        sim.step(10)
        stats = sim.solver_stats()
        return stats["iterations"] / stats["solves"]

    n = 40
    vertices, triangles = jittered_square(n)
    shuffled, shuffled_triangles, _, new = numbered_at_random(n)
    pins = [n * n - n, n * n - 1]
    ordered = iterations(vertices, triangles, pins)
    scattered = iterations(shuffled, shuffled_triangles, [int(new[v]) for v in pins])
    assert scattered <= 1.1 * ordered, (scattered, ordered)
