//! Linear algebra for the implicit solvers, independent of [`crate::Simulation`]: symmetric
//! 3 x 3 block matrices on the cloth's grid stencil, the conjugate gradient that solves them, the
//! preconditioners that act on them (block Jacobi, geometric multigrid), a sparse Cholesky
//! factorisation with a nested-dissection ordering for grids, and the fixed-chunk reductions
//! that keep every result bitwise the same for any number of threads.
//!
//! The mesh cloth's matrices are a [`SpringMatrix`] (3 x 3 blocks, for implicit Euler,
//! preconditioned by the smoothed-aggregation multigrid [`Amg`]) and a [`SparseCholesky`]
//! ordered by [`dissect_points`] (for projective dynamics).
//!
//! Everything else works on grids of `nx` x `ny` nodes indexed `p = j * nx + i`, the particle
//! numbering of [`crate::grid::Grid`], and on per-node 3-vectors stored as [`crate::soa::Vec3s`].

pub mod amg;
pub mod block_lanes;
pub mod cg;
pub mod cholesky;
pub mod dense;
pub mod multigrid;
pub mod reduce;
pub mod spring_matrix;
pub mod stencil;

pub use amg::Amg;
pub use cg::ConjugateGradient;
pub use cholesky::{dissect_points, ScalarStencil, SparseCholesky};
pub use multigrid::Multigrid;
pub use spring_matrix::SpringMatrix;
pub use stencil::{BlockStencil, Sym3, OFFSETS, SLOTS};
