//! Settings, statistics and assembly helpers shared by the integrators that solve a system each
//! step (`implicit_euler`, `projective_dynamics`).

use serde::Serialize;

use crate::grid::SpringKind;
use crate::linear::stencil::slot_of;
pub use crate::scene::{Preconditioner, SolverSettings};

/// What the solver did, accumulated since the integrator was created. For `implicit_euler` an
/// iteration is a CG iteration and the residual is `|r| / |b|` of the linear system; for
/// `projective_dynamics` an iteration is a local-global iteration and the residual is the
/// gradient norm of the step's incremental potential relative to its value at the first
/// iterate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SolverStats {
    pub solves: u64,
    pub iterations: u64,
    pub last_iterations: u32,
    /// The residual at the end of the last solve.
    pub last_residual: f32,
    /// Solves that stopped at the iteration cap above the tolerance.
    pub not_converged: u64,
    /// The largest final residual among those.
    pub worst_residual: f32,
    /// The most iterations any one solve took.
    pub most_iterations: u32,
    /// Matrix factorisations (`projective_dynamics`: each change of pins, cuts, masses or step
    /// refactors its global matrix); 0 for `implicit_euler`, which factors nothing.
    pub factorizations: u64,
    /// Wall time in s spent setting up solves: `implicit_euler`'s assembly of the matrix and
    /// build of the preconditioner, `projective_dynamics`'s factorisations. Inside the
    /// integrator's `profile()` time.
    pub setup_seconds: f64,
    /// Wall time in s spent iterating (CG iterations; local-global iterations).
    pub solve_seconds: f64,
}

impl SolverStats {
    /// Books one solve of `iterations` that ended at `residual` against `tolerance` (0: a fixed
    /// iteration count, never "not converged"; NaN counts as not converged).
    pub fn record(&mut self, iterations: u32, residual: f64, tolerance: f64) {
        self.solves += 1;
        self.iterations += iterations as u64;
        self.last_iterations = iterations;
        self.last_residual = residual as f32;
        self.most_iterations = self.most_iterations.max(iterations);
        if tolerance > 0.0 && (residual.is_nan() || residual > tolerance) {
            self.not_converged += 1;
            self.worst_residual = self.worst_residual.max(residual as f32);
        }
    }
}

/// The matrix slot of a spring kind's block `A[anchor, partner]`: every kind steps to an
/// upper-half neighbour, so its block is stored, not its transpose.
pub(super) fn kind_slot(kind: SpringKind) -> usize {
    let (di, dj) = kind.step();
    slot_of(di as i32, dj as i32)
        .filter(|&(_, transposed)| !transposed)
        .expect("every spring kind is an upper-half offset")
        .0
}

/// `x` where `live`, else zero: a select, so that an infinite or NaN `x` computed from a dead
/// spring (a cut particle far away) cannot leak through as `0 * inf`.
#[inline(always)]
pub(super) fn live_or_zero(live: bool, x: f32) -> f32 {
    if live {
        x
    } else {
        0.0
    }
}
