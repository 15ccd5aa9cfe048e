//! Backward Euler, linearised once per step (Baraff and Witkin, "Large steps in cloth
//! simulation", SIGGRAPH 1998), solved by a matrix-free, Jacobi-preconditioned conjugate
//! gradient.

use rayon::prelude::*;

use super::{par_update, FiniteCheck, Integrator, StepContext};
use crate::forces::springs::neighbour_runs;
use crate::forces::Linearization;
use crate::grid::SpringKind;
use crate::soa::Vec3s;

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
    rhs: Vec3s,
    dv: Vec3s,
    r: Vec3s,
    z: Vec3s,
    p: Vec3s,
    q: Vec3s,
    diag: Vec3s,
    partials: Vec<f64>,
}

/// Particles per partial sum of a dot product: fixed, so that sums are bitwise the same for
/// any number of threads.
const REDUCE_CHUNK: usize = 4096;

impl Work {
    fn new(n: usize) -> Self {
        Work {
            alpha: Default::default(),
            beta: Default::default(),
            u: Default::default(),
            kinds: Vec::new(),
            rhs: Vec3s::zeros(n),
            dv: Vec3s::zeros(n),
            r: Vec3s::zeros(n),
            z: Vec3s::zeros(n),
            p: Vec3s::zeros(n),
            q: Vec3s::zeros(n),
            diag: Vec3s::zeros(n),
            partials: vec![0.0; n.div_ceil(REDUCE_CHUNK)],
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

    pub fn stats(&self) -> SolverStats {
        self.stats
    }
}

impl Integrator for ImplicitEuler {
    fn name(&self) -> &'static str {
        "implicit_euler"
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        Some(self.stats)
    }

    fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        let n = ctx.current.pos.len();
        let work = self.work.get_or_insert_with(|| Work::new(n));
        ctx.eval_forces_at(ctx.current);

        // Which terms depend on the state, and how.
        let mut drag = 0.0f32;
        work.kinds.clear();
        for lin in ctx.forces.linearizations() {
            match lin {
                Linearization::Constant => {}
                Linearization::Drag { c } => drag += c,
                Linearization::Springs { family, k, c } => {
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
        let offsets: Vec<(usize, usize)> = work
            .kinds
            .iter()
            .map(|&(kind, _)| (kind.index(), ctx.grid.offset(kind)))
            .collect();

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
                for (i, p) in range.clone().enumerate() {
                    b.set(i, h * f.get(p));
                    let m = mass[p] + h * drag;
                    d.set(i, glam::Vec3::splat(m));
                }
                for (&(k, o), &(_, hc)) in offsets.iter().zip(kinds.iter()) {
                    for run in neighbour_runs(grid_n, o, range.clone())
                        .into_iter()
                        .flatten()
                    {
                        for t in 0..run.len {
                            let (a, nb, s) = (run.a + t, run.b + t, run.spring + t);
                            let (al, be, us) = (alpha[k][s], beta[k][s], u[k].get(s));
                            // K = C - h c u u^T (the damping part has no x-derivative).
                            let alpha_k = al - hc * springs.active[k][s];
                            let dvel = vel.get(a) - vel.get(nb);
                            let kv = be * dvel + alpha_k * us.dot(dvel) * us;
                            let i = a - range.start;
                            b.set(i, b.get(i) - kv);
                            d.set(i, d.get(i) + glam::Vec3::splat(be) + al * us * us);
                        }
                    }
                }
                for (i, p) in range.enumerate() {
                    if w[p] == 0.0 {
                        b.set(i, glam::Vec3::ZERO); // held particles: filtered out
                    }
                }
            });
        }

        // Preconditioned conjugate gradient from dv = 0.
        let settings = self.settings;
        let product = |work: &mut Work| {
            let Work {
                alpha,
                beta,
                u,
                p,
                q,
                ..
            } = work;
            let p = &*p;
            q.par_chunks_mut(chunk).enumerate().for_each(|(c, mut q)| {
                let range = c * chunk..c * chunk + q.len();
                for (i, a) in range.clone().enumerate() {
                    q.set(i, (mass[a] + h * drag) * p.get(a));
                }
                for &(k, o) in &offsets {
                    for run in neighbour_runs(grid_n, o, range.clone())
                        .into_iter()
                        .flatten()
                    {
                        for t in 0..run.len {
                            let (a, nb, s) = (run.a + t, run.b + t, run.spring + t);
                            let dp = p.get(a) - p.get(nb);
                            let us = u[k].get(s);
                            let i = a - range.start;
                            q.set(
                                i,
                                q.get(i) + beta[k][s] * dp + alpha[k][s] * us.dot(dp) * us,
                            );
                        }
                    }
                }
                for (i, a) in range.enumerate() {
                    if w[a] == 0.0 {
                        q.set(i, glam::Vec3::ZERO);
                    }
                }
            });
        };
        work.dv.fill(glam::Vec3::ZERO);
        work.r.copy_from(&work.rhs);
        precondition(&work.r, &work.diag, &mut work.z);
        work.p.copy_from(&work.z);
        let b_norm = dot(&work.rhs, &work.rhs, &mut work.partials).sqrt();
        let mut rz = dot(&work.r, &work.z, &mut work.partials);
        let mut residual = if b_norm > 0.0 { 1.0 } else { 0.0 };
        let mut iterations = 0;
        while residual > settings.tolerance as f64 && iterations < settings.max_iterations {
            product(work);
            let pq = dot(&work.p, &work.q, &mut work.partials);
            if pq <= 0.0 || !pq.is_finite() {
                break; // breakdown: the matrix is not positive definite along p
            }
            let step = (rz / pq) as f32;
            axpy(&mut work.dv, step, &work.p);
            axpy(&mut work.r, -step, &work.q);
            iterations += 1;
            residual = dot(&work.r, &work.r, &mut work.partials).sqrt() / b_norm;
            precondition(&work.r, &work.diag, &mut work.z);
            let rz_new = dot(&work.r, &work.z, &mut work.partials);
            let beta = (rz_new / rz) as f32;
            rz = rz_new;
            // p = z + beta p
            let Work { p, z, .. } = work;
            let z = &*z;
            p.par_chunks_mut(chunk).enumerate().for_each(|(c, mut p)| {
                for i in 0..p.len() {
                    let a = c * chunk + i;
                    p.set(i, z.get(a) + beta * p.get(i));
                }
            });
        }
        self.stats.solves += 1;
        self.stats.iterations += iterations as u64;
        self.stats.last_iterations = iterations;
        self.stats.last_residual = residual as f32;
        if residual > settings.tolerance as f64 {
            self.stats.not_converged += 1;
        }

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
        .for_each(|(ci, ((alpha, beta), mut u))| {
            for i in 0..alpha.len() {
                let s = ci * chunk + i;
                if active[s] == 0.0 || s + o >= n {
                    alpha[i] = 0.0;
                    beta[i] = 0.0;
                    u.set(i, glam::Vec3::ZERO);
                    continue;
                }
                let d = pos.get(s + o) - pos.get(s);
                let l = d.length();
                let dir = if l > 0.0 { d / l } else { glam::Vec3::ZERO };
                let g = if l > 0.0 {
                    (1.0 - rest[s] / l).max(0.0)
                } else {
                    0.0
                };
                alpha[i] = h * c + h * h * k * (1.0 - g);
                beta[i] = h * h * k * g;
                u.set(i, dir);
            }
        });
}

fn precondition(r: &Vec3s, diag: &Vec3s, z: &mut Vec3s) {
    for (z, (r, d)) in [
        (&mut z.x, (&r.x, &diag.x)),
        (&mut z.y, (&r.y, &diag.y)),
        (&mut z.z, (&r.z, &diag.z)),
    ] {
        z.par_iter_mut()
            .zip(r.par_iter())
            .zip(d.par_iter())
            .for_each(|((z, r), d)| *z = r / d);
    }
}

fn axpy(y: &mut Vec3s, a: f32, x: &Vec3s) {
    for (y, x) in [(&mut y.x, &x.x), (&mut y.y, &x.y), (&mut y.z, &x.z)] {
        y.par_iter_mut()
            .zip(x.par_iter())
            .for_each(|(y, x)| *y += a * x);
    }
}

/// `a . b` in f64, summed in fixed chunks so the result does not depend on the thread count.
fn dot(a: &Vec3s, b: &Vec3s, partials: &mut [f64]) -> f64 {
    let n = a.len();
    partials.par_iter_mut().enumerate().for_each(|(c, out)| {
        let range = c * REDUCE_CHUNK..((c + 1) * REDUCE_CHUNK).min(n);
        let mut sum = 0.0f64;
        for comp in 0..3 {
            let (x, y) = (a.component(comp, &range), b.component(comp, &range));
            sum += x.iter().zip(y).map(|(x, y)| (x * y) as f64).sum::<f64>();
        }
        *out = sum;
    });
    partials.iter().sum()
}
