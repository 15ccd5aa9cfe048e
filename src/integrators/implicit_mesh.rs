//! Implicit Euler on a mesh cloth: the grid's equations ([`super::ImplicitEuler`]) over the
//! mesh's spring list, assembled into a [`SpringMatrix`] (one symmetric 3 x 3 block per spring
//! and per vertex) and solved by the same preconditioned conjugate gradient.
//!
//! **Preconditioners.** `jacobi` and `block_jacobi` are the grid's. The grid's default,
//! `multigrid`, is a geometric hierarchy of the stencil; a mesh has none, so on a mesh it is
//! block Jacobi plus the sparse Cholesky factor of the matrix's isotropic part, added
//! (`z = D^-1 r + P^-1 r`, symmetric positive definite as each term is),
//!
//! ```text
//! P = M + h c_d I + sum_s (h c_s + h^2 k_s) A_s^T A_s        (one scalar for x, y and z)
//! ```
//!
//! over the free vertices, ordered by nested dissection of the rest shape
//! ([`crate::linear::dissect_points`]). Each spring's block of the true matrix,
//! `C_s = (h c_s + h^2 k_s (1 - g)) u u^T + h^2 k_s g I`, lies between zero and its block of `P`:
//! `P` holds the stiff in-plane stretching the Jacobi preconditioners leave to CG, but overstates
//! the out-of-plane stiffness of a slack cloth (`g` near 0, where the matrix is near `M`), which
//! the block-Jacobi term covers (alone, `P` took 93 iterations a solve on a stiff 1k-vertex
//! mesh; with block Jacobi, 23). `P` depends only on the step, the masses, the pins and the
//! material: it is factored once and refactored only when one of those changes. Predicted
//! contacts (`k_c n n^T` on a vertex's diagonal) are in the block-Jacobi term only.
//!
//! Every sum has a fixed order (per spring, then per vertex over its springs in spring order;
//! the factor's solve is serial), so a step is bitwise the same for any number of threads.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::solver::{live_or_zero, Preconditioner, SolverSettings, SolverStats, CONTACT_STIFFNESS};
use super::StepContext;
use crate::collisions::PredictedContacts;
use crate::linear::cg::{diagonal_blocks, ConjugateGradient};
use crate::linear::stencil::SlotArrays;
use crate::linear::{dissect_points, SparseCholesky, SpringMatrix, Sym3};
use crate::mesh_cloth::MeshCloth;
use crate::soa::{Floats, Vec3s};

/// Springs per parallel work item of the per-spring pass.
const SPRING_CHUNK: usize = 4096;

/// The mesh's system and the solver's vectors, kept between steps.
pub(super) struct MeshSystem {
    matrix: SpringMatrix,
    /// Per spring, its unfiltered block `C_s` and `K_s (v_a - v_b)`.
    blocks: Vec<Sym3>,
    kv: Vec<Vec3>,
    pub(super) rhs: Vec3s,
    pub(super) dv: Vec3s,
    /// Scratch for the preconditioner.
    extra: Vec3s,
    cg: ConjugateGradient,
    /// The Jacobi preconditioners' inverse diagonal blocks.
    jacobi: SlotArrays,
    /// The rest shape's nested-dissection order, made with the first factor.
    order: Vec<usize>,
    /// The factor of `P` and what it was built from.
    factor: Option<(FactorKey, SparseCholesky)>,
}

/// Everything `P` is built from.
#[derive(PartialEq)]
struct FactorKey {
    h: u32,
    drag: u32,
    mass: Vec<f32>,
    inv_mass: Vec<f32>,
    /// Which springs hold: a cut or a tear changes `P`.
    active: Vec<bool>,
}

impl FactorKey {
    fn of(h: f32, drag: f32, ctx: &StepContext) -> Self {
        FactorKey {
            active: ctx.mesh.map_or_else(Vec::new, |m| m.springs.active.clone()),
            h: h.to_bits(),
            drag: drag.to_bits(),
            mass: ctx.particles.mass.to_vec(),
            inv_mass: ctx.particles.inv_mass.to_vec(),
        }
    }

    fn matches(&self, h: f32, drag: f32, ctx: &StepContext) -> bool {
        self.h == h.to_bits()
            && self.drag == drag.to_bits()
            && self.mass[..] == ctx.particles.mass[..]
            && self.inv_mass[..] == ctx.particles.inv_mass[..]
            && ctx
                .mesh
                .is_some_and(|m| self.active[..] == m.springs.active[..])
    }
}

impl MeshSystem {
    pub(super) fn new(mesh: &MeshCloth) -> Self {
        let n = mesh.len();
        let s = &mesh.springs;
        MeshSystem {
            matrix: SpringMatrix::new(&s.a, &s.b, &mesh.offsets, &mesh.incident),
            blocks: vec![Sym3::ZERO; s.len()],
            kv: vec![Vec3::ZERO; s.len()],
            rhs: Vec3s::zeros(n),
            dv: Vec3s::zeros(n),
            extra: Vec3s::zeros(n),
            cg: ConjugateGradient::new(n),
            jacobi: std::array::from_fn(|_| Floats::zeros(n)),
            order: Vec::new(),
            factor: None,
        }
    }

    /// Assembles the step's system (contacts held), builds the preconditioner and solves for
    /// `dv` (in `self.dv`), booking the times and the solve in `stats`.
    pub(super) fn solve(
        &mut self,
        mesh: &MeshCloth,
        (h, drag): (f32, f32),
        settings: SolverSettings,
        stats: &mut SolverStats,
        ctx: &StepContext,
    ) {
        let started = Instant::now();
        self.build_blocks(mesh, h, ctx);
        self.matrix.gather();
        self.assemble_diagonal_and_rhs(mesh, h, drag, ctx);
        if let Some(contacts) = ctx.contacts.filter(|c| c.count > 0) {
            self.hold_contacts(h, contacts, ctx);
        }
        match settings.preconditioner {
            Preconditioner::Jacobi => {
                let d = &self.matrix.diagonal;
                for (c, out) in self.jacobi.iter_mut().enumerate() {
                    for (p, o) in out.iter_mut().enumerate() {
                        *o = if c < 3 && d[p].0[c] > 0.0 {
                            1.0 / d[p].0[c]
                        } else {
                            0.0
                        };
                    }
                }
            }
            Preconditioner::BlockJacobi => {
                for (p, d) in self.matrix.diagonal.iter().enumerate() {
                    for (out, v) in self.jacobi.iter_mut().zip(d.inverse_or_zero().0) {
                        out[p] = v;
                    }
                }
            }
            Preconditioner::Multigrid => {
                for (p, d) in self.matrix.diagonal.iter().enumerate() {
                    for (out, v) in self.jacobi.iter_mut().zip(d.inverse_or_zero().0) {
                        out[p] = v;
                    }
                }
                if !self
                    .factor
                    .as_ref()
                    .is_some_and(|f| f.0.matches(h, drag, ctx))
                {
                    let factor = self.factor_isotropic(mesh, h, drag, ctx);
                    self.factor = Some((FactorKey::of(h, drag, ctx), factor));
                    stats.factorizations += 1;
                }
            }
        }
        let solving = Instant::now();
        stats.setup_seconds += (solving - started).as_secs_f64();
        let MeshSystem {
            matrix,
            rhs,
            dv,
            cg,
            jacobi,
            factor,
            extra,
            ..
        } = self;
        let (iterations, residual) = cg.solve(
            &*matrix,
            rhs,
            dv,
            settings.tolerance as f64,
            settings.max_iterations,
            |r, z| match (settings.preconditioner, factor.as_mut()) {
                (Preconditioner::Multigrid, Some((_, factor))) => {
                    // Held vertices are not unknowns of the factor: their z stays zero.
                    diagonal_blocks(jacobi, r, extra);
                    z.fill(Vec3::ZERO);
                    factor.solve(r, z);
                    for (z, e) in [
                        (&mut z.x, &extra.x),
                        (&mut z.y, &extra.y),
                        (&mut z.z, &extra.z),
                    ] {
                        for (z, e) in z.iter_mut().zip(e.iter()) {
                            *z += e;
                        }
                    }
                }
                _ => diagonal_blocks(jacobi, r, z),
            },
        );
        stats.solve_seconds += solving.elapsed().as_secs_f64();
        stats.record(iterations, residual, settings.tolerance as f64);
    }

    /// Per spring, `C_s = alpha u u^T + beta I` (`alpha = h c + h^2 k (1 - g)`,
    /// `beta = h^2 k g`, `g = max(0, 1 - L / l)`), `K_s (v_a - v_b)` with
    /// `K_s = C_s - h c u u^T`, and the filtered off-diagonal block `-C_s` (zero when an end is
    /// held).
    fn build_blocks(&mut self, mesh: &MeshCloth, h: f32, ctx: &StepContext) {
        let s = &mesh.springs;
        let (pos, vel, w) = (&ctx.current.pos, &ctx.current.vel, &ctx.particles.inv_mass);
        self.blocks
            .par_chunks_mut(SPRING_CHUNK)
            .zip(self.kv.par_chunks_mut(SPRING_CHUNK))
            .zip(self.matrix.off.par_chunks_mut(SPRING_CHUNK))
            .enumerate()
            .for_each(|(ci, ((blocks, kv), off))| {
                for i in 0..blocks.len() {
                    let e = ci * SPRING_CHUNK + i;
                    let (a, b) = (s.a[e] as usize, s.b[e] as usize);
                    let (k, c) = (s.k[e], s.c[e]);
                    let d = pos.get(b) - pos.get(a);
                    let l = d.length();
                    let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                    let g = (1.0 - s.rest[e] * inv_l).max(0.0) * (l > 0.0) as u32 as f32;
                    let alpha = h * c + h * h * k * (1.0 - g);
                    let beta = h * h * k * g;
                    let u = d * inv_l;
                    let block = Sym3::outer(alpha, u, beta);
                    let dw = vel.get(a) - vel.get(b);
                    blocks[i] = block;
                    kv[i] = (alpha - h * c) * u.dot(dw) * u + beta * dw;
                    let coupled = w[a] != 0.0 && w[b] != 0.0;
                    off[i] = Sym3(block.0.map(|x| live_or_zero(coupled, -x)));
                }
            });
    }

    /// The diagonal blocks `D_a = (m_a + h drag) I + sum_s C_s` and the right-hand side
    /// `b_a = h f_a - sum_s (+-) K_s (v_a - v_b)` (the first end takes `-`, the second `+`),
    /// zero for held vertices.
    fn assemble_diagonal_and_rhs(
        &mut self,
        mesh: &MeshCloth,
        h: f32,
        drag: f32,
        ctx: &StepContext,
    ) {
        let chunk = ctx.chunk;
        let (force, mass, w) = (&*ctx.force, &ctx.particles.mass, &ctx.particles.inv_mass);
        let (blocks, kv) = (&self.blocks, &self.kv);
        self.matrix
            .diagonal
            .par_chunks_mut(chunk)
            .zip(self.rhs.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(ci, (d, mut b))| {
                for (i, di) in d.iter_mut().enumerate() {
                    let v = ci * chunk + i;
                    if w[v] == 0.0 {
                        *di = Sym3::ZERO;
                        b.set(i, Vec3::ZERO);
                        continue;
                    }
                    let m = mass[v] + h * drag;
                    let mut block = Sym3([m, m, m, 0.0, 0.0, 0.0]);
                    let mut r = h * force.get(v);
                    for &e in &mesh.incident[mesh.offsets[v] as usize..mesh.offsets[v + 1] as usize]
                    {
                        let s = (e >> 1) as usize;
                        block.add_scaled(1.0, &blocks[s]);
                        r = if e & 1 == 0 { r - kv[s] } else { r + kv[s] };
                    }
                    *di = block;
                    b.set(i, r);
                }
            });
    }

    /// The grid's contact spring ([`super::implicit_euler`]'s `hold_contacts`) on each free
    /// vertex with a predicted contact: `A += h^2 k_c n n^T`,
    /// `b -= h k_c n (max(n . x - offset, 0) + h n . v)`, `k_c = CONTACT_STIFFNESS m / h^2`.
    fn hold_contacts(&mut self, h: f32, contacts: &PredictedContacts, ctx: &StepContext) {
        let (mass, w, cur) = (&ctx.particles.mass, &ctx.particles.inv_mass, ctx.current);
        for p in 0..self.matrix.len() {
            let n = contacts.normal.get(p);
            if n == Vec3::ZERO || w[p] == 0.0 {
                continue;
            }
            let s = CONTACT_STIFFNESS * mass[p];
            self.matrix.diagonal[p].add_scaled(s, &Sym3::outer(1.0, n, 0.0));
            let ahead = (n.dot(cur.pos.get(p)) - contacts.offset[p]).max(0.0);
            let gap = ahead + h * n.dot(cur.vel.get(p));
            self.rhs.set(p, self.rhs.get(p) - (s / h) * gap * n);
        }
    }

    /// The factor of the isotropic part `P` over the free vertices.
    fn factor_isotropic(
        &mut self,
        mesh: &MeshCloth,
        h: f32,
        drag: f32,
        ctx: &StepContext,
    ) -> SparseCholesky {
        if self.order.is_empty() {
            self.order = mesh_order(mesh);
        }
        let (h, drag) = (h as f64, drag as f64);
        let (mass, w) = (&ctx.particles.mass, &ctx.particles.inv_mass);
        let s = &mesh.springs;
        let weight = |e: usize| h * s.c[e] as f64 + h * h * s.k[e] as f64;
        let mut diagonal: Vec<f64> = mass.iter().map(|&m| m as f64 + h * drag).collect();
        for e in 0..s.len() {
            diagonal[s.a[e] as usize] += weight(e);
            diagonal[s.b[e] as usize] += weight(e);
        }
        let order = self.order.iter().copied().filter(|&p| w[p] > 0.0).collect();
        let entries = (0..s.len()).map(|e| (s.a[e] as usize, s.b[e] as usize, -weight(e)));
        SparseCholesky::factor_ordered(order, &diagonal, entries)
    }
}

/// The nested-dissection order of a mesh's vertices by their rest positions, with the springs
/// (stretch and bend) as the graph.
pub(super) fn mesh_order(mesh: &MeshCloth) -> Vec<usize> {
    let s = &mesh.springs;
    let neighbours: Vec<u32> = mesh
        .incident
        .iter()
        .map(|&e| {
            let i = (e >> 1) as usize;
            if e & 1 == 0 {
                s.b[i]
            } else {
                s.a[i]
            }
        })
        .collect();
    let offsets = &mesh.offsets;
    dissect_points(&mesh.rest, |p| {
        &neighbours[offsets[p] as usize..offsets[p + 1] as usize]
    })
}
