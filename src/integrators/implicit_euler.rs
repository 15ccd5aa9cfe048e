//! Backward Euler, linearised once per step (Baraff and Witkin, "Large steps in cloth
//! simulation", SIGGRAPH 1998), solved by a preconditioned conjugate gradient
//! (`src/linear/cg.rs`) on the assembled block matrix.

use std::time::Instant;

use rayon::prelude::*;

use super::contact_filter::ContactFilter;
use super::implicit_mesh::MeshSystem;
use super::self_contact::{SelfContactTerm, WithSelfContacts};
use super::solver::{
    kind_slot, live_or_zero, Preconditioner, SolverSettings, SolverStats, CONTACT_STIFFNESS,
};
use super::{par_update, FiniteCheck, StepContext};
use crate::collisions::{Impulses, PredictedContacts};
use crate::forces::Force;
use crate::grid::SpringKind;
use crate::linear::cg::{diagonal_blocks, BlockOperator, ConjugateGradient, Start};
use crate::linear::stencil::{par_chunks6, SlotArrays};
use crate::linear::{BlockStencil, Multigrid};
use crate::soa::{Floats, Vec3s};
use crate::springs::{anchored_run, neighbour_runs};

/// Backward Euler: find `dv` with
///
/// ```text
/// (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v)
/// v' = v + dv,   x' = x + h v'
/// ```
///
/// For a spring with direction `u`, length `l`, rest length `L`, the blocks are
/// `df_a/dx_a = -k (u u^T + g (I - u u^T))` with `g = max(0, 1 - L/l)` and
/// `df_a/dv_a = -c u u^T`. Clamping `g` at zero drops the destabilising transverse stiffness of
/// compressed springs (the standard fix that keeps the matrix positive definite).
///
/// **Held particles.** Pinned and cut particles (`inv_mass == 0`) are filtered out of the system:
/// their rows and columns are zero and their `dv` stays zero. A cut particle's springs are dead,
/// and nothing computed from them enters the system: every value taken from a dead spring is
/// selected away (not multiplied by zero, which would let an infinite or NaN direction through),
/// so where a cut particle sits cannot change the solve. A pinned particle's springs do enter
/// the right-hand side, through `h^2 df/dx v`, with the pin's velocity: that is how the cloth
/// follows a dragged pin.
///
/// **State between steps.** On the grid none: the solve starts from `dv = 0`, the matrix and
/// the multigrid hierarchy are rebuilt from the step's own state. A mesh's solve reuses earlier
/// solves' work (its coarse operators, the last accepted `dv` as CG's start,
/// [`super::implicit_mesh`]), which changes the result only within CG's tolerance, and which
/// [`ImplicitEuler::restart`] drops wherever a run and its restored copy must agree.
///
/// Unconditionally stable and first order: it damps, strongly at large steps. Cost per step:
/// one force evaluation, one assembly of the matrix, the preconditioner's setup, and per CG
/// iteration one matrix-vector product and one preconditioner application.
pub struct ImplicitEuler {
    settings: SolverSettings,
    stats: SolverStats,
    /// `(family, k, c)` of the spring terms, refilled each step (kept to reuse its allocation).
    families: Vec<(crate::grid::Family, f32, f32)>,
    work: Option<Work>,
    /// A mesh cloth's system ([`super::implicit_mesh`]), made on its first step.
    mesh: Option<MeshSystem>,
    /// The predicted contacts held exactly inside the solve.
    filter: ContactFilter,
    /// The self-collision pairs held apart inside the solve (grid cloth only).
    self_contact: SelfContactTerm,
    /// Whether the last step stopped at its loose pair-finding solve, its system kept for
    /// [`ImplicitEuler::finish_loose`].
    loose: bool,
    /// The settings of the last step's first solve, which [`ImplicitEuler::finish_loose`]
    /// finishes.
    first: SolverSettings,
}

/// The matrix `A = M + h drag I + sum_s C_s` (filtered), per-spring data and the solver's
/// vectors.
struct Work {
    matrix: BlockStencil,
    /// Which spring kinds take part, with the matrix slot of each.
    kinds: Vec<(SpringKind, usize)>,
    /// Per kind, `K_s (v_a - v_b)` of the spring anchored at each particle (`h^2 df/dx` part
    /// of its block times the velocity difference).
    kv: [Vec3s; 6],
    /// The preconditioner's blocks (Jacobi: the inverse diagonal as diagonal blocks).
    jacobi: SlotArrays,
    multigrid: Multigrid,
    rhs: Vec3s,
    /// The right-hand side before the contact filter's reduction, with the held self-contact
    /// pairs' loads: what a later round of a step adds its pairs to and reduces again. Kept
    /// only while a step holds both (empty otherwise).
    assembled: Vec3s,
    dv: Vec3s,
    cg: ConjugateGradient,
}

impl Work {
    fn new(n: usize, nx: usize, ny: usize, kinds: Vec<(SpringKind, usize)>) -> Self {
        let slots: Vec<usize> = kinds.iter().map(|k| k.1).collect();
        let mut kv: [Vec3s; 6] = Default::default();
        for &(kind, _) in &kinds {
            kv[kind.index()] = Vec3s::zeros(n);
        }
        Work {
            matrix: BlockStencil::new(nx, ny, &slots),
            kinds,
            kv,
            jacobi: std::array::from_fn(|_| Floats::zeros(n)),
            multigrid: Multigrid::new(),
            rhs: Vec3s::zeros(n),
            assembled: Vec3s::zeros(0),
            dv: Vec3s::zeros(n),
            cg: ConjugateGradient::new(n),
        }
    }
}

impl ImplicitEuler {
    pub fn new(settings: SolverSettings) -> Self {
        ImplicitEuler {
            settings,
            stats: SolverStats::default(),
            families: Vec::new(),
            work: None,
            mesh: None,
            filter: ContactFilter::default(),
            self_contact: SelfContactTerm::default(),
            loose: false,
            first: settings,
        }
    }
}

impl ImplicitEuler {
    pub fn solver_stats(&self) -> SolverStats {
        self.stats
    }

    /// Per particle, what its predicted contact did in the last solve: the normal impulse (N s,
    /// positive where it pushed) and a sticking contact's tangential one; zero without one.
    pub fn contact_impulses(&self) -> Impulses<'_> {
        self.filter.impulses()
    }

    /// The last step became the state: a mesh's next solve may start from its `dv`.
    pub fn accept(&mut self) {
        if let Some(mesh) = &mut self.mesh {
            mesh.accept();
        }
    }

    /// The next step reuses nothing from earlier solves (a mesh's coarse operators, its CG
    /// start), as a new integrator would not: a snapshot was taken, or the state or the
    /// history was set from outside.
    pub fn restart(&self) {
        if let Some(mesh) = &self.mesh {
            mesh.restart();
        }
    }

    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        self.loose = false;
        ctx.eval_forces_at(ctx.current);
        let started = Instant::now();
        let n = ctx.current.pos.len();
        let mut drag = 0.0f32;
        let families = &mut self.families;
        families.clear();
        for &force in ctx.forces.forces() {
            match force {
                Force::Springs { family, k, c } => families.push((family, k, c)),
                Force::Drag { c } => drag += c,
                Force::Gravity { .. } => {}
            }
        }
        if let Some(mesh) = ctx.mesh {
            let system = self.mesh.get_or_insert_with(|| MeshSystem::new(mesh));
            let (settings, stats) = (self.settings, &mut self.stats);
            system.solve(mesh, (h, drag), (settings, stats), &mut self.filter, ctx);
            return update(h, ctx, system.solution());
        }
        let work = self.work.get_or_insert_with(|| {
            let kinds = families
                .iter()
                .flat_map(|&(family, _, _)| family.kinds().map(|kind| (kind, kind_slot(kind))))
                .collect();
            Work::new(n, ctx.grid.nx, ctx.grid.ny, kinds)
        });
        // Two kinds per family, in the order the work was built with.
        for (&(_, k, c), kinds) in families.iter().zip(work.kinds.chunks(2)) {
            for &(kind, slot) in kinds {
                build_blocks(&mut work.matrix, &mut work.kv, kind, slot, h, k, c, ctx);
            }
        }
        assemble_diagonal_and_rhs(work, h, drag, ctx);
        if let Some(contacts) = ctx.contacts.filter(|c| c.count > 0) {
            stiffen_contacts(work, contacts, ctx);
        }
        filter_couplings(work, ctx);
        let (cur, w) = (ctx.current, &ctx.particles.inv_mass[..]);
        let self_contact = &mut self.self_contact;
        match ctx.self_pairs {
            Some(pairs) => {
                self_contact.gather(h, pairs, (&cur.pos, &cur.vel, w));
                self_contact.add_diagonal(0, work.matrix.slot_mut(0));
                self_contact.add_rhs(0, h, &mut work.rhs);
            }
            None => self_contact.clear(),
        }
        self.stats.self_pairs += self_contact.len() as u64;
        let mass = &ctx.particles.mass;
        let filter = &mut self.filter;
        let state = (&cur.pos, &cur.vel, w);
        filter.gather(
            h,
            ctx.contacts,
            state,
            |p| CONTACT_STIFFNESS * mass[p],
            None,
        );
        let term = (!self.self_contact.is_empty()).then_some(&self.self_contact);
        // Rounds after the first add their pairs to the unreduced right-hand side.
        let filtered = !filter.is_empty();
        if filtered && ctx.self_pairs.is_some() {
            if work.assembled.len() != n {
                work.assembled = Vec3s::zeros(n);
            }
            work.assembled.copy_from(&work.rhs);
        }
        if filtered {
            let (operator, chunk) = (
                WithSelfContacts {
                    matrix: &work.matrix,
                    term,
                },
                ctx.chunk,
            );
            filter.reduce(&mut work.rhs, |x, y| operator.apply(x, y, chunk));
        }

        self.stats.setup_seconds += started.elapsed().as_secs_f64();
        let settings = self.settings;
        // The first solve of a step that may hold more pairs after it only finds which pairs
        // its `dv` brings within `thickness`: loose, unless it turns out to be the last. With
        // no pair ahead (a cloth where nothing is close) there is none to find, and one solve
        // to `cg_tolerance` costs less than a loose one finished from where it stopped.
        let more_rounds = ctx.self_pairs.is_some_and(|p| !p.pairs.is_empty());
        let mut first = settings;
        if more_rounds {
            let loose = if ctx.may_stop_loose {
                CONTACT_FINDING_TOLERANCE
            } else {
                PAIR_FINDING_TOLERANCE
            };
            first.tolerance = settings.tolerance.max(loose);
        }
        self.first = first;
        let term = (!self.self_contact.is_empty()).then_some(&self.self_contact);
        let stats = (first, &mut self.stats);
        solve_once(work, term, &mut self.filter, stats, ctx.chunk, Start::Zero);
        self.loose = more_rounds && ctx.may_stop_loose && first.tolerance > settings.tolerance;
        if !self.loose {
            self.settle(h, ctx, first);
        }
        update(h, ctx, &self.work.as_ref().expect("assembled above").dv)
    }

    /// Whether the last step stopped at its loose pair-finding solve
    /// ([`StepContext::may_stop_loose`]): its result only shows where the step goes.
    pub fn stopped_loose(&self) -> bool {
        self.loose
    }

    /// Finishes a step that stopped at its loose pair-finding solve, its system (matrix,
    /// contacts, pairs held) as it left it: `ctx` must carry the same state, contacts and pairs.
    pub fn finish_loose(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        debug_assert!(self.loose, "no loose step to finish");
        self.loose = false;
        let first = self.first;
        self.settle(h, ctx, first);
        update(h, ctx, &self.work.as_ref().expect("a step assembled it").dv)
    }

    /// After the step's first solve (to `first`'s tolerance), holds the pairs its `dv` brought
    /// within `thickness` and solves the step again with them, or, where it brought none,
    /// finishes that solve to `cg_tolerance`: at most [`SELF_ROUNDS`] solves a step.
    fn settle(&mut self, h: f32, ctx: &StepContext, first: SolverSettings) {
        let settings = self.settings;
        let Some(pairs) = ctx.self_pairs else {
            return;
        };
        let Some(work) = self.work.as_mut() else {
            return;
        };
        let cur = ctx.current;
        let mut round = 1;
        while round < SELF_ROUNDS {
            let filtered = !self.filter.is_empty();
            let Work {
                matrix,
                rhs,
                assembled,
                dv,
                ..
            } = &mut *work;
            let loads = if filtered { assembled } else { rhs };
            let added = self.self_contact.extend(
                h,
                pairs,
                (&cur.pos, &cur.vel, dv),
                (matrix.slot_mut(0), loads),
            );
            self.stats.self_pairs += added as u64;
            if pairs.asked() {
                // The step is solved again with the pairs (`stepper/pipeline/solve.rs`).
                break;
            }
            let this = if round == 1 { first } else { settings };
            if added == 0 {
                // The loose solve's system is the step's: finish it from where it stopped (the
                // filtered unknown is `S dv`, the held particles' prescribed part taken out).
                if this.tolerance > settings.tolerance {
                    self.filter.project(&mut work.dv);
                    let term = (!self.self_contact.is_empty()).then_some(&self.self_contact);
                    let stats = (settings, &mut self.stats);
                    solve_once(work, term, &mut self.filter, stats, ctx.chunk, Start::Guess);
                }
                break;
            }
            if filtered {
                // The matrix changed with the pairs added: the prescribed motion's load too.
                work.rhs.copy_from(&work.assembled);
                let operator = WithSelfContacts {
                    matrix: &work.matrix,
                    term: Some(&self.self_contact),
                };
                let chunk = ctx.chunk;
                self.filter
                    .reduce(&mut work.rhs, |x, y| operator.apply(x, y, chunk));
            }
            let term = (!self.self_contact.is_empty()).then_some(&self.self_contact);
            let stats = (settings, &mut self.stats);
            solve_once(work, term, &mut self.filter, stats, ctx.chunk, Start::Zero);
            round += 1;
        }
    }
}

/// How many times at most implicit Euler solves a step with self-contact pairs held inside it:
/// after a solve, the pairs it brought within `thickness` are held too and the step is solved
/// again.
const SELF_ROUNDS: u32 = 2;

/// The relative residual `|r| / |b|` at which the first solve of a step holding self-contact
/// pairs stops when a second may follow (the scene's `cg_tolerance` where that is looser). Its
/// `dv` is not the step's: it only finds the pairs the solve brings within `thickness` (on a
/// wound twist most of those the step holds), and the second solve, from zero with them all,
/// meets `cg_tolerance`. A step whose first solve brings no new pair finishes that solve to
/// `cg_tolerance` from where it stopped. Trade-off: looser takes fewer iterations but finds the
/// pairs from a rougher `dv`, and the step's result moves with the pairs found (measured in
/// `docs/notes/contact.md`, "Where a frame goes"); at `cg_tolerance` it is two full solves.
const PAIR_FINDING_TOLERANCE: f32 = 3e-2;

/// The relative residual at which the first solve of a step holding self-contact pairs stops
/// where the caller may take it as the step's result only to correct the colliders' contacts
/// ([`StepContext::may_stop_loose`]). Its `dv` decides which contacts pull and which particles
/// it carries into a collider, and the last round's solve holds what it decided: at
/// [`PAIR_FINDING_TOLERANCE`] the built-in `pile` never came to rest (at 5 s 18 particles above
/// 0.1 m/s, up to 0.29 m/s), at 1e-2 not in one run of four, at 3e-3 in all four
/// (docs/notes/contact.md, "2026-12-06 (pilesettle)"). Trade-off: tighter costs iterations in
/// every such round.
const CONTACT_FINDING_TOLERANCE: f32 = 3e-3;

/// `v' = v + dv`, `x' = x + h v'` for free particles; held ones keep their state bitwise.
/// Returns whether everything written is finite.
fn update(h: f32, ctx: &mut StepContext, dv: &Vec3s) -> bool {
    let (cur, w) = (ctx.current, &ctx.particles.inv_mass);
    par_update(ctx.next, ctx.chunk, |mut out| {
        let mut check = FiniteCheck::default();
        for (i, p) in out.range.clone().enumerate() {
            let (x, v) = (cur.pos.get(p), cur.vel.get(p));
            let (x_new, v_new) = if w[p] > 0.0 {
                let v_new = v + dv.get(p);
                (x + h * v_new, v_new)
            } else {
                (x, v)
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

/// The blocks `-C_s` of every spring of `kind` into the matrix slot `slot` (unfiltered), and
/// `K_s (v_a - v_b)` into `kv`, with `C_s = alpha u u^T + beta I`, `alpha = h c + h^2 k (1 - g)`,
/// `beta = h^2 k g`, `K_s = C_s - h c u u^T`. Slots with no live spring get zeros.
#[allow(clippy::too_many_arguments)]
fn build_blocks(
    matrix: &mut BlockStencil,
    kv: &mut [Vec3s; 6],
    kind: SpringKind,
    slot: usize,
    h: f32,
    k: f32,
    c: f32,
    ctx: &StepContext,
) {
    let n = ctx.grid.len();
    let o = ctx.grid.offset(kind);
    let ki = kind.index();
    let (pos, vel, springs) = (&ctx.current.pos, &ctx.current.vel, ctx.springs);
    let (rest, active) = (&springs.rest[ki], &springs.active[ki]);
    let chunk = ctx.chunk;
    par_chunks6(matrix.slot_mut(slot), chunk)
        .zip(kv[ki].par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(ci, ([bxx, byy, bzz, bxy, bxz, byz], mut kv))| {
            // Slots whose partner would be off the end hold no spring.
            let start = ci * chunk;
            let run = anchored_run(n, o, start..start + bxx.len());
            let (len, s, t) = (run.len, run.a_range(), run.b_range());
            let (xa, xb) = (pos.slices(s.clone()), pos.slices(t.clone()));
            let (va, vb) = (vel.slices(s.clone()), vel.slices(t));
            let (rest, active) = (&rest[s.clone()], &active[s]);
            crate::simd::dispatch!({
                for i in 0..len {
                    let (dx, dy, dz) = (xb.x[i] - xa.x[i], xb.y[i] - xa.y[i], xb.z[i] - xa.z[i]);
                    let l = (dx * dx + dy * dy + dz * dz).sqrt();
                    let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                    let g = (1.0 - rest[i] * inv_l).max(0.0) * (l > 0.0) as u32 as f32;
                    let alpha = h * c + h * h * k * (1.0 - g);
                    let beta = h * h * k * g;
                    let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
                    let live = active[i] != 0.0;
                    bxx[i] = live_or_zero(live, -(alpha * ux * ux + beta));
                    byy[i] = live_or_zero(live, -(alpha * uy * uy + beta));
                    bzz[i] = live_or_zero(live, -(alpha * uz * uz + beta));
                    bxy[i] = live_or_zero(live, -(alpha * ux * uy));
                    bxz[i] = live_or_zero(live, -(alpha * ux * uz));
                    byz[i] = live_or_zero(live, -(alpha * uy * uz));
                    // K (v_a - v_b): the damping part h c u u^T has no x-derivative.
                    let (wx, wy, wz) = (va.x[i] - vb.x[i], va.y[i] - vb.y[i], va.z[i] - vb.z[i]);
                    let along = (alpha - h * c) * (ux * wx + uy * wy + uz * wz);
                    kv.x[i] = live_or_zero(live, along * ux + beta * wx);
                    kv.y[i] = live_or_zero(live, along * uy + beta * wy);
                    kv.z[i] = live_or_zero(live, along * uz + beta * wz);
                }
            });
            for b in [bxx, byy, bzz, bxy, bxz, byz] {
                b[len..].fill(0.0);
            }
            kv.sub_mut(len..kv.len()).fill(glam::Vec3::ZERO);
        });
}

/// The diagonal blocks `D_a = (m_a + h drag) I + sum_s C_s` and the right-hand side
/// `b_a = h f_a - sum_s K_s (v_a - v_other)` (gathered over the springs each particle anchors and
/// ends, from the unfiltered blocks); zero for held particles.
fn assemble_diagonal_and_rhs(work: &mut Work, h: f32, drag: f32, ctx: &StepContext) {
    let Work {
        matrix,
        kinds,
        kv,
        rhs,
        ..
    } = work;
    let (grid_n, chunk) = (ctx.grid.len(), ctx.chunk);
    let (force, mass, w) = (&*ctx.force, &ctx.particles.mass, &ctx.particles.inv_mass);
    let mut diag = std::mem::take(matrix.slot_mut(0));
    let matrix = &*matrix;
    par_chunks6(&mut diag, chunk)
        .zip(rhs.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(ci, (mut d, mut b))| {
            let range = ci * chunk..ci * chunk + d[0].len();
            crate::simd::dispatch!({
                let f = force.slices(range.clone());
                for (i, p) in range.clone().enumerate() {
                    let m = mass[p] + h * drag;
                    d[0][i] = m;
                    d[1][i] = m;
                    d[2][i] = m;
                    d[3][i] = 0.0;
                    d[4][i] = 0.0;
                    d[5][i] = 0.0;
                    b.x[i] = h * f.x[i];
                    b.y[i] = h * f.y[i];
                    b.z[i] = h * f.z[i];
                }
                for &(kind, slot) in kinds.iter() {
                    let o = ctx.grid.offset(kind);
                    let blocks = matrix.slot(slot);
                    let kv = &kv[kind.index()];
                    for (end, run) in neighbour_runs(grid_n, o, range.clone())
                        .into_iter()
                        .enumerate()
                    {
                        let Some(run) = run else { continue };
                        let (s, dst) = (run.spring..run.spring + run.len, run.a - range.start);
                        for c in 0..6 {
                            // The stored block is -C_s.
                            for (t, &v) in d[c][dst..dst + run.len]
                                .iter_mut()
                                .zip(&blocks[c][s.clone()])
                            {
                                *t -= v;
                            }
                        }
                        // +K (v_a - v_b) for the anchor, -K (v_a - v_b) for the far end.
                        let sign = if end == 0 { -1.0 } else { 1.0 };
                        let kv = kv.slices(s.clone());
                        for (out, kv) in [(&mut *b.x, kv.x), (&mut *b.y, kv.y), (&mut *b.z, kv.z)] {
                            for (t, &v) in out[dst..dst + run.len].iter_mut().zip(kv) {
                                *t += sign * v;
                            }
                        }
                    }
                }
                for (i, p) in range.clone().enumerate() {
                    if w[p] == 0.0 {
                        for dc in d.iter_mut() {
                            dc[i] = 0.0;
                        }
                        b.set(i, glam::Vec3::ZERO);
                    }
                }
            });
        });
    *work.matrix.slot_mut(0) = diag;
}

/// Adds `k n n^T` (`k = CONTACT_STIFFNESS m`, the `h^2 k_c` of a stiff spring onto the plane;
/// `k I` for a sticking contact) to the diagonal block of each free particle with a predicted
/// contact, and a sliding contact's friction damper (part of the system, unlike `k`). The contact itself is the [`ContactFilter`]'s, exact; `S (k n n^T) S = 0`, so this
/// leaves the filtered system as it is, but the preconditioner built on the matrix then sees the
/// particle as held where the filtered system holds it.
fn stiffen_contacts(work: &mut Work, contacts: &PredictedContacts, ctx: &StepContext) {
    let (mass, w) = (&ctx.particles.mass, &ctx.particles.inv_mass);
    let Work { matrix, .. } = work;
    let mut diag = std::mem::take(matrix.slot_mut(0));
    par_chunks6(&mut diag, ctx.chunk)
        .enumerate()
        .for_each(|(ci, mut d)| {
            for i in 0..d[0].len() {
                let p = ci * ctx.chunk + i;
                if contacts.normal.get(p) == glam::Vec3::ZERO || w[p] == 0.0 {
                    continue;
                }
                let s = CONTACT_STIFFNESS * mass[p];
                let block = contacts.held_directions(p).0;
                for (column, v) in d.iter_mut().zip(block) {
                    column[i] += s * v;
                }
                if let Some(damper) = contacts.slide_block(p) {
                    for (column, v) in d.iter_mut().zip(damper.0) {
                        column[i] += v;
                    }
                }
            }
        });
    *matrix.slot_mut(0) = diag;
}

/// Zeroes the coupling blocks of every spring with a held end: the filtered matrix.
fn filter_couplings(work: &mut Work, ctx: &StepContext) {
    let (grid_n, chunk) = (ctx.grid.len(), ctx.chunk);
    let w = &ctx.particles.inv_mass;
    for &(kind, slot) in &work.kinds {
        let o = ctx.grid.offset(kind);
        par_chunks6(work.matrix.slot_mut(slot), chunk)
            .enumerate()
            .for_each(|(ci, blocks)| {
                let start = ci * chunk;
                // Anchors whose partner exists; the blocks past them are zero already.
                let run = anchored_run(grid_n, o, start..start + blocks[0].len());
                let (wa, wb) = (&w[run.a_range()], &w[run.b_range()]);
                let len = run.len;
                crate::simd::dispatch!({
                    for comp in blocks {
                        for ((x, wa), wb) in comp[..len].iter_mut().zip(wa).zip(wb) {
                            *x = live_or_zero(*wa != 0.0 && *wb != 0.0, *x);
                        }
                    }
                })
            });
    }
}

/// The preconditioner's setup and one CG solve of `work`'s system (with the self-contact
/// couplings `term` in its product, and the collider contacts' `filter`) into `work.dv`, from
/// `start` (from the last `dv` without a new setup).
fn solve_once(
    work: &mut Work,
    term: Option<&SelfContactTerm>,
    filter: &mut ContactFilter,
    (settings, stats): (SolverSettings, &mut SolverStats),
    chunk: usize,
    start: Start,
) {
    let started = Instant::now();
    match settings.preconditioner {
        _ if start == Start::Guess => {}
        Preconditioner::Jacobi => {
            let d = work.matrix.slot(0);
            for (c, out) in work.jacobi.iter_mut().enumerate() {
                for (p, o) in out.iter_mut().enumerate() {
                    *o = if c < 3 && d[c][p] > 0.0 {
                        1.0 / d[c][p]
                    } else {
                        0.0
                    };
                }
            }
        }
        Preconditioner::BlockJacobi => work.matrix.diagonal_inverse(&mut work.jacobi, chunk),
        Preconditioner::Multigrid => work.multigrid.build(&work.matrix, chunk),
    }
    let solving = Instant::now();
    stats.setup_seconds += (solving - started).as_secs_f64();
    let Work {
        matrix,
        jacobi,
        multigrid,
        rhs,
        dv,
        cg,
        ..
    } = work;
    let matrix = &*matrix;
    let operator = WithSelfContacts { matrix, term };
    let precondition = |r: &Vec3s, z: &mut Vec3s| match settings.preconditioner {
        Preconditioner::Multigrid => multigrid.apply(matrix, r, z, chunk),
        Preconditioner::Jacobi | Preconditioner::BlockJacobi => diagonal_blocks(jacobi, r, z),
    };
    let limits = (settings.tolerance as f64, settings.max_iterations);
    // Without contacts the filter projects nothing: the plain preconditioned CG.
    let project = &*filter;
    let (iterations, residual) = cg.solve_filtered(
        &operator,
        rhs,
        dv,
        limits,
        precondition,
        |v| project.project(v),
        start,
    );
    if !filter.is_empty() {
        filter.finish(dv, |x, y| operator.apply(x, y, chunk));
    }
    stats.solve_seconds += solving.elapsed().as_secs_f64();
    stats.record(iterations, residual, settings.tolerance as f64);
}
