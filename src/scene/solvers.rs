//! The solvers a scene chooses: the integrator ([`IntegratorKind`], with each one's name and
//! stability limit) and the implicit solvers' settings. The schemes themselves are in
//! `src/integrators/`, which builds them from these.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The time integrators a scene can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", try_from = "String")]
pub enum IntegratorKind {
    ExplicitEuler,
    SymplecticEuler,
    Verlet,
    Rk4,
    ImplicitEuler,
    ProjectiveDynamics,
}

impl IntegratorKind {
    pub const ALL: [IntegratorKind; 6] = [
        IntegratorKind::ExplicitEuler,
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Verlet,
        IntegratorKind::Rk4,
        IntegratorKind::ImplicitEuler,
        IntegratorKind::ProjectiveDynamics,
    ];

    /// Its name in scenes, `effects` and `profile()`.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::ExplicitEuler => "explicit_euler",
            IntegratorKind::SymplecticEuler => "symplectic_euler",
            IntegratorKind::Verlet => "verlet",
            IntegratorKind::Rk4 => "rk4",
            IntegratorKind::ImplicitEuler => "implicit_euler",
            IntegratorKind::ProjectiveDynamics => "projective_dynamics",
        }
    }

    /// Every name, in [`IntegratorKind::ALL`] order.
    pub fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|k| k.name()).collect()
    }

    /// The integrator called `name`; the error names `parameter`.
    pub fn by_name(name: &str, parameter: &str) -> Result<IntegratorKind> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                Error::value(
                    parameter,
                    format!(
                        "unknown integrator {name:?}; valid ones are {:?}",
                        Self::names()
                    ),
                )
            })
    }

    /// Whether it holds the contacts a step is predicted to make inside its solve
    /// (`crate::integrators::StepContext::contacts`): the implicit solvers, whose display-frame
    /// steps are long enough that projecting their result out of a collider afterwards crushes
    /// springs.
    pub fn holds_contacts(self) -> bool {
        matches!(
            self,
            IntegratorKind::ImplicitEuler | IntegratorKind::ProjectiveDynamics
        )
    }

    /// The largest substep `h` (s) at which this integrator stays stable on a mode of angular
    /// frequency `omega` (rad/s, `omega2 = omega^2`) damped at a rate between `gamma_lo` and
    /// `gamma_hi` (1/s), or None when any is (the implicit solvers). For the damped oscillator
    /// `x'' = -omega^2 x - gamma x'`:
    ///
    /// - symplectic Euler and Verlet need `h^2 omega^2 + 2 h gamma < 4` (Jury's test on the step
    ///   matrix; `h omega < 2` undamped);
    /// - RK4 needs `h |lambda| < 2 sqrt 2` where the mode oscillates (`lambda` the mode's
    ///   eigenvalue, `|lambda| = omega`) and `< 2.785` on the real axis where it is overdamped;
    /// - explicit Euler grows every undamped mode: it needs `h < gamma / omega^2` (with the
    ///   smaller `gamma`, the safe side) and, overdamped, `h |lambda| < 2`.
    pub fn stable_substep(self, omega2: f64, gamma_hi: f64, gamma_lo: f64) -> Option<f64> {
        let omega = omega2.sqrt();
        // The magnitude of the mode's fastest eigenvalue when overdamped (real), else None.
        let overdamped = |gamma: f64| {
            let d = gamma * gamma / 4.0 - omega2;
            (d > 0.0).then(|| gamma / 2.0 + d.sqrt())
        };
        match self {
            // Both solve backward Euler implicitly; neither has a step limit.
            IntegratorKind::ImplicitEuler | IntegratorKind::ProjectiveDynamics => None,
            IntegratorKind::Rk4 => Some(match overdamped(gamma_hi) {
                Some(lambda) => 2.785 / lambda,
                None => 2.0 * std::f64::consts::SQRT_2 / omega,
            }),
            IntegratorKind::ExplicitEuler => {
                let growth = gamma_lo / omega2;
                Some(overdamped(gamma_hi).map_or(growth, |lambda| growth.min(2.0 / lambda)))
            }
            IntegratorKind::SymplecticEuler | IntegratorKind::Verlet => {
                Some((-gamma_hi + (gamma_hi * gamma_hi + 4.0 * omega2).sqrt()) / omega2)
            }
        }
    }
}

/// Read from a name only: serde would also take a one-key table for an enum.
impl TryFrom<String> for IntegratorKind {
    type Error = String;

    fn try_from(name: String) -> std::result::Result<Self, String> {
        IntegratorKind::by_name(&name, "integrator").map_err(|e| match e {
            Error::InvalidValue { message, .. } => message,
            other => other.to_string(),
        })
    }
}

impl std::fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

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
