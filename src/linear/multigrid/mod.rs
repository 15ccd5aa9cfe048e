//! Geometric multigrid with Galerkin coarse operators, a preconditioner for the conjugate
//! gradient on [`BlockStencil`] systems.
//!
//! **Hierarchy.** Each level halves the grid in both directions by bilinear interpolation
//! (`transfer.rs`); the coarse matrix is the Galerkin product `A_c = P^T A P` (`galerkin.rs`),
//! again a [`BlockStencil`]. Coarsening stops at three nodes a side, where a dense Cholesky
//! factorisation solves exactly.
//!
//! **Held nodes.** The systems this serves are filtered: a pinned or cut particle's rows and
//! columns are zero and its unknown stays zero. The coarse operators keep those constraints
//! built in, prolongation is masked so a correction never moves a held node, and the smoother's
//! free mask keeps every level's held unknowns at zero.
//!
//! **Cycle.** One V-cycle with one damped block-Jacobi sweep (`x += omega D^-1 (b - A x)`,
//! `omega = 0.7`) before and after the coarse correction. Pre- and post-smoother are the same
//! symmetric operator, so the cycle is a symmetric positive definite preconditioner and CG may
//! use it. The smoother damps the error that varies from node to node; the coarse levels remove
//! the smooth error, which block Jacobi alone needs the more iterations for the larger the grid
//! and the stiffer the springs. So CG's iteration count barely grows with either.
//!
//! Every pass is parallel over fixed chunks of nodes and writes only its own chunk, so the
//! result is bitwise the same for any number of threads.

mod galerkin;
mod transfer;

use rayon::prelude::*;

use super::dense::DenseCholesky;
use super::stencil::{add_product, set_product, BlockStencil, SlotArrays, Sym3, SLOTS};
use crate::soa::{Floats, Vec3s};
use galerkin::{galerkin, interior_table, Term};
use transfer::{prolong, restrict, Transfer1d, COARSEST_SIDE};

/// Damping of the block-Jacobi smoother: 2/3 is optimal for the Laplacian, and on cloth the
/// iteration counts hardly change between 0.6 and 0.8, so 0.7 sits in the middle.
pub const OMEGA: f32 = 0.7;

/// One level of the hierarchy.
#[derive(Clone, Debug)]
struct Level {
    /// The level's matrix; empty for level 0, which is the caller's.
    matrix: BlockStencil,
    /// The smoother `omega D^-1`, block by block.
    dinv: SlotArrays,
    /// 1 for a free node, 0 for a held one (zero diagonal block).
    free: Floats,
    b: Vec3s,
    x: Vec3s,
    r: Vec3s,
}

/// One level's part of a V-cycle: its matrix, right-hand side and unknowns (the caller's on
/// the finest level, the level's own below it), with its smoother, free mask and residual.
struct System<'a> {
    matrix: &'a BlockStencil,
    b: &'a Vec3s,
    x: &'a mut Vec3s,
    r: &'a mut Vec3s,
    dinv: &'a SlotArrays,
    free: &'a Floats,
}

impl Level {
    /// This level, number `l`, as a V-cycle works on it: level 0 solves the caller's system
    /// `fine z = r`.
    fn system<'a>(
        &'a mut self,
        l: usize,
        fine: &'a BlockStencil,
        r: &'a Vec3s,
        z: &'a mut Vec3s,
    ) -> System<'a> {
        let Level {
            matrix,
            dinv,
            free,
            b,
            x,
            r: residual,
        } = self;
        let (matrix, b, x) = if l == 0 {
            (fine, r, z)
        } else {
            (&*matrix, &*b, x)
        };
        System {
            matrix,
            b,
            x,
            r: residual,
            dinv,
            free,
        }
    }

    fn new(nx: usize, ny: usize, own_matrix: bool) -> Self {
        let n = nx * ny;
        Level {
            matrix: if own_matrix {
                BlockStencil::full(nx, ny)
            } else {
                BlockStencil::new(0, 0, &[])
            },
            dinv: std::array::from_fn(|_| Floats::zeros(n)),
            free: Floats::zeros(n),
            b: Vec3s::zeros(n),
            x: Vec3s::zeros(n),
            r: Vec3s::zeros(n),
        }
    }

    fn heap_bytes(&self) -> usize {
        self.matrix.heap_bytes()
            + self.dinv.iter().map(Floats::heap_bytes).sum::<usize>()
            + self.free.heap_bytes()
            + self.b.heap_bytes()
            + self.x.heap_bytes()
            + self.r.heap_bytes()
    }
}

/// A multigrid preconditioner for one grid shape; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Multigrid {
    levels: Vec<Level>,
    /// `transfers[l]` maps level `l + 1` onto level `l`.
    transfers: Vec<(Transfer1d, Transfer1d)>,
    /// The interior Galerkin pattern of each coarsening, and which fine slots it reads.
    tables: Vec<([Vec<Term>; SLOTS], [bool; SLOTS])>,
    coarsest: DenseCholesky,
    dense: Vec<f64>,
    rhs: Vec<f64>,
    /// Galerkin rows of boundary nodes, before they are scattered into the slot arrays.
    boundary: Vec<(usize, [Sym3; SLOTS])>,
    /// Each fine slot component de-interleaved by rows into even and odd columns, so that the
    /// interior Galerkin sums (which read every other fine node) run over contiguous memory; one
    /// set per coarsening.
    split: Vec<Vec<Floats>>,
    /// Per coarsening, the half-transferred vector (coarse along i, fine along j) between the
    /// two 1-D passes of restriction and prolongation.
    halves: Vec<Vec3s>,
    fine_shape: (usize, usize),
}

impl Multigrid {
    pub fn new() -> Self {
        Self::default()
    }

    /// Levels including the finest.
    pub fn depth(&self) -> usize {
        self.levels.len()
    }

    pub fn heap_bytes(&self) -> usize {
        self.levels.iter().map(Level::heap_bytes).sum::<usize>()
            + (self.dense.capacity() + self.rhs.capacity()) * size_of::<f64>() * 2
    }

    fn shape(&mut self, fine: &BlockStencil) {
        let present: [bool; SLOTS] = std::array::from_fn(|s| fine.is_present(s));
        if self.fine_shape == (fine.nx, fine.ny)
            && self.tables.first().is_some_and(|t| t.1 == present)
        {
            return;
        }
        self.levels = vec![Level::new(fine.nx, fine.ny, false)];
        self.transfers.clear();
        self.tables.clear();
        self.halves.clear();
        self.split.clear();
        let (mut nx, mut ny) = (fine.nx, fine.ny);
        let mut reads = present;
        while nx.max(ny) > COARSEST_SIDE {
            let t = (Transfer1d::new(nx), Transfer1d::new(ny));
            self.halves.push(Vec3s::zeros(t.0.coarse * ny));
            self.split.push(Vec::new());
            (nx, ny) = (t.0.coarse, t.1.coarse);
            self.tables.push((interior_table(&reads), reads));
            reads = [true; SLOTS];
            self.transfers.push(t);
            self.levels.push(Level::new(nx, ny, true));
        }
        self.fine_shape = (fine.nx, fine.ny);
    }

    /// Builds the hierarchy for the matrix `fine` (filtered: zero rows and columns for held
    /// nodes). Allocates only when the grid's shape or the stored slots change.
    pub fn build(&mut self, fine: &BlockStencil, chunk: usize) {
        self.shape(fine);
        let Multigrid {
            levels,
            transfers,
            tables,
            boundary,
            coarsest,
            dense,
            split,
            ..
        } = self;
        let depth = levels.len();
        for l in 0..depth {
            let (head, tail) = levels.split_at_mut(l + 1);
            let Level {
                matrix: own,
                dinv,
                free,
                ..
            } = &mut head[l];
            let matrix = if l == 0 { fine } else { &*own };
            matrix.diagonal_inverse(dinv, chunk);
            for c in dinv.iter_mut() {
                c.iter_mut().for_each(|w| *w *= OMEGA);
            }
            let d = matrix.slot(0);
            for (p, free) in free.iter_mut().enumerate() {
                *free = ((d[0][p] + d[1][p] + d[2][p]) > 0.0) as u32 as f32;
            }
            match tail.first_mut() {
                Some(next) => galerkin(
                    matrix,
                    &transfers[l],
                    &tables[l].0,
                    &mut next.matrix,
                    boundary,
                    &mut split[l],
                ),
                None => {
                    dense_of(matrix, dense);
                    coarsest.factor(dense, 3 * matrix.len());
                }
            }
        }
    }

    /// `z = M^-1 r`: one V-cycle for the matrix `fine` the hierarchy was built from.
    pub fn apply(&mut self, fine: &BlockStencil, r: &Vec3s, z: &mut Vec3s, chunk: usize) {
        let depth = self.levels.len();
        if depth == 1 {
            self.solve_coarsest(0, Some((r, z)));
            return;
        }
        // Down: pre-smooth from zero, restrict the residual.
        for l in 0..depth - 1 {
            let (head, tail) = self.levels.split_at_mut(l + 1);
            let level = head[l].system(l, fine, r, z);
            smooth::<false>(level.dinv, level.b, level.x, chunk);
            residual(level.matrix, level.x, level.b, level.r, chunk);
            restrict(
                &self.transfers[l],
                level.r,
                &mut self.halves[l],
                &mut tail[0].b,
            );
        }
        self.solve_coarsest(depth - 1, None);
        // Up: prolong the correction, post-smooth.
        for l in (0..depth - 1).rev() {
            let (head, tail) = self.levels.split_at_mut(l + 1);
            let level = head[l].system(l, fine, r, z);
            prolong(
                &self.transfers[l],
                &tail[0].x,
                &mut self.halves[l],
                level.free,
                level.x,
            );
            residual(level.matrix, level.x, level.b, level.r, chunk);
            smooth::<true>(level.dinv, level.r, level.x, chunk);
        }
    }

    /// The dense solve on the coarsest level (`io` for a one-level hierarchy).
    fn solve_coarsest(&mut self, l: usize, io: Option<(&Vec3s, &mut Vec3s)>) {
        let level = &mut self.levels[l];
        let n = level.free.len();
        self.rhs.clear();
        let b = io.as_ref().map_or(&level.b, |(r, _)| *r);
        for p in 0..n {
            self.rhs
                .extend_from_slice(&[b.x[p] as f64, b.y[p] as f64, b.z[p] as f64]);
        }
        self.coarsest.solve(&mut self.rhs);
        let x = match io {
            Some((_, z)) => z,
            None => &mut level.x,
        };
        for p in 0..n {
            let f = level.free[p] as f64;
            x.x[p] = (f * self.rhs[3 * p]) as f32;
            x.y[p] = (f * self.rhs[3 * p + 1]) as f32;
            x.z[p] = (f * self.rhs[3 * p + 2]) as f32;
        }
    }
}

/// `x = W b` (`ADD == false`) or `x += W b` with the smoother's `W = omega D^-1`.
fn smooth<const ADD: bool>(w: &SlotArrays, b: &Vec3s, x: &mut Vec3s, chunk: usize) {
    x.par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, mut out)| {
            let range = c * chunk..c * chunk + out.len();
            let d: [&[f32]; 6] = std::array::from_fn(|k| &w[k][range.clone()]);
            let b = b.slices(range.clone());
            crate::simd::dispatch!(if ADD {
                add_product(d, b, &mut out)
            } else {
                set_product(d, b, &mut out)
            })
        });
}

/// `r = b - A x`.
fn residual(a: &BlockStencil, x: &Vec3s, b: &Vec3s, r: &mut Vec3s, chunk: usize) {
    r.par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, mut out)| {
            let range = c * chunk..c * chunk + out.len();
            crate::simd::dispatch!(a.residual_range(x, b, range.clone(), &mut out))
        });
}

/// The dense `3n x 3n` matrix of `a`, row-major, in f64.
fn dense_of(a: &BlockStencil, out: &mut Vec<f64>) {
    let n = a.len();
    let m = 3 * n;
    out.clear();
    out.resize(m * m, 0.0);
    for p in 0..n {
        for q in 0..n {
            let block = a.entry(p, q).to_dmat3();
            if block == glam::DMat3::ZERO {
                continue;
            }
            for r in 0..3 {
                for c in 0..3 {
                    out[(3 * p + r) * m + 3 * q + c] = block.col(c)[r];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::cg::BlockOperator;
    use super::super::stencil::{BlockStencil, OFFSETS};
    use super::*;
    use glam::Vec3;

    /// A filtered SPD matrix with the cloth stencil's shape: a mass term plus springs of random
    /// direction to the six spring-kind neighbours, some nodes held.
    pub(super) fn cloth_like(nx: usize, ny: usize, held: &[usize]) -> BlockStencil {
        let kinds = [1usize, 5, 6, 4, 2, 10];
        let mut a = BlockStencil::new(nx, ny, &kinds);
        let n = nx * ny;
        let mut diag = vec![Sym3::outer(0.0, Vec3::ZERO, 1.0); n];
        let is_held = |p: usize| held.contains(&p);
        for p in 0..n {
            let (i, j) = ((p % nx) as i32, (p / nx) as i32);
            for &s in &kinds {
                let (di, dj) = OFFSETS[s];
                let (qi, qj) = (i + di, j + dj);
                if !(0..nx as i32).contains(&qi) || !(0..ny as i32).contains(&qj) {
                    continue;
                }
                let q = (qj as usize) * nx + qi as usize;
                let u = Vec3::new((p as f32).sin(), (q as f32).cos(), 0.3).normalize();
                let c = Sym3::outer(40.0 + s as f32, u, 2.0);
                diag[p].add_scaled(1.0, &c);
                diag[q].add_scaled(1.0, &c);
                if !is_held(p) && !is_held(q) {
                    a.set_block(s, p, Sym3(c.0.map(|x| -x)));
                }
            }
        }
        for (p, d) in diag.into_iter().enumerate() {
            a.set_block(0, p, if is_held(p) { Sym3::ZERO } else { d });
        }
        a
    }

    pub(super) fn dense(a: &BlockStencil) -> Vec<f64> {
        let mut out = Vec::new();
        dense_of(a, &mut out);
        out
    }

    /// Preconditioned CG in f64 with the V-cycle; returns the iterations to `tol`.
    fn pcg_iterations(a: &BlockStencil, mg: &mut Multigrid, b: &Vec3s, tol: f64) -> usize {
        let n = a.len();
        let mut x = Vec3s::zeros(n);
        let mut r = b.clone();
        let mut z = Vec3s::zeros(n);
        let mut q = Vec3s::zeros(n);
        let dot =
            |u: &Vec3s, v: &Vec3s| -> f64 { (0..n).map(|p| u.get(p).dot(v.get(p)) as f64).sum() };
        mg.apply(a, &r, &mut z, 64);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let bn = dot(b, b).sqrt();
        for it in 1..500 {
            a.apply(&p, &mut q, 64);
            let alpha = rz / dot(&p, &q);
            for i in 0..n {
                x.set(i, x.get(i) + alpha as f32 * p.get(i));
                r.set(i, r.get(i) - alpha as f32 * q.get(i));
            }
            if dot(&r, &r).sqrt() / bn < tol {
                return it;
            }
            mg.apply(a, &r, &mut z, 64);
            let rz2 = dot(&r, &z);
            for i in 0..n {
                p.set(i, z.get(i) + (rz2 / rz) as f32 * p.get(i));
            }
            rz = rz2;
        }
        500
    }

    #[test]
    fn the_v_cycle_makes_cg_converge_in_few_iterations_and_keeps_held_nodes_at_zero() {
        let (nx, ny) = (40, 33);
        let held = [nx * (ny - 1), nx * ny - 1, 5 * nx + 7];
        let a = cloth_like(nx, ny, &held);
        let mut mg = Multigrid::new();
        mg.build(&a, 256);
        assert_eq!(mg.depth(), 6);
        let n = nx * ny;
        let mut b = Vec3s::from_fn(n, |p| Vec3::new((p as f32 * 0.1).sin(), 1.0, -0.5));
        for &p in &held {
            b.set(p, Vec3::ZERO);
        }
        let mut z = Vec3s::zeros(n);
        mg.apply(&a, &b, &mut z, 256);
        for &p in &held {
            assert_eq!(z.get(p), Vec3::ZERO);
        }
        let iterations = pcg_iterations(&a, &mut mg, &b, 1e-5);
        assert!(iterations <= 12, "{iterations} iterations");
    }

    #[test]
    fn the_v_cycle_is_the_same_for_any_number_of_threads() {
        let a = cloth_like(70, 50, &[0]);
        let b = Vec3s::from_fn(3500, |p| Vec3::new(p as f32, 0.5, (p as f32).cos()));
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let mut mg = Multigrid::new();
                    mg.build(&a, 128);
                    let mut z = Vec3s::zeros(3500);
                    mg.apply(&a, &b, &mut z, 128);
                    z
                })
        };
        assert_eq!(run(1), run(4));
    }
}
