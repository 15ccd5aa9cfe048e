//! Projective dynamics for mass-spring cloth (Liu, Bargteil, O'Brien and Kavan, "Fast
//! simulation of mass-spring systems", SIGGRAPH Asia 2013), accelerated with Chebyshev
//! semi-iteration (Wang, "A Chebyshev semi-iterative approach for accelerating projective and
//! position-based dynamics", SIGGRAPH Asia 2015).
//!
//! **The step.** Backward Euler on positions, solved exactly rather than linearised: with
//! `v = (x - x_n) / h` it is the minimiser of the incremental potential
//!
//! ```text
//! G(x) = 1/(2 h^2) |x - y|_M^2 + c_d/(2h) |x - x_n|^2 + sum_s k_s/2 (|d_s| - L_s)^2 + D(x),
//! y = x_n + h v_n + h^2 a
//! ```
//!
//! (`a` the constant accelerations, gravity; `c_d` air drag; `d_s = x_b - x_a`), where the
//! damping along each spring, `c ((v_b - v_a) . u) u`, enters as the gradient of the
//! dissipation `D` at fixed directions `u`. Its stationarity condition is, for every free
//! particle `a`,
//!
//! ```text
//! (m_a/h^2 + c_d/h) x_a - sum_s (k_s + c_s/h)(x_b - x_a) = m_a/h^2 y_a + c_d/h x_n,a - sum_s w_s,
//! w_s = k_s L_s u_s + (c_s/h) (d_s - (u_s . (d_s - d_n,s)) u_s),     u_s = d_s / |d_s|
//! ```
//!
//! (`b` the other end of spring `s`, `w_s` taken with the sign of the direction `a -> b`). The
//! left side is a constant matrix `Q = M/h^2 + c_d/h I + sum_s (k_s + c_s/h) A_s^T A_s` (a
//! weighted graph Laplacian, the same scalar for x, y and z). Each **local** step projects every
//! spring onto its rest length (`L_s u_s`) and takes the part of the damping that `Q`'s
//! isotropic `c_s/h` does not hold; each **global** step solves `Q x = rhs(x_k)`, with `Q`
//! factored once (`src/linear/cholesky.rs`). At a fixed point the equations above hold exactly:
//! the result is the backward-Euler step of the same model the explicit integrators step,
//! springs, damping and drag included.
//!
//! **In increments.** `Q x_k - rhs(x_k)` is the gradient `g(x_k)` of `G`, so the global step is
//! `x_{k+1} = x_k - Q^-1 g(x_k)`: the same iteration, computed from `g`, which is summed from the
//! forces themselves (inertia, drag, `k (l - L) u + (c/h) (u . (d - d_n)) u` per spring). Formed
//! as `rhs` instead, the net force is the small difference of `m/h^2 y` and the spring terms, and
//! float32 loses it as `h` shrinks, until at small substeps the step is dominated by rounding.
//! (Projective dynamics is thereby a quasi-Newton method with the constant
//! Hessian approximation `Q`, as Liu, Bouaziz and Kavan note in "Quasi-Newton methods for
//! real-time simulation of hyperelastic materials", 2017.)
//!
//! **Chebyshev.** The iterates are extrapolated as `x_{k+1} = w_{k+1} (x~_{k+1} - x_{k-1}) +
//! x_{k-1}` with `w_1 = 1`, `w_2 = 2/(2 - rho^2)`, `w_{k+1} = 4/(4 - rho^2 w_k)`, `x~` the plain
//! local-global result. When the gradient norm grows the extrapolation is restarted (`w = 1`).
//!
//! **Held particles** (pinned or cut) are not unknowns. A pinned particle enters its springs at
//! `x_n + h v_n`: at rest for a plain pin, moving with the drag for a kinematic pin, as in
//! implicit Euler's linearisation. A cut particle's springs are dead; every value computed from
//! them is selected away, so where it sits cannot change the step.
//!
//! **Contacts.** With colliders, each particle the stepper predicts to make a contact
//! ([`crate::collisions::predict`]) adds the term `w_c/2 |x - P(x)|^2` to `G` (Bouaziz et al.,
//! "Projective dynamics", 2014), `P` the projection onto the outer side of the contact's plane
//! and `w_c = 100 m/h^2`: its local step is that projection and it adds `w_c` to the particle's
//! diagonal of `Q`, isotropic like every term there. The springs around a landing particle feel
//! the contact within the step; projected out of the collider after the solve instead, a long
//! step crushes the springs of rows landing on each other (the dropped `pile` at 1/60 s gains
//! five times its energy). `Q` is refactored when the set of particles in contact changes, not
//! when their planes do: on steps where a cloth lands, and on most steps of a cloth resting on
//! a collider, whose rim makes and breaks contacts (`drape` at its 1 ms steps: 758
//! factorisations in its first 1,706 solves). With contacts the iteration runs without
//! Chebyshev's extrapolation (see [`ProjectiveDynamics::step`]).
//!
//! **State between steps.** Only the factorisation of `Q`, a cache keyed on everything it is
//! built from (step, masses, held particles, live springs, stiffness, damping, drag, contacts)
//! and rebuilt when any of them changes: a refused step needs no rollback, and
//! [`super::Integrator::reset_history`] has nothing to do.
//!
//! **Cost.** Per iteration one pass over the springs and two triangular solves with three
//! right-hand sides; a change of pins, cuts, masses or step refactors `Q`
//! (`O(N^1.5)`, see docs/stiff.md for the times).
//!
//! **Residual.** `profile().solver` reports local-global iterations and the gradient norm of `G`
//! at the last iterate relative to its value at the first, `|g_K| / |g_0|`: zero exactly at the
//! backward-Euler solution.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::solver::{
    contact_weight, depth, in_contact, kind_slot, live_or_zero, SolverSettings, SolverStats,
};
use super::{par_update, FiniteCheck, StepContext};
use crate::forces::Force;
use crate::grid::SpringKind;
use crate::linear::reduce::{dot3, partials, REDUCE_CHUNK};
use crate::linear::{ScalarStencil, SparseCholesky};
use crate::soa::Vec3s;
use crate::springs::{anchored_run, neighbour_runs};

/// See the module docs.
pub struct ProjectiveDynamics {
    settings: SolverSettings,
    stats: SolverStats,
    /// `(kind, k, c)` of every spring kind, refilled each step (kept for its allocation).
    kinds: Vec<(SpringKind, f32, f32)>,
    work: Option<Work>,
}

/// Everything `Q` is built from, to know when to refactor; compared and refreshed in place, so
/// that a step allocates nothing once the buffers have their size.
#[derive(Clone, Debug, Default, PartialEq)]
struct Key {
    valid: bool,
    h: u32,
    drag: u32,
    /// `(kind, k, c)` bits of every spring kind.
    kinds: Vec<(SpringKind, u32, u32)>,
    mass: Vec<f32>,
    inv_mass: Vec<f32>,
    /// `active` of each kind of `kinds`, back to back.
    active: Vec<f32>,
    /// Which particles are in a predicted contact.
    contact: Vec<bool>,
    /// A mesh cloth's live springs (empty on the grid): a cut or a tear changes `Q`.
    mesh_active: Vec<bool>,
}

impl Key {
    fn matches(
        &self,
        h: f32,
        drag: f32,
        kinds: &[(SpringKind, f32, f32)],
        ctx: &StepContext,
    ) -> bool {
        self.valid
            && self.h == h.to_bits()
            && self.drag == drag.to_bits()
            && self.kinds.len() == kinds.len()
            && self
                .kinds
                .iter()
                .zip(kinds)
                .all(|(a, b)| a.0 == b.0 && a.1 == b.1.to_bits() && a.2 == b.2.to_bits())
            && self.mass[..] == ctx.particles.mass[..]
            && self.inv_mass[..] == ctx.particles.inv_mass[..]
            && kinds.iter().enumerate().all(|(i, (kind, _, _))| {
                let n = ctx.grid.len();
                self.active[i * n..(i + 1) * n] == ctx.springs.active[kind.index()][..]
            })
            && self.contact.len() == ctx.grid.len()
            && (0..ctx.grid.len()).all(|p| self.contact[p] == in_contact(ctx, p))
            && ctx.mesh.map_or(&[][..], |m| &m.springs.active[..]) == &self.mesh_active[..]
    }

    fn store(&mut self, h: f32, drag: f32, kinds: &[(SpringKind, f32, f32)], ctx: &StepContext) {
        self.valid = true;
        self.h = h.to_bits();
        self.drag = drag.to_bits();
        self.kinds.clear();
        self.kinds.extend(
            kinds
                .iter()
                .map(|&(kind, k, c)| (kind, k.to_bits(), c.to_bits())),
        );
        self.mass.clear();
        self.mass.extend_from_slice(&ctx.particles.mass);
        self.inv_mass.clear();
        self.inv_mass.extend_from_slice(&ctx.particles.inv_mass);
        self.active.clear();
        for (kind, _, _) in kinds {
            self.active
                .extend_from_slice(&ctx.springs.active[kind.index()]);
        }
        self.contact.clear();
        self.contact
            .extend((0..ctx.grid.len()).map(|p| in_contact(ctx, p)));
        let live = ctx.mesh.map_or(&[][..], |m| &m.springs.active[..]);
        self.mesh_active.clear();
        self.mesh_active.extend_from_slice(live);
    }
}

struct Work {
    key: Key,
    /// `(kind, k, c)` of every spring kind in the pipeline.
    kinds: Vec<(SpringKind, f32, f32)>,
    factor: SparseCholesky,
    /// The current iterate as a displacement from the start of the step, `x_k - x_n` (held
    /// particles at `h v_n`), the one before it, the global step's increment `Q^-1 g`, the
    /// inertial target `y - x_n` and the gradient. Displacements keep float32's full relative
    /// precision for the step's motion: as absolute positions, `h^2 g` is below the resolution
    /// of a coordinate of 1 m once `h` is under 1e-4 s, and the cloth stopped falling.
    x: Vec3s,
    previous: Vec3s,
    increment: Vec3s,
    y: Vec3s,
    grad: Vec3s,
    /// Per kind, the force of the spring anchored at each particle on that particle.
    force: [Vec3s; 6],
    partials: Vec<f64>,
    /// A mesh cloth's: the force of each spring on its first end, and the rest shape's
    /// nested-dissection order (made with the first factor).
    spring_force: Vec3s,
    order: Vec<usize>,
}

impl ProjectiveDynamics {
    pub fn new(settings: SolverSettings) -> Self {
        ProjectiveDynamics {
            settings,
            stats: SolverStats::default(),
            kinds: Vec::new(),
            work: None,
        }
    }
}

impl ProjectiveDynamics {
    pub fn solver_stats(&self) -> SolverStats {
        self.stats
    }

    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        // The force at the start of the step is not needed by the iteration, but its armed
        // evaluation is where the watchdog checks the springs of the state the step starts from.
        ctx.eval_forces_at(ctx.current);
        let n = ctx.grid.len();
        let (mut drag, mut accel) = (0.0f32, Vec3::ZERO);
        let kinds = &mut self.kinds;
        kinds.clear();
        for &force in ctx.forces.forces() {
            match force {
                Force::Springs { family, k, c } => {
                    kinds.extend(family.kinds().map(|kind| (kind, k, c)));
                }
                Force::Drag { c } => drag += c,
                Force::Gravity { g } => accel += g,
            }
        }
        let work = self.work.get_or_insert_with(|| Work {
            key: Key::default(),
            kinds: Vec::new(),
            factor: SparseCholesky::default(),
            x: Vec3s::zeros(n),
            previous: Vec3s::zeros(n),
            increment: Vec3s::zeros(n),
            y: Vec3s::zeros(n),
            grad: Vec3s::zeros(n),
            force: Default::default(),
            partials: partials(n),
            spring_force: Vec3s::default(),
            order: Vec::new(),
        });
        if !work.key.matches(h, drag, kinds, ctx) {
            let started = Instant::now();
            work.kinds.clear();
            work.kinds.extend_from_slice(kinds);
            factor(work, h, drag, ctx);
            work.key.store(h, drag, kinds, ctx);
            self.stats.factorizations += 1;
            self.stats.setup_seconds += started.elapsed().as_secs_f64();
        }

        // The inertial target as a displacement, y - x_n = h v_n + h^2 a, and the first
        // iterate; held particles move by h v_n.
        let (cur, w) = (ctx.current, &ctx.particles.inv_mass);
        let accel_term = h * h * accel;
        work.y
            .par_chunks_mut(ctx.chunk)
            .zip(work.x.par_chunks_mut(ctx.chunk))
            .enumerate()
            .for_each(|(ci, (mut y, mut x))| {
                for i in 0..y.len() {
                    let q = ci * ctx.chunk + i;
                    let moved = h * cur.vel.get(q);
                    let target = if w[q] > 0.0 {
                        moved + accel_term
                    } else {
                        moved
                    };
                    y.set(i, target);
                    x.set(i, target);
                }
            });
        // A particle in contact starts on its plane, where the prediction put it, not at the free
        // motion's end behind it: there its stiff weight's gradient alone would set the first
        // increments.
        if let Some(contacts) = ctx.contacts.filter(|c| c.count > 0) {
            for p in 0..n {
                if in_contact(ctx, p) {
                    let normal = contacts.normal.get(p);
                    let d = work.x.get(p);
                    let behind = depth(normal, contacts.offset[p], cur.pos.get(p), d);
                    if behind > 0.0 {
                        work.x.set(p, d + behind * normal);
                    }
                }
            }
        }
        let settings = self.settings;
        let started = Instant::now();
        // Chebyshev's extrapolation assumes a fixed linear iteration; a contact's term switches
        // on and off with the side of its plane the iterate is on, and extrapolated across that
        // switch the iterates overshoot (a cloth landing on a 2 cm ball at 1/60 s gained 980 %
        // of its energy with it, 11 % without). With contacts, the iteration is the plain one.
        let rho = if ctx.contacts.is_some_and(|c| c.count > 0) {
            0.0
        } else {
            settings.pd_chebyshev_rho
        };
        let (mut omega, mut cheb_k) = (1.0f32, 0u32);
        let (mut g0, mut g_last) = (0.0f64, f64::INFINITY);
        let mut iterations = 0u32;
        let mut residual;
        loop {
            let g = local_step(work, h, drag, ctx);
            if iterations == 0 {
                g0 = g;
            }
            residual = if g0 > 0.0 { g / g0 } else { 0.0 };
            if !residual.is_finite()
                || iterations >= settings.pd_iterations
                || residual <= settings.pd_tolerance as f64
            {
                break;
            }
            work.factor.solve(&work.grad, &mut work.increment);
            // Chebyshev: restart when the gradient grew.
            if g > g_last {
                cheb_k = 0;
            }
            g_last = g;
            omega = match cheb_k {
                0 => 1.0,
                1 => 2.0 / (2.0 - rho * rho),
                _ => 4.0 / (4.0 - rho * rho * omega),
            };
            cheb_k += 1;
            extrapolate(work, omega, w);
            iterations += 1;
        }
        self.stats.solve_seconds += started.elapsed().as_secs_f64();
        self.stats.record(
            iterations,
            if residual.is_finite() {
                residual
            } else {
                f64::NAN
            },
            settings.pd_tolerance as f64,
        );

        // x' = x_n + dx, v' = dx / h for free particles; held ones keep their state bitwise.
        let dx = &work.x;
        let inv_h = 1.0 / h;
        par_update(ctx.next, ctx.chunk, |mut out| {
            let mut check = FiniteCheck::default();
            for (i, p) in out.range.clone().enumerate() {
                let (xn, vn) = (cur.pos.get(p), cur.vel.get(p));
                let (x_new, v_new) = if w[p] > 0.0 {
                    let d = dx.get(p);
                    (xn + d, d * inv_h)
                } else {
                    (xn, vn)
                };
                out.pos.set(i, x_new);
                out.vel.set(i, v_new);
                for value in x_new.to_array().into_iter().chain(v_new.to_array()) {
                    check.watch(value);
                }
            }
            check
        })
    }
}

/// Builds `Q` and factors it over the free particles.
fn factor(work: &mut Work, h: f32, drag: f32, ctx: &StepContext) {
    if let Some(mesh) = ctx.mesh {
        let (order, forces) = (&mut work.order, &mut work.spring_force);
        work.factor = super::projective_mesh::factor(mesh, order, forces, (h, drag), ctx);
        return;
    }
    let n = ctx.grid.len();
    let (mass, w) = (&ctx.particles.mass, &ctx.particles.inv_mass);
    let slots: Vec<usize> = work
        .kinds
        .iter()
        .map(|&(kind, _, _)| kind_slot(kind))
        .collect();
    let mut q = ScalarStencil::new(ctx.grid.nx, ctx.grid.ny, &slots);
    let (h64, drag64) = (h as f64, drag as f64);
    for p in 0..n {
        q.slot_mut(0)[p] = if w[p] > 0.0 {
            mass[p] as f64 / (h64 * h64) + drag64 / h64
        } else {
            0.0
        };
    }
    for (&(kind, k, c), &slot) in work.kinds.iter().zip(&slots) {
        let (o, active) = (ctx.grid.offset(kind), &ctx.springs.active[kind.index()]);
        let weight = k as f64 + c as f64 / h64;
        for a in 0..n.saturating_sub(o) {
            if active[a] == 0.0 {
                continue;
            }
            let b = a + o;
            let (fa, fb) = (w[a] > 0.0, w[b] > 0.0);
            if fa {
                q.slot_mut(0)[a] += weight;
            }
            if fb {
                q.slot_mut(0)[b] += weight;
            }
            if fa && fb {
                q.slot_mut(slot)[a] = -weight;
            }
        }
    }
    for (p, &m) in mass.iter().enumerate() {
        if in_contact(ctx, p) {
            q.slot_mut(0)[p] += contact_weight(m, h) as f64;
        }
    }
    let free: Vec<bool> = w.iter().map(|&w| w > 0.0).collect();
    work.factor = SparseCholesky::factor(&q, &free);
    for kind in work.kinds.iter().map(|k| k.0) {
        if work.force[kind.index()].len() != n {
            work.force[kind.index()] = Vec3s::zeros(n);
        }
    }
}

/// The local step at the current iterate `x = x_n + work.x`: every spring's force, and the
/// gradient of the incremental potential, `g = M/h^2 (x - y) + c_d/h (x - x_n) - f_springs(x)`,
/// zero for held particles. Returns `|g|`.
fn local_step(work: &mut Work, h: f32, drag: f32, ctx: &StepContext) -> f64 {
    if let Some(mesh) = ctx.mesh {
        let Work {
            x,
            y,
            grad,
            spring_force,
            partials,
            ..
        } = work;
        return super::projective_mesh::local_step(
            mesh,
            (x, y),
            (grad, spring_force, partials),
            (h, drag),
            ctx,
        );
    }
    let n = ctx.grid.len();
    let chunk = ctx.chunk;
    let (cur, rest, active) = (&ctx.current.pos, &ctx.springs.rest, &ctx.springs.active);
    let x = &work.x;
    let inv_h = 1.0 / h;
    // The force per spring, by anchor.
    for &(kind, k, c) in &work.kinds {
        let o = ctx.grid.offset(kind);
        let ki = kind.index();
        let (rest, active) = (&rest[ki], &active[ki]);
        let ch = c * inv_h;
        work.force[ki]
            .par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(ci, mut f)| {
                let start = ci * chunk;
                let run = anchored_run(n, o, start..start + f.len());
                let (len, s, t) = (run.len, run.a_range(), run.b_range());
                let (ea, eb) = (x.slices(s.clone()), x.slices(t.clone()));
                let (na, nb) = (cur.slices(s.clone()), cur.slices(t));
                let (rest, active) = (&rest[s.clone()], &active[s]);
                crate::simd::dispatch!({
                    for i in 0..len {
                        // The spring's change over the step, then the spring itself.
                        let (ex, ey, ez) =
                            (eb.x[i] - ea.x[i], eb.y[i] - ea.y[i], eb.z[i] - ea.z[i]);
                        let (dx, dy, dz) = (
                            (nb.x[i] - na.x[i]) + ex,
                            (nb.y[i] - na.y[i]) + ey,
                            (nb.z[i] - na.z[i]) + ez,
                        );
                        let l = (dx * dx + dy * dy + dz * dz).sqrt();
                        let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                        let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
                        // u . (d - d_n): the spring's lengthening over the step.
                        let along = ux * ex + uy * ey + uz * ez;
                        // A zero-length spring has no direction and exerts no force.
                        let s = k * (l - rest[i]) * (l > 0.0) as u32 as f32 + ch * along;
                        let live = active[i] != 0.0;
                        f.x[i] = live_or_zero(live, s * ux);
                        f.y[i] = live_or_zero(live, s * uy);
                        f.z[i] = live_or_zero(live, s * uz);
                    }
                });
                f.sub_mut(len..f.len()).fill(Vec3::ZERO);
            });
    }
    // The gradient per particle.
    let Work {
        kinds,
        y,
        grad,
        force,
        partials,
        ..
    } = work;
    let (mass, inv_mass) = (&ctx.particles.mass, &ctx.particles.inv_mass);
    let contacts = ctx.contacts.filter(|c| c.count > 0);
    let inv_h2 = inv_h * inv_h;
    let drag_h = drag * inv_h;
    grad.par_chunks_mut(REDUCE_CHUNK)
        .zip(partials.par_iter_mut())
        .enumerate()
        .for_each(|(ci, (g, partial))| {
            let range = ci * REDUCE_CHUNK..ci * REDUCE_CHUNK + g.len();
            *partial = crate::simd::dispatch!({
                let (yv, xs) = (y.slices(range.clone()), x.slices(range.clone()));
                for (i, p) in range.clone().enumerate() {
                    let m = mass[p] * inv_h2;
                    g.x[i] = m * (xs.x[i] - yv.x[i]) + drag_h * xs.x[i];
                    g.y[i] = m * (xs.y[i] - yv.y[i]) + drag_h * xs.y[i];
                    g.z[i] = m * (xs.z[i] - yv.z[i]) + drag_h * xs.z[i];
                }
                for &(kind, _, _) in kinds.iter() {
                    let o = ctx.grid.offset(kind);
                    for (end, run) in neighbour_runs(n, o, range.clone()).into_iter().enumerate() {
                        let Some(run) = run else { continue };
                        // The force is the anchor's: the anchor's gradient takes -F, the far
                        // end's +F.
                        let sign = if end == 0 { -1.0 } else { 1.0 };
                        let fs = force[kind.index()].slices(run.spring..run.spring + run.len);
                        let dst = run.a - range.start..run.a - range.start + run.len;
                        for (g, f) in [
                            (&mut g.x[dst.clone()], fs.x),
                            (&mut g.y[dst.clone()], fs.y),
                            (&mut g.z[dst.clone()], fs.z),
                        ] {
                            for (g, f) in g.iter_mut().zip(f) {
                                *g += sign * f;
                            }
                        }
                    }
                }
                // A contact's term `w_c/2 |x - P(x)|^2`, `P` the projection onto the outer
                // side of its plane: zero on that side, `-w_c depth n` behind it.
                if let Some(contacts) = contacts {
                    for (i, p) in range.clone().enumerate() {
                        let normal = contacts.normal.get(p);
                        if normal == Vec3::ZERO {
                            continue;
                        }
                        let (xn, d) = (cur.get(p), Vec3::new(xs.x[i], xs.y[i], xs.z[i]));
                        let behind = depth(normal, contacts.offset[p], xn, d).max(0.0);
                        let push = contact_weight(mass[p], h) * behind;
                        g.x[i] -= push * normal.x;
                        g.y[i] -= push * normal.y;
                        g.z[i] -= push * normal.z;
                    }
                }
                for (i, p) in range.clone().enumerate() {
                    let free = inv_mass[p] > 0.0;
                    g.x[i] = live_or_zero(free, g.x[i]);
                    g.y[i] = live_or_zero(free, g.y[i]);
                    g.z[i] = live_or_zero(free, g.z[i]);
                }
                let gs = g.as_slices();
                dot3(gs, gs)
            });
        });
    partials.iter().sum::<f64>().sqrt()
}

/// `x_{k+1} = omega (x~ - x_{k-1}) + x_{k-1}` on the free particles, with the global step's
/// result `x~ = x_k - Q^-1 g(x_k)`, and `x_{k-1} = x_k`.
fn extrapolate(work: &mut Work, omega: f32, inv_mass: &[f32]) {
    let Work {
        x,
        previous,
        increment,
        ..
    } = work;
    let chunk = REDUCE_CHUNK;
    x.par_chunks_mut(chunk)
        .zip(previous.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(ci, (mut x, mut prev))| {
            let range = ci * chunk..ci * chunk + x.len();
            let d = increment.slices(range.clone());
            for (i, p) in range.enumerate() {
                if inv_mass[p] == 0.0 {
                    continue;
                }
                let (xk, xkm1) = (x.get(i), prev.get(i));
                let xs = xk - Vec3::new(d.x[i], d.y[i], d.z[i]);
                let next = if omega == 1.0 {
                    xs
                } else {
                    omega * (xs - xkm1) + xkm1
                };
                prev.set(i, xk);
                x.set(i, next);
            }
        });
}
