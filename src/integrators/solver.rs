//! Settings, statistics and assembly helpers shared by the integrators that solve a system each
//! step (`implicit_euler`, `projective_dynamics`).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::grid::SpringKind;
use crate::linear::stencil::slot_of;

/// The preconditioner of `implicit_euler`'s conjugate gradient.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", try_from = "String")]
pub enum Preconditioner {
    /// The inverse of the matrix's diagonal: cheapest per iteration, most iterations.
    Jacobi,
    /// The inverse of each particle's 3 x 3 diagonal block: a spring couples a particle's
    /// three components, which the scalar diagonal ignores, so fewer iterations than Jacobi
    /// for almost the same cost.
    BlockJacobi,
    /// One geometric multigrid V-cycle (`src/linear/multigrid/`): iteration counts that barely
    /// grow with stiffness or resolution, for a setup of about five matrix-vector products and
    /// an apply of about four. The default.
    Multigrid,
}

impl Preconditioner {
    pub const ALL: [Preconditioner; 3] = [
        Preconditioner::Jacobi,
        Preconditioner::BlockJacobi,
        Preconditioner::Multigrid,
    ];

    /// Its name in scenes and `solver_stats()`.
    pub fn name(self) -> &'static str {
        match self {
            Preconditioner::Jacobi => "jacobi",
            Preconditioner::BlockJacobi => "block_jacobi",
            Preconditioner::Multigrid => "multigrid",
        }
    }

    /// Every name, in [`Preconditioner::ALL`] order.
    pub fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|k| k.name()).collect()
    }

    /// The preconditioner called `name`.
    pub fn by_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                Error::value(
                    "preconditioner",
                    format!(
                        "unknown preconditioner {name:?}; valid ones are {:?}",
                        Self::names()
                    ),
                )
            })
    }
}

impl std::fmt::Display for Preconditioner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Read from a name only (serde would also take a one-key table for an enum).
impl TryFrom<String> for Preconditioner {
    type Error = String;

    fn try_from(name: String) -> std::result::Result<Self, String> {
        Preconditioner::by_name(&name).map_err(|e| match e {
            Error::InvalidValue { message, .. } => message,
            other => other.to_string(),
        })
    }
}

/// Settings of the implicit solvers; each reads its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// `implicit_euler`: relative residual `|r| / |b|` at which CG stops. Default 1e-4: well
    /// below the step's own linearisation error; float32 arithmetic stalls a little below 1e-6.
    pub tolerance: f32,
    /// `implicit_euler`: most CG iterations per step. Default 200. A solve that hits the cap is
    /// used (it is still a descent step) but counted as not converged.
    pub max_iterations: u32,
    /// `implicit_euler`: the CG preconditioner. Default multigrid.
    pub preconditioner: Preconditioner,
    /// `projective_dynamics`: local-global iterations per substep, at most. Default 20.
    pub pd_iterations: u32,
    /// `projective_dynamics`: relative gradient norm `|g_k| / |g_0|` at which the iterations
    /// stop early and below which a substep counts as converged. Default 0: always run
    /// `pd_iterations`, the way projective dynamics is used, and count nothing as unconverged.
    pub pd_tolerance: f32,
    /// `projective_dynamics`: Chebyshev's spectral-radius estimate `rho` (Wang 2015), in
    /// `[0, 1)`. Default 0.8, where stiff cloth converges fastest at the 10 to 50 iterations a
    /// substep runs; 0 turns the acceleration off. Larger values make the first iterates
    /// overshoot (the solver restarts the acceleration when the gradient grows).
    pub pd_chebyshev_rho: f32,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-4,
            max_iterations: 200,
            preconditioner: Preconditioner::Multigrid,
            pd_iterations: 20,
            pd_tolerance: 0.0,
            pd_chebyshev_rho: 0.8,
        }
    }
}

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
