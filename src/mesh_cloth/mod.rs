//! A cloth from any triangle mesh, beside the grid.
//!
//! # How it sits beside the grid
//!
//! The grid cloth stores its springs implicitly: the 12-neighbour stencil, one slot per kind
//! at each anchor particle ([`crate::grid`], [`crate::springs`]), which every fast pass walks
//! as runs of consecutive indices. A mesh has no stencil, so a mesh cloth keeps its springs as
//! an explicit edge list, [`EdgeSprings`]: for each spring its two ends, rest length,
//! stiffness and damping, and its [`EdgeKind`]. The model's topology is
//! [`crate::model::Topology`]: `Grid` (the fast path, untouched) or `Mesh` (this module). The
//! particle passes (integration, pins, colliders, the watchdog's finite check, snapshots) never
//! looked at the stencil and run unchanged on a mesh cloth, whose particles are laid out as a
//! one-row grid (`nx` = vertex count, `ny` = 1) with every stencil slot empty; the springs of
//! [`EdgeSprings`] are added to the force after the grid's sweep ([`forces`]), and the surface
//! passes (normals, energy, strain, the drawn mesh, self-collision, wind, picking) read the
//! mesh's triangles. The implicit solvers assemble their matrices from the spring list
//! (`src/integrators/implicit_mesh.rs`, `src/integrators/projective_mesh.rs`) and strain
//! limiting walks it (`src/strain_limit/mesh.rs`). Cuts and tears sever springs of the list and
//! the triangles on them stop being drawn ([`topology`]).
//!
//! # Springs
//!
//! * *Stretch*: one spring on every edge of the mesh.
//! * *Bend*: one spring across every interior edge, between the two vertices opposite it (the
//!   grid's bending springs span two cells the same way). Like the grid's, such a spring
//!   resists a fold only to second order in the fold angle, so a finer mesh is softer in
//!   bending; `bending = "isometric"` gives this family's stiffness to the quadratic bending
//!   energy of a flat sheet instead ([`bending`]), which holds a curvature alike at every
//!   resolution.
//!
//! The force law is the grid's, `f_a = k (l - L) u + c ((v_b - v_a) . u) u`, `f_b = -f_a`.
//!
//! # Material in physical units
//!
//! A triangle `t` of area `A_t` gives each of its three edges a third of its area; `A_e` is the
//! sum over the (one or two) triangles of edge `e`. A spring of rest length `L` representing
//! area `A_e` gets
//!
//! ```text
//! k = Y A_e / L^2,        c = D A_e / L^2
//! ```
//!
//! with `Y` the stretch modulus (N/m) and `D` the damping modulus (N s/m). Under a uniform
//! strain `e` in every direction each spring is stretched by `e L`, so the mesh stores
//!
//! ```text
//! sum_e k (e L)^2 / 2 = Y e^2 / 2 sum_e A_e = Y e^2 A / 2
//! ```
//!
//! whatever the number, size or shape of its triangles: the energy density `Y e^2 / 2` is a
//! property of the material, not of the mesh (the same holds for the dissipation `D r^2` at a
//! strain rate `r`). Under a uniaxial strain an edge at angle `theta` stretches by
//! `e cos^2 theta`, so the response along a direction depends on how the edges' areas are
//! spread over directions (`Y <cos^4>`, 3/8 Y for an isotropic spread); an irregular mesh is
//! close to isotropic at every resolution, which is what keeps coarse and fine alike. The bend
//! springs get `k = B A_h / L^2` with `A_h` a third of the two triangles' areas and `B` the
//! bend modulus, by the same argument.
//!
//! The grid's springs already scale this way (a structural spring `k` stores `k e^2` per
//! m^2 at any spacing), so the grid cloth with `k_structural`, `k_shear` has the isotropic
//! modulus `Y = 2 (k_structural + 2 k_shear)`.
//!
//! Mass is lumped: vertex `v` gets `rho sum_t A_t / 3` over its triangles, `rho` the areal
//! density (kg/m^2), so the total is `rho A` exactly.
//!
//! Newton's `add_cloth_mesh` takes the same shape of input (vertices, triangle indices,
//! density, stiffness per element) with a triangle FEM element per face and a dihedral element
//! per interior edge; Blender's cloth builds springs on edges (structural), across faces
//! (shear, on quads) and across edges (bending), with stiffness it scales by rest length. The
//! edge springs here are the smallest model that runs on every explicit integrator already in
//! the solver, with one set of equations for every pass.

/// Isometric bending's elements, compiled with the scene (`src/scene/bending.rs`) as the
/// triangle membrane's rest state is.
pub mod bending {
    pub use crate::scene::IsometricBending;
}
pub mod forces;
pub mod graded;
pub mod membrane;
pub mod packed;
pub mod topology;

pub use graded::{graded_square, Grading};
pub use topology::MeshTopology;

// The compiled mesh (its checks, masses and springs) lives with the scene that validates it,
// so that the scene's checks and stability estimate need nothing from here.
pub use crate::scene::{EdgeKind, EdgeSprings, MeshCloth};

/// A seeded stream of uniform numbers in `[-1, 1]` (splitmix64: no dependency).
fn uniform_stream(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z ^ (z >> 31)) as f64 / u64::MAX as f64 * 2.0 - 1.0
    }
}

/// An irregular triangulation of a `size` x `size` square in the plane through `center` along
/// `+x` and `+y` (a hanging sheet): `n` x `n` points on a grid, the interior ones moved by up
/// to `jitter` grid spacings in x and y (boundary points slide along their edge only, corners
/// stay), each quad split along its shorter diagonal (the Delaunay choice for the quad), wound
/// counter-clockwise seen from `+z`. The same `seed` gives the same mesh. For tests, benchmarks
/// and scenes that need a mesh with no grid structure in its springs.
pub fn jittered_square(
    n: usize,
    size: f64,
    center: [f64; 3],
    jitter: f64,
    seed: u64,
) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    assert!(n >= 2, "a square needs at least 2 x 2 points");
    let mut uniform = uniform_stream(seed);
    let h = size / (n - 1) as f64;
    let mut vertices = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (dx, dy) = (uniform() * jitter * h, uniform() * jitter * h);
            let inner = |k: usize| k > 0 && k < n - 1;
            let x = i as f64 * h - size / 2.0 + if inner(i) { dx } else { 0.0 };
            let y = j as f64 * h - size / 2.0 + if inner(j) { dy } else { 0.0 };
            vertices.push([center[0] + x, center[1] + y, center[2]]);
        }
    }
    let dist2 = |a: usize, b: usize| {
        let (p, q) = (vertices[a], vertices[b]);
        (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>()
    };
    let mut triangles = Vec::with_capacity(2 * (n - 1) * (n - 1));
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            let (b, c) = (a + 1, a + n);
            let d = c + 1;
            let tris = if dist2(a, d) <= dist2(b, c) {
                [[a, b, d], [a, d, c]]
            } else {
                [[a, b, c], [b, d, c]]
            };
            triangles.extend(tris.map(|t| t.map(|k| k as i64)));
        }
    }
    (vertices, triangles)
}
