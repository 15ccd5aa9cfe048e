//! Backward Euler, linearised once per step (Baraff and Witkin, "Large steps in cloth
//! simulation", SIGGRAPH 1998), solved by a matrix-free, Jacobi-preconditioned conjugate
//! gradient.

use rayon::prelude::*;

use super::{par_update, FiniteCheck, StepContext};
use crate::forces::Force;
use crate::grid::SpringKind;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::{anchored_run, neighbour_runs, SpringRun as Run};

/// Settings of the linear solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// Relative residual `|r| / |b|` at which CG stops. Default 1e-4: well below the step's
    /// own linearisation error; float32 arithmetic stalls a little below 1e-6.
    pub tolerance: f32,
    /// Most CG iterations per step. Default 200. A solve that hits the cap is used (it is still
    /// a descent step) but counted in `profile()` as not converged.
    pub max_iterations: u32,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-4,
            max_iterations: 200,
        }
    }
}

/// What the solver did, accumulated since the integrator was created.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolverStats {
    pub solves: u64,
    pub iterations: u64,
    pub last_iterations: u32,
    /// `|r| / |b|` at the end of the last solve.
    pub last_residual: f32,
    /// Solves that stopped at the iteration cap above the tolerance.
    pub not_converged: u64,
    /// The largest final `|r| / |b|` among those.
    pub worst_residual: f32,
}

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
/// compressed springs (the standard fix that keeps the matrix positive definite). Pinned and
/// cut particles are held by filtering: their rows and columns are removed from the solve.
///
/// Unconditionally stable and first order: it damps, strongly at large steps. Cost per step is
/// one force evaluation plus one matrix-vector product per CG iteration.
pub struct ImplicitEuler {
    settings: SolverSettings,
    stats: SolverStats,
    work: Option<Work>,
}

/// Per-spring blocks `C = alpha u u^T + beta I` of `h D + h^2 K`, and the CG vectors.
struct Work {
    alpha: [Vec<f32>; 6],
    beta: [Vec<f32>; 6],
    u: [Vec3s; 6],
    /// Which spring kinds take part, with their family's `h c` (damping part of `alpha`).
    kinds: Vec<(SpringKind, f32)>,
    /// `(kind index, index offset)` of the same kinds (kept to reuse its allocation).
    offsets: Vec<(usize, usize)>,
    rhs: Vec3s,
    dv: Vec3s,
    r: Vec3s,
    z: Vec3s,
    p: Vec3s,
    q: Vec3s,
    diag: Vec3s,
    /// Per-chunk partial sums of one and of two dot products.
    partials: Vec<f64>,
    partials2: Vec<[f64; 2]>,
}

/// Particles per work item of the CG passes, and per partial sum of their dot products: fixed,
/// so that the sums are bitwise the same for any number of threads.
const REDUCE_CHUNK: usize = 1024;

impl Work {
    fn new(n: usize) -> Self {
        Work {
            alpha: Default::default(),
            beta: Default::default(),
            u: Default::default(),
            kinds: Vec::new(),
            offsets: Vec::new(),
            rhs: Vec3s::zeros(n),
            dv: Vec3s::zeros(n),
            r: Vec3s::zeros(n),
            z: Vec3s::zeros(n),
            p: Vec3s::zeros(n),
            q: Vec3s::zeros(n),
            diag: Vec3s::zeros(n),
            partials: vec![0.0; n.div_ceil(REDUCE_CHUNK)],
            partials2: vec![[0.0; 2]; n.div_ceil(REDUCE_CHUNK)],
        }
    }
}

impl ImplicitEuler {
    pub fn new(settings: SolverSettings) -> Self {
        ImplicitEuler {
            settings,
            stats: SolverStats::default(),
            work: None,
        }
    }
}

impl ImplicitEuler {
    pub fn solver_stats(&self) -> SolverStats {
        self.stats
    }

    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        let n = ctx.current.pos.len();
        let work = self.work.get_or_insert_with(|| Work::new(n));
        ctx.eval_forces_at(ctx.current);

        // Which terms depend on the state, and how.
        let mut drag = 0.0f32;
        work.kinds.clear();
        for &force in ctx.forces.forces() {
            match force {
                Force::Gravity { .. } => {}
                Force::Drag { c } => drag += c,
                Force::Springs { family, k, c } => {
                    for kind in family.kinds() {
                        work.kinds.push((kind, h * c));
                        build_blocks(work, kind, h, k, c, ctx);
                    }
                }
            }
        }

        let w = &ctx.particles.inv_mass;
        let mass = &ctx.particles.mass;
        let chunk = ctx.chunk;
        let grid_n = ctx.grid.len();
        work.offsets.clear();
        let grid = ctx.grid;
        work.offsets.extend(
            work.kinds
                .iter()
                .map(|&(kind, _)| (kind.index(), grid.offset(kind))),
        );
        let offsets = std::mem::take(&mut work.offsets);

        // Right-hand side b = h f - h^2 K v (K v gathered like a force), and the Jacobi
        // diagonal of A = M + h drag I + sum C.
        {
            let Work {
                alpha,
                beta,
                u,
                kinds,
                rhs,
                diag,
                ..
            } = work;
            let (f, vel, springs) = (&*ctx.force, &ctx.current.vel, ctx.springs);
            let rhs_and_diag = rhs.par_chunks_mut(chunk).zip(diag.par_chunks_mut(chunk));
            rhs_and_diag.enumerate().for_each(|(c, (mut b, mut d))| {
                let range = c * chunk..c * chunk + b.len();
                crate::simd::dispatch!({
                    for (comp, (b, d)) in [
                        (&mut *b.x, &mut *d.x),
                        (&mut *b.y, &mut *d.y),
                        (&mut *b.z, &mut *d.z),
                    ]
                    .into_iter()
                    .enumerate()
                    {
                        let f = f.component(comp, &range);
                        for (i, p) in range.clone().enumerate() {
                            b[i] = h * f[i];
                            d[i] = mass[p] + h * drag;
                        }
                    }
                    for (&(k, o), &(_, hc)) in offsets.iter().zip(kinds.iter()) {
                        let blocks = Blocks {
                            alpha: &alpha[k],
                            beta: &beta[k],
                            u: &u[k],
                        };
                        for run in neighbour_runs(grid_n, o, range.clone())
                            .into_iter()
                            .flatten()
                        {
                            // K = C - h c u u^T: the damping part has no x-derivative.
                            let stiffness_only = Some((hc, &springs.active[k][..]));
                            blocks.apply(run, vel, stiffness_only, -1.0, &mut b, range.start);
                            blocks.add_diagonal(run, &mut d, range.start);
                        }
                    }
                    filter_held(&mut b, &w[range.clone()]);
                })
            });
        }

        // Preconditioned conjugate gradient from dv = 0.
        let settings = self.settings;
        // q = A p, returning p . q.
        let product = |work: &mut Work| -> f64 {
            let Work {
                alpha,
                beta,
                u,
                p,
                q,
                partials,
                ..
            } = work;
            let p = &*p;
            q.par_chunks_mut(REDUCE_CHUNK)
                .zip(partials.par_iter_mut())
                .enumerate()
                .for_each(|(c, (mut q, partial))| {
                    let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + q.len();
                    *partial = crate::simd::dispatch!({
                        for (comp, q) in [&mut *q.x, &mut *q.y, &mut *q.z].into_iter().enumerate() {
                            let p = p.component(comp, &range);
                            for (i, a) in range.clone().enumerate() {
                                q[i] = (mass[a] + h * drag) * p[i];
                            }
                        }
                        for &(k, o) in &offsets {
                            let blocks = Blocks {
                                alpha: &alpha[k],
                                beta: &beta[k],
                                u: &u[k],
                            };
                            for run in neighbour_runs(grid_n, o, range.clone())
                                .into_iter()
                                .flatten()
                            {
                                blocks.apply(run, p, None, 1.0, &mut q, range.start);
                            }
                        }
                        filter_held(&mut q, &w[range.clone()]);
                        chunk_dot(p.slices(range.clone()), &q)
                    });
                });
            partials.iter().sum()
        };
        // Preconditioned conjugate gradient from dv = 0, three parallel passes per iteration
        // with the dot products fused into them. Partial sums are over fixed chunks and added
        // in order, so the solve is bitwise the same for any number of threads.
        let (b_dot_b, mut rz) = start_solve(work);
        let b_norm = b_dot_b.sqrt();
        let mut residual = if b_norm > 0.0 { 1.0 } else { 0.0 };
        let mut iterations = 0;
        while residual > settings.tolerance as f64 && iterations < settings.max_iterations {
            let pq = product(work);
            if pq <= 0.0 || !pq.is_finite() {
                break; // breakdown: the matrix is not positive definite along p
            }
            let (r_dot_r, rz_new) = advance_solution(work, (rz / pq) as f32);
            iterations += 1;
            residual = r_dot_r.sqrt() / b_norm;
            if residual <= settings.tolerance as f64 {
                break;
            }
            next_direction(work, (rz_new / rz) as f32);
            rz = rz_new;
        }
        self.stats.solves += 1;
        self.stats.iterations += iterations as u64;
        self.stats.last_iterations = iterations;
        self.stats.last_residual = residual as f32;
        if residual > settings.tolerance as f64 {
            self.stats.not_converged += 1;
            self.stats.worst_residual = self.stats.worst_residual.max(residual as f32);
        }

        work.offsets = offsets; // hand the allocation back for the next step

        // v' = v + dv, x' = x + h v'.
        let (cur, dv) = (ctx.current, &work.dv);
        par_update(ctx.next, chunk, |mut out| {
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
}

/// One spring kind's blocks `C_s = alpha_s u_s u_s^T + beta_s I`, indexed by spring slot.
struct Blocks<'a> {
    alpha: &'a [f32],
    beta: &'a [f32],
    u: &'a Vec3s,
}

impl Blocks<'_> {
    /// `out[a] += scale * C_s (p_a - p_b)` over a run of particles `a` with neighbours `b`.
    /// With `stiffness_only = Some((h c, active))`, the damping part `h c u u^T` is left out of
    /// `C`, which leaves `h^2 K`.
    #[inline(always)]
    fn apply(
        &self,
        run: Run,
        p: &Vec3s,
        stiffness_only: Option<(f32, &[f32])>,
        scale: f32,
        out: &mut Vec3SliceMut,
        out_start: usize,
    ) {
        let n = run.len;
        let (a, b, s) = (
            run.a..run.a + n,
            run.b..run.b + n,
            run.spring..run.spring + n,
        );
        let (pax, pay, paz) = (p.component(0, &a), p.component(1, &a), p.component(2, &a));
        let (pbx, pby, pbz) = (p.component(0, &b), p.component(1, &b), p.component(2, &b));
        let (ux, uy, uz) = (
            self.u.component(0, &s),
            self.u.component(1, &s),
            self.u.component(2, &s),
        );
        let (alpha, beta) = (&self.alpha[s.clone()], &self.beta[s.clone()]);
        let (cut, active) = match stiffness_only {
            Some((hc, active)) => (hc, &active[s]),
            None => (0.0, alpha), // any slice of the right length: multiplied by zero
        };
        let o = a.start - out_start..a.end - out_start;
        let (ox, oy, oz) = (&mut out.x[o.clone()], &mut out.y[o.clone()], &mut out.z[o]);
        for i in 0..n {
            let (dx, dy, dz) = (pax[i] - pbx[i], pay[i] - pby[i], paz[i] - pbz[i]);
            let along = (alpha[i] - cut * active[i]) * (ux[i] * dx + uy[i] * dy + uz[i] * dz);
            ox[i] += scale * (beta[i] * dx + along * ux[i]);
            oy[i] += scale * (beta[i] * dy + along * uy[i]);
            oz[i] += scale * (beta[i] * dz + along * uz[i]);
        }
    }

    /// `out[a] += diag(C_s)` over a run.
    #[inline(always)]
    fn add_diagonal(&self, run: Run, out: &mut Vec3SliceMut, out_start: usize) {
        let n = run.len;
        let s = run.spring..run.spring + n;
        let (alpha, beta) = (&self.alpha[s.clone()], &self.beta[s.clone()]);
        let o = run.a - out_start..run.a - out_start + n;
        for (comp, out) in [&mut *out.x, &mut *out.y, &mut *out.z]
            .into_iter()
            .enumerate()
        {
            let (u, out) = (self.u.component(comp, &s), &mut out[o.clone()]);
            for i in 0..n {
                out[i] += beta[i] + alpha[i] * u[i] * u[i];
            }
        }
    }
}

/// Zeroes the rows of held particles (`inv_mass == 0`): they are filtered out of the solve.
#[inline(always)]
fn filter_held(v: &mut Vec3SliceMut, inv_mass: &[f32]) {
    for comp in [&mut *v.x, &mut *v.y, &mut *v.z] {
        for (x, w) in comp.iter_mut().zip(inv_mass) {
            *x = if *w == 0.0 { 0.0 } else { *x };
        }
    }
}

/// The blocks of every spring of `kind` at the current state.
fn build_blocks(work: &mut Work, kind: SpringKind, h: f32, k: f32, c: f32, ctx: &StepContext) {
    let n = ctx.grid.len();
    let o = ctx.grid.offset(kind);
    let ki = kind.index();
    let (pos, springs) = (&ctx.current.pos, ctx.springs);
    if work.alpha[ki].len() != n {
        work.alpha[ki] = vec![0.0; n];
        work.beta[ki] = vec![0.0; n];
        work.u[ki] = Vec3s::zeros(n);
    }
    let (rest, active) = (&springs.rest[ki], &springs.active[ki]);
    let chunk = ctx.chunk;
    let (alpha, beta, u) = (&mut work.alpha[ki], &mut work.beta[ki], &mut work.u[ki]);
    alpha
        .par_chunks_mut(chunk)
        .zip(beta.par_chunks_mut(chunk))
        .zip(u.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(ci, ((alpha, beta), u))| {
            // Slots whose partner would be off the end hold no spring (active = 0).
            let start = ci * chunk;
            let run = anchored_run(n, o, start..start + alpha.len());
            let (s, t, len) = (run.a_range(), run.b_range(), run.len);
            let (ax, ay, az) = (
                pos.component(0, &s),
                pos.component(1, &s),
                pos.component(2, &s),
            );
            let (bx, by, bz) = (
                pos.component(0, &t),
                pos.component(1, &t),
                pos.component(2, &t),
            );
            let (rest, active) = (&rest[s.clone()], &active[s]);
            crate::simd::dispatch!({
                for i in 0..len {
                    let (dx, dy, dz) = (bx[i] - ax[i], by[i] - ay[i], bz[i] - az[i]);
                    let l = (dx * dx + dy * dy + dz * dz).sqrt();
                    let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                    let g = (1.0 - rest[i] * inv_l).max(0.0) * (l > 0.0) as u32 as f32;
                    alpha[i] = active[i] * (h * c + h * h * k * (1.0 - g));
                    beta[i] = active[i] * (h * h * k * g);
                    // A dead slot's direction is zero: its far end may be a cut particle
                    // anywhere, whose direction is not finite (and 0 * NaN is NaN).
                    let live = active[i] != 0.0;
                    let dead = |u: f32| if live { u } else { 0.0 };
                    u.x[i] = dead(dx * inv_l);
                    u.y[i] = dead(dy * inv_l);
                    u.z[i] = dead(dz * inv_l);
                }
            });
            alpha[len..].fill(0.0);
            beta[len..].fill(0.0);
            for comp in [&mut *u.x, &mut *u.y, &mut *u.z] {
                comp[len..].fill(0.0);
            }
        });
}

/// `dv = 0, r = b, z = P^-1 r, p = z`; returns `(b . b, r . z)`.
fn start_solve(work: &mut Work) -> (f64, f64) {
    let Work {
        rhs,
        diag,
        dv,
        r,
        z,
        p,
        partials2,
        ..
    } = work;
    let (rhs, diag) = (&*rhs, &*diag);
    dv.fill(glam::Vec3::ZERO);
    r.copy_from(rhs);
    z.par_chunks_mut(REDUCE_CHUNK)
        .zip(partials2.par_iter_mut())
        .enumerate()
        .for_each(|(c, (z, partial))| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + z.len();
            let (b, d) = (rhs.slices(range.clone()), diag.slices(range));
            let mut sums = [0.0f64; 2];
            for (z, b, d) in [(z.x, b.x, d.x), (z.y, b.y, d.y), (z.z, b.z, d.z)] {
                for i in 0..z.len() {
                    z[i] = b[i] / d[i];
                }
                sums[0] += dot(b, b);
                sums[1] += dot(b, z);
            }
            *partial = sums;
        });
    p.copy_from(z);
    sum_pairs(partials2)
}

/// `dv += step p, r -= step q, z = P^-1 r`; returns `(r . r, r . z)`.
fn advance_solution(work: &mut Work, step: f32) -> (f64, f64) {
    let Work {
        dv,
        r,
        z,
        p,
        q,
        diag,
        partials2,
        ..
    } = work;
    let (p, q, diag) = (&*p, &*q, &*diag);
    let chunks = dv
        .par_chunks_mut(REDUCE_CHUNK)
        .zip(r.par_chunks_mut(REDUCE_CHUNK));
    chunks
        .zip(z.par_chunks_mut(REDUCE_CHUNK))
        .zip(partials2.par_iter_mut())
        .enumerate()
        .for_each(|(c, (((dv, r), z), partial))| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + dv.len();
            *partial = crate::simd::dispatch!({
                let mut sums = [0.0f64; 2];
                let (p, q, d) = (
                    p.slices(range.clone()),
                    q.slices(range.clone()),
                    diag.slices(range),
                );
                for (dv, r, z, p, q, d) in [
                    (dv.x, r.x, z.x, p.x, q.x, d.x),
                    (dv.y, r.y, z.y, p.y, q.y, d.y),
                    (dv.z, r.z, z.z, p.z, q.z, d.z),
                ] {
                    for i in 0..dv.len() {
                        dv[i] += step * p[i];
                        r[i] -= step * q[i];
                        z[i] = r[i] / d[i];
                    }
                    sums[0] += dot(r, r);
                    sums[1] += dot(r, z);
                }
                sums
            });
        });
    sum_pairs(partials2)
}

/// `p = z + beta p`.
fn next_direction(work: &mut Work, beta: f32) {
    let Work { p, z, .. } = work;
    let z = &*z;
    p.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, p)| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + p.len();
            let z = z.slices(range);
            for (p, z) in [(p.x, z.x), (p.y, z.y), (p.z, z.z)] {
                for i in 0..p.len() {
                    p[i] = z[i] + beta * p[i];
                }
            }
        });
}

/// Dot product of one chunk's three components, in f64.
#[inline(always)]
fn chunk_dot(a: crate::soa::Vec3Slice, b: &Vec3SliceMut) -> f64 {
    dot(a.x, b.x) + dot(a.y, b.y) + dot(a.z, b.z)
}

/// `a . b`: sixteen independent float32 lanes (so the loop vectorises without reordering any
/// sum, and every instruction set gives the same bits), added up in f64 at the end.
#[inline(always)]
fn dot(a: &[f32], b: &[f32]) -> f64 {
    const LANES: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0.0f32; LANES];
    let whole = n / LANES * LANES;
    for (x, y) in a[..whole]
        .chunks_exact(LANES)
        .zip(b[..whole].chunks_exact(LANES))
    {
        for l in 0..LANES {
            lanes[l] += x[l] * y[l];
        }
    }
    let tail: f64 = a[whole..]
        .iter()
        .zip(&b[whole..])
        .map(|(x, y)| (x * y) as f64)
        .sum();
    lanes.iter().map(|&l| l as f64).sum::<f64>() + tail
}

fn sum_pairs(partials: &[[f64; 2]]) -> (f64, f64) {
    partials
        .iter()
        .fold((0.0, 0.0), |acc, s| (acc.0 + s[0], acc.1 + s[1]))
}
