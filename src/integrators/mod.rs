//! Time integrators: the running scheme with whatever it keeps between steps ([`Integrator`]),
//! built from the [`IntegratorKind`] a scene names (`src/scene/solvers.rs`, with each one's name
//! and stability limit); each scheme's update is in its own file.
//!
//! An integrator reads the state at the start of the step (`current`) and writes the state at
//! its end into a second buffer (`next`). The stepper swaps the two only when the step came out
//! finite, so rolling back a diverged step costs nothing.

mod contact_filter;
mod explicit_euler;
mod implicit_euler;
mod implicit_mesh;
mod projective_dynamics;
mod projective_mesh;
mod rk4;
mod self_contact;
pub mod solver;
mod symplectic_euler;
mod verlet;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use crate::scene::IntegratorKind;
pub use implicit_euler::ImplicitEuler;
pub use projective_dynamics::ProjectiveDynamics;
pub use rk4::Rk4;
pub use self_contact::SelfPairs;
pub use solver::{Preconditioner, SolverSettings, SolverStats};
pub use verlet::Verlet;

use crate::collisions::{Impulses, PredictedContacts};
use crate::forces::{ForceModel, StateRef};
use crate::grid::Grid;
use crate::particles::Particles;
use crate::profile::Profile;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::Springs;
use crate::state::Kinematics;

/// Everything a step reads and writes.
pub struct StepContext<'a> {
    pub grid: Grid,
    pub current: &'a Kinematics,
    pub next: &'a mut Kinematics,
    pub particles: &'a Particles,
    pub springs: &'a Springs,
    /// A mesh cloth's springs; None on the grid.
    pub mesh: Option<&'a crate::mesh_cloth::MeshCloth>,
    pub forces: &'a mut ForceModel,
    /// Scratch for the total force, one vector per particle.
    pub force: &'a mut Vec3s,
    /// Particles per parallel work item.
    pub chunk: usize,
    pub profile: &'a mut Profile,
    /// The contacts the substep is predicted to make, for a solver that holds them inside its
    /// solve ([`IntegratorKind::holds_contacts`]); `None` without colliders and for the others,
    /// whose contacts the collider passes handle after the fact.
    pub contacts: Option<&'a PredictedContacts>,
    /// The self-collision pairs ahead of the step, for implicit Euler to hold apart inside its
    /// solve (`self_contact.rs`); `None` without `[self_collision]`, with the term off, and
    /// for the other integrators.
    pub self_pairs: Option<SelfPairs<'a>>,
    /// Whether the caller corrects `contacts` from this step's result and steps again where
    /// they changed: implicit Euler may then stop a step holding self-contact pairs at its
    /// loose pair-finding solve, which shows where the step goes at about half the cost, and
    /// finish it ([`Integrator::finish_loose`]) only where the contacts stayed. The correction
    /// then judges a `dv` solved to the contact-finding tolerance (3e-3, `implicit_euler.rs`)
    /// instead of `cg_tolerance`.
    pub may_stop_loose: bool,
}

impl StepContext<'_> {
    /// Evaluates the total force at `state` into `self.force`.
    pub fn eval_forces_at(&mut self, state: &Kinematics) {
        let state = StateRef {
            grid: self.grid,
            pos: &state.pos,
            vel: &state.vel,
            mass: &self.particles.mass,
            springs: self.springs,
            mesh: self.mesh,
        };
        self.forces
            .evaluate(state, self.force, self.chunk, self.profile);
    }
}

/// The state an integrator carries between steps, beyond positions and velocities.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct History {
    /// Verlet: the velocities are backward differences (its start-up step is done).
    pub primed: bool,
}

/// A running integrator: its scheme and what it keeps from step to step.
pub enum Integrator {
    ExplicitEuler,
    SymplecticEuler,
    Verlet(Verlet),
    Rk4(Box<Rk4>),
    ImplicitEuler(Box<ImplicitEuler>),
    ProjectiveDynamics(Box<ProjectiveDynamics>),
}

impl Integrator {
    /// A fresh integrator of `kind`, with the implicit solvers' `solver` settings.
    pub fn new(kind: IntegratorKind, solver: SolverSettings) -> Integrator {
        match kind {
            IntegratorKind::ExplicitEuler => Integrator::ExplicitEuler,
            IntegratorKind::SymplecticEuler => Integrator::SymplecticEuler,
            IntegratorKind::Verlet => Integrator::Verlet(Verlet::default()),
            IntegratorKind::Rk4 => Integrator::Rk4(Box::default()),
            IntegratorKind::ImplicitEuler => {
                Integrator::ImplicitEuler(Box::new(ImplicitEuler::new(solver)))
            }
            IntegratorKind::ProjectiveDynamics => {
                Integrator::ProjectiveDynamics(Box::new(ProjectiveDynamics::new(solver)))
            }
        }
    }

    pub fn kind(&self) -> IntegratorKind {
        match self {
            Integrator::ExplicitEuler => IntegratorKind::ExplicitEuler,
            Integrator::SymplecticEuler => IntegratorKind::SymplecticEuler,
            Integrator::Verlet(_) => IntegratorKind::Verlet,
            Integrator::Rk4(_) => IntegratorKind::Rk4,
            Integrator::ImplicitEuler(_) => IntegratorKind::ImplicitEuler,
            Integrator::ProjectiveDynamics(_) => IntegratorKind::ProjectiveDynamics,
        }
    }

    /// Name in scenes, `effects` and `profile()`.
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// Writes into `ctx.next` the state one step `h` (s) after `ctx.current`. Particles with
    /// `inv_mass == 0` are copied unchanged. Returns whether every written value is finite.
    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        match self {
            Integrator::ExplicitEuler => explicit_euler::step(h, ctx),
            Integrator::SymplecticEuler => symplectic_euler::step(h, ctx),
            Integrator::Verlet(v) => v.step(h, ctx),
            Integrator::Rk4(r) => r.step(h, ctx),
            Integrator::ImplicitEuler(i) => i.step(h, ctx),
            Integrator::ProjectiveDynamics(p) => p.step(h, ctx),
        }
    }

    /// Whether the last [`Integrator::step`] stopped at its loose pair-finding solve
    /// ([`StepContext::may_stop_loose`]).
    pub fn stopped_loose(&self) -> bool {
        match self {
            Integrator::ImplicitEuler(i) => i.stopped_loose(),
            _ => false,
        }
    }

    /// Finishes a step that stopped at its loose pair-finding solve, writing the step's result
    /// into `ctx.next`; `ctx` carries the same state, contacts and pairs as that step. Returns
    /// whether every written value is finite.
    pub fn finish_loose(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        match self {
            Integrator::ImplicitEuler(i) => i.finish_loose(h, ctx),
            // Their steps are whole: `ctx.next` already holds the result.
            _ => true,
        }
    }

    /// Called when the state was changed from outside (new positions or velocities, a new
    /// step size): an integrator that keeps history must start afresh.
    pub fn reset_history(&mut self) {
        match self {
            Integrator::Verlet(v) => v.reset_history(),
            Integrator::ImplicitEuler(i) => i.restart(),
            _ => {}
        }
    }

    /// Called when a snapshot is taken: an integrator that reuses earlier solves' work, which
    /// a snapshot does not hold, starts afresh at the next step, as one restored from that
    /// snapshot does, so that both go on bitwise alike.
    pub fn restart_point(&self) {
        if let Integrator::ImplicitEuler(i) = self {
            i.restart();
        }
    }

    /// Called after a (sub)step's result became the state. History that a step builds (as
    /// Verlet's start-up) is committed here, never in [`Integrator::step`]: a step that is
    /// refused must leave the integrator as it was.
    pub fn accept(&mut self) {
        match self {
            Integrator::Verlet(v) => v.accept(),
            Integrator::ImplicitEuler(i) => i.accept(),
            _ => {}
        }
    }

    /// What the integrator carries from one step to the next, for a rollback to restore with
    /// the state it belongs to.
    pub fn history(&self) -> History {
        match self {
            Integrator::Verlet(v) => v.history(),
            _ => History::default(),
        }
    }

    /// Restores what [`Integrator::history`] returned.
    pub fn set_history(&mut self, history: History) {
        match self {
            Integrator::Verlet(v) => v.set_history(history),
            // The state goes back to where another run (or attempt) may also start from.
            Integrator::ImplicitEuler(i) => i.restart(),
            _ => {}
        }
    }

    /// Per particle, the impulses (N s) its predicted contact gave inside the last solve, for
    /// an integrator whose contacts are exact constraints (implicit Euler), which holds a
    /// sticking contact in all three directions; None for the others, whose contacts
    /// [`crate::collisions::PredictedContacts::correct`] judges by where the solve left the
    /// particle, and whose friction acts after the solve.
    pub fn contact_impulses(&self) -> Option<Impulses<'_>> {
        match self {
            Integrator::ImplicitEuler(i) => Some(i.contact_impulses()),
            _ => None,
        }
    }

    /// Linear-solver statistics, for integrators that solve a system each step.
    pub fn solver_stats(&self) -> Option<SolverStats> {
        match self {
            Integrator::ImplicitEuler(i) => Some(i.solver_stats()),
            Integrator::ProjectiveDynamics(p) => Some(p.solver_stats()),
            _ => None,
        }
    }
}

/// One chunk of the per-particle update: the particles `range`, their start state and force,
/// and the slices of `next` to write.
pub struct UpdateChunk<'a> {
    pub range: std::ops::Range<usize>,
    pub pos: Vec3SliceMut<'a>,
    pub vel: Vec3SliceMut<'a>,
}

/// Watches the values an update loop writes for a non-finite one: an OR over "all exponent
/// bits set" (infinity or NaN). Integer OR is associative, so the loop still vectorises (a float
/// sum would serialise it), and the check costs two integer operations per value in a loop that
/// is streaming those values anyway, instead of a second pass over memory.
#[derive(Clone, Copy, Debug, Default)]
pub struct FiniteCheck(u32);

impl FiniteCheck {
    #[inline(always)]
    pub fn watch(&mut self, x: f32) {
        // Exponent bits all set: x.abs() >= infinity as integers, branch-free.
        self.0 |= ((x.to_bits() & 0x7fff_ffff) >= 0x7f80_0000) as u32;
    }

    pub fn all_finite(self) -> bool {
        self.0 == 0
    }
}

/// All ones for a particle that integration must not move (`inv_mass == 0`), else zero.
#[inline(always)]
pub fn hold_mask(inv_mass: f32) -> u32 {
    ((inv_mass == 0.0) as u32).wrapping_neg()
}

/// `old` where `mask` is all ones, `new` where it is zero, bit for bit.
#[inline(always)]
pub fn select_bits(mask: u32, old: f32, new: f32) -> f32 {
    f32::from_bits((old.to_bits() & mask) | (new.to_bits() & !mask))
}

/// Runs `update` over every chunk of `next` in parallel and reports whether everything it
/// wrote is finite, as the [`FiniteCheck`] each chunk returns says.
pub fn par_update(
    next: &mut Kinematics,
    chunk: usize,
    update: impl Fn(UpdateChunk) -> FiniteCheck + Sync + Send,
) -> bool {
    let Kinematics { pos, vel } = next;
    pos.par_chunks_mut(chunk)
        .zip(vel.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (pos, vel))| {
            let range = c * chunk..c * chunk + pos.len();
            update(UpdateChunk { range, pos, vel })
        })
        .all(|check| check.all_finite())
}

/// The update shared by the one-stage explicit schemes: with `dv = h f / m` from the force at the
/// start of the step, `rule(x, v, dv)` gives the new `(x, v)` of one component of one particle.
/// Particles that must not move keep their state bitwise.
pub fn one_stage_update(
    ctx: &mut StepContext,
    h: f32,
    rule: impl Fn(f32, f32, f32) -> (f32, f32) + Sync + Send + Copy,
) -> bool {
    ctx.eval_forces_at(ctx.current);
    let (cur, force, inv_mass) = (ctx.current, &*ctx.force, &ctx.particles.inv_mass);
    par_update(ctx.next, ctx.chunk, |out| {
        let r = out.range.clone();
        let w = &inv_mass[r.clone()];
        let mut check = FiniteCheck::default();
        for (c, (dst_x, dst_v)) in [
            (out.pos.x, out.vel.x),
            (out.pos.y, out.vel.y),
            (out.pos.z, out.vel.z),
        ]
        .into_iter()
        .enumerate()
        {
            let (x, v, f) = (
                cur.pos.component(c, &r),
                cur.vel.component(c, &r),
                force.component(c, &r),
            );
            check.0 |= crate::simd::dispatch!(update_component(rule, h, x, v, f, w, dst_x, dst_v));
        }
        check
    })
}

/// One component of [`one_stage_update`] over a chunk; returns the [`FiniteCheck`] bits.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn update_component(
    rule: impl Fn(f32, f32, f32) -> (f32, f32),
    h: f32,
    x: &[f32],
    v: &[f32],
    f: &[f32],
    w: &[f32],
    dst_x: &mut [f32],
    dst_v: &mut [f32],
) -> u32 {
    let n = w.len();
    let (x, v, f, dst_x, dst_v) = (&x[..n], &v[..n], &f[..n], &mut dst_x[..n], &mut dst_v[..n]);
    let mut check = FiniteCheck::default();
    for i in 0..n {
        let (x_new, v_new) = rule(x[i], v[i], h * f[i] * w[i]);
        // Held particles keep their bits: a blend of bit patterns rather than a branch, so
        // that the loop vectorises.
        let keep = hold_mask(w[i]);
        let (x_out, v_out) = (
            select_bits(keep, x[i], x_new),
            select_bits(keep, v[i], v_new),
        );
        dst_x[i] = x_out;
        dst_v[i] = v_out;
        check.watch(x_out);
        check.watch(v_out);
    }
    check.0
}

/// Like [`par_update`] over two state buffers at once, chunk by chunk.
pub fn par_update2(
    a: &mut Kinematics,
    b: &mut Kinematics,
    chunk: usize,
    update: impl Fn(std::ops::Range<usize>, UpdateChunk, UpdateChunk) + Sync + Send,
) {
    let (Kinematics { pos: ap, vel: av }, Kinematics { pos: bp, vel: bv }) = (a, b);
    ap.par_chunks_mut(chunk)
        .zip(av.par_chunks_mut(chunk))
        .zip(bp.par_chunks_mut(chunk).zip(bv.par_chunks_mut(chunk)))
        .enumerate()
        .for_each(|(c, ((ap, av), (bp, bv)))| {
            let range = c * chunk..c * chunk + ap.len();
            let a = UpdateChunk {
                range: range.clone(),
                pos: ap,
                vel: av,
            };
            let b = UpdateChunk {
                range: range.clone(),
                pos: bp,
                vel: bv,
            };
            update(range, a, b)
        });
}
