//! Time integrators. Each advances the state by one (sub)step `h` through the same force model;
//! adding one means adding a file here and a line in [`by_name`].
//!
//! An integrator reads the state at the start of the step (`current`) and writes the state at its
//! end into a second buffer (`next`). The simulation swaps the two only when the step came out
//! finite, so rolling back a diverged step costs nothing.

mod explicit_euler;
mod implicit_euler;
mod rk4;
mod symplectic_euler;
mod verlet;

use rayon::prelude::*;

pub use explicit_euler::ExplicitEuler;
pub use implicit_euler::{ImplicitEuler, SolverSettings, SolverStats};
pub use rk4::Rk4;
pub use symplectic_euler::SymplecticEuler;
pub use verlet::Verlet;

use crate::error::{Error, Result};
use crate::forces::{ForceInput, ForceModel, Springs};
use crate::grid::Grid;
use crate::profile::Profile;
use crate::scene::INTEGRATORS;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::state::{Kinematics, Particles};

/// Everything a step reads and writes.
pub struct StepContext<'a> {
    pub grid: Grid,
    pub current: &'a Kinematics,
    pub next: &'a mut Kinematics,
    pub particles: &'a Particles,
    pub springs: &'a Springs,
    pub forces: &'a ForceModel,
    /// Scratch for the total force, one vector per particle.
    pub force: &'a mut Vec3s,
    /// Particles per parallel work item.
    pub chunk: usize,
    pub profile: &'a mut Profile,
}

impl StepContext<'_> {
    /// Evaluates the total force at `state` into `self.force`.
    pub fn eval_forces_at(&mut self, state: &Kinematics) {
        let input = ForceInput {
            grid: self.grid,
            pos: &state.pos,
            vel: &state.vel,
            mass: &self.particles.mass,
            springs: self.springs,
        };
        self.forces
            .evaluate(&input, self.force, self.chunk, self.profile);
    }
}

/// A time integrator.
pub trait Integrator: Send + Sync {
    /// Name in the scene, `effects` and `profile()`.
    fn name(&self) -> &'static str;

    /// Writes into `ctx.next` the state one step `h` (s) after `ctx.current`. Particles with
    /// `inv_mass == 0` are copied unchanged. Returns whether every written value is finite.
    fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool;

    /// Called when the state was changed from outside (new positions or velocities, a new
    /// step size): an integrator that keeps history must start afresh.
    fn reset_history(&mut self) {}

    /// Linear-solver statistics, for integrators that solve a system each step.
    fn solver_stats(&self) -> Option<implicit_euler::SolverStats> {
        None
    }
}

/// The integrator called `name` in a scene.
pub fn by_name(name: &str, solver: SolverSettings) -> Result<Box<dyn Integrator>> {
    match name {
        "explicit_euler" => Ok(Box::new(ExplicitEuler)),
        "symplectic_euler" => Ok(Box::new(SymplecticEuler)),
        "verlet" => Ok(Box::new(Verlet::default())),
        "rk4" => Ok(Box::new(Rk4::default())),
        "implicit_euler" => Ok(Box::new(ImplicitEuler::new(solver))),
        _ => Err(Error::value(
            "integrator",
            format!("unknown integrator {name:?}; valid ones are {INTEGRATORS:?}"),
        )),
    }
}

/// One chunk of the per-particle update: the particles `range`, their start state and force,
/// and the slices of `next` to write.
pub struct UpdateChunk<'a> {
    pub range: std::ops::Range<usize>,
    pub pos: Vec3SliceMut<'a>,
    pub vel: Vec3SliceMut<'a>,
}

/// Runs `update` over every chunk of `next` in parallel and reports whether all of it is
/// finite afterwards. `update` returns a probe: a sum of `value * 0` over what it wrote, which
/// is NaN exactly when something non-finite was written. That costs one multiply-add per value
/// in a loop that is already streaming them, instead of a second pass over memory.
pub fn par_update(
    next: &mut Kinematics,
    chunk: usize,
    update: impl Fn(UpdateChunk) -> f32 + Sync + Send,
) -> bool {
    let Kinematics { pos, vel } = next;
    pos.par_chunks_mut(chunk)
        .zip(vel.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (pos, vel))| {
            let range = c * chunk..c * chunk + pos.len();
            update(UpdateChunk { range, pos, vel })
        })
        .all(|probe| !probe.is_nan())
}

/// The update shared by the one-stage explicit schemes: with `dv = h f / m` from the force at the
/// start of the step, `rule(x, v, dv)` gives the new `(x, v)` of one component of one particle.
/// Particles that must not move keep their state bitwise.
pub fn one_stage_update(
    ctx: &mut StepContext,
    h: f32,
    rule: impl Fn(f32, f32, f32) -> (f32, f32) + Sync + Send,
) -> bool {
    ctx.eval_forces_at(ctx.current);
    let (cur, force, inv_mass) = (ctx.current, &*ctx.force, &ctx.particles.inv_mass);
    par_update(ctx.next, ctx.chunk, |out| {
        let r = out.range.clone();
        let (x, v, f) = (
            cur.pos.slices(r.clone()),
            cur.vel.slices(r.clone()),
            force.slices(r.clone()),
        );
        let w = &inv_mass[r];
        let mut probe = 0.0f32;
        for (dst_x, dst_v, x, v, f) in [
            (&mut *out.pos.x, &mut *out.vel.x, x.x, v.x, f.x),
            (&mut *out.pos.y, &mut *out.vel.y, x.y, v.y, f.y),
            (&mut *out.pos.z, &mut *out.vel.z, x.z, v.z, f.z),
        ] {
            let (dst_x, dst_v, x, v, f) = (
                &mut dst_x[..w.len()],
                &mut dst_v[..w.len()],
                &x[..w.len()],
                &v[..w.len()],
                &f[..w.len()],
            );
            for i in 0..w.len() {
                let (x_new, v_new) = rule(x[i], v[i], h * f[i] * w[i]);
                let moving = w[i] > 0.0;
                dst_x[i] = if moving { x_new } else { x[i] };
                dst_v[i] = if moving { v_new } else { v[i] };
                probe += dst_x[i] * 0.0 + dst_v[i] * 0.0;
            }
        }
        probe
    })
}

/// Like [`par_update`] over two state buffers at once, chunk by chunk.
pub fn par_update2(
    a: &mut Kinematics,
    b: &mut Kinematics,
    chunk: usize,
    update: impl Fn(std::ops::Range<usize>, UpdateChunk, UpdateChunk) -> f32 + Sync + Send,
) -> bool {
    let (Kinematics { pos: ap, vel: av }, Kinematics { pos: bp, vel: bv }) = (a, b);
    ap.par_chunks_mut(chunk)
        .zip(av.par_chunks_mut(chunk))
        .zip(bp.par_chunks_mut(chunk).zip(bv.par_chunks_mut(chunk)))
        .enumerate()
        .map(|(c, ((ap, av), (bp, bv)))| {
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
        })
        .all(|probe| !probe.is_nan())
}
