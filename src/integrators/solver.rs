//! Settings, statistics and assembly helpers shared by the integrators that solve a system each
//! step (`implicit_euler`, `projective_dynamics`).

use glam::Vec3;
use serde::Serialize;

use super::StepContext;

use crate::grid::SpringKind;
use crate::linear::stencil::slot_of;
use crate::scene::{IntegratorKind, Scene};
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
    /// Solves holding contacts that gained energy while nothing did work on the cloth, run
    /// again in halves (a half that gains too is counted again), since the simulation was
    /// built. Kept by the stepper, not the integrator.
    pub halved: u64,
    /// `implicit_euler` with `self_collision.solve_stiffness`: self-collision pairs held apart
    /// inside its solves, summed over solves.
    pub self_pairs: u64,
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

    /// What to tell a user once some solve of `scene`'s integrator stopped at its cap above
    /// its tolerance, and what to change; None while every solve converged.
    pub fn not_converged_message(&self, scene: &Scene) -> Option<String> {
        if self.not_converged == 0 {
            return None;
        }
        let (what, cap, tolerance, remedy) = match scene.integrator {
            IntegratorKind::ProjectiveDynamics => (
                "the local-global iterations stopped at pd_iterations",
                scene.pd_iterations,
                ("relative gradient", "pd_tolerance", scene.pd_tolerance),
                "the last iterate. Raise pd_iterations, loosen pd_tolerance",
            ),
            _ => (
                "the conjugate gradient stopped at cg_max_iterations",
                scene.cg_max_iterations,
                ("relative residual", "cg_tolerance", scene.cg_tolerance),
                "the partial solution. Raise cg_max_iterations, loosen cg_tolerance",
            ),
        };
        Some(format!(
            "{}: {what} = {cap} with {} up to {:.2e} > {} = {:.0e} ({} of {} solves so far); \
             the step was taken with {remedy} or reduce dt. profile() counts these.",
            scene.integrator,
            tolerance.0,
            self.worst_residual,
            tolerance.1,
            tolerance.2,
            self.not_converged,
            self.solves,
        ))
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

/// How much stiffer than its own inertia (`m / h^2`) the weight `w_c` holding a contact is.
/// The predicted penetration left after a converged solve is about `1 / (1 + CONTACT_WEIGHT)`
/// of the free motion's, which the collider pass after the step removes. Not larger: the weight
/// is isotropic in `Q` while the contact pushes only along its normal, so a particle in contact
/// slides along its plane within the iterations as if `w_c` times heavier. At 1000 a cloth
/// draped over a sphere at 0.5 ms substeps gained up to 0.1 J (of 2.7 J) over its running
/// minimum; at 300, 0.01 J; at 100 and below nothing. Much softer (30) lets the cloth that
/// lands on a small ball at 1/60 s sink in and swing off it.
pub(super) const CONTACT_WEIGHT: f32 = 100.0;

/// `w_c` of a particle of mass `m` at step `h`.
pub(super) fn contact_weight(m: f32, h: f32) -> f32 {
    CONTACT_WEIGHT * m / (h * h)
}

/// Whether free particle `p` is in a predicted contact this step.
pub(super) fn in_contact(ctx: &StepContext, p: usize) -> bool {
    ctx.contacts
        .is_some_and(|c| c.count > 0 && c.normal.get(p) != Vec3::ZERO)
        && ctx.particles.inv_mass[p] > 0.0
}

/// How far a particle at `x_n + dx` is behind the plane `n . x = offset` of its predicted
/// contact (negative ahead of it). A particle that starts behind the plane (inside a collider)
/// is held where it is along `n`, not pulled onto the plane within the step: that would turn the
/// depth into speed; the collider pass after the step puts it out without velocity.
#[inline(always)]
pub(super) fn depth(n: Vec3, offset: f32, xn: Vec3, dx: Vec3) -> f32 {
    let ahead = (n.dot(xn) - offset).max(0.0);
    -ahead - n.dot(dx)
}

/// How much stiffer than its own inertia (`m / h^2`) implicit Euler makes a held particle along
/// its contact normal in the matrix it builds its preconditioner on (`k n n^T`, `k` this times
/// `m`, on the particle's diagonal block). The contact itself is exact (the conjugate gradient
/// is filtered, `contact_filter.rs`), and the filter removes this term from the operator, so it
/// only shapes the preconditioner, which then treats the particle as nearly fixed along `n`, as
/// the filtered system does.
pub(super) const CONTACT_STIFFNESS: f32 = 1000.0;
