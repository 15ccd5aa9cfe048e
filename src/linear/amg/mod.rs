//! Smoothed-aggregation algebraic multigrid (Vanek, Mandel and Brezina 1996; PyAMG's
//! `smoothed_aggregation_solver`): a preconditioner for the conjugate gradient on a
//! [`SpringMatrix`], the mesh cloth's counterpart of the grid's geometric [`super::Multigrid`].
//!
//! **Hierarchy** ([`Amg::new`]), built on a reference matrix: each level aggregates the nodes
//! of the one above along its strong connections and prolongs by the smoothed aggregate
//! indicator (`aggregate.rs`); the next reference is the Galerkin product `P^T A P`
//! (`galerkin.rs`), down to at most [`COARSEST`] nodes. The aggregates and prolongators depend
//! only on the reference, so a caller builds them once for a topology, pins, step and material.
//!
//! **Coarse operators** ([`Amg::update`]): the Galerkin products of the step's matrix through
//! the fixed prolongators, recomputed each time the matrix changes (every step of implicit
//! Euler), with its diagonal blocks and the dense Cholesky factor of the coarsest level.
//!
//! **Cycle** ([`Amg::apply`]): one V-cycle with one damped block-Jacobi sweep
//! (`x += omega D^-1 (b - A x)`, `omega` = [`OMEGA`]) before and after the coarse correction.
//! Two sweeps each cut CG's iterations on the stiff 16k drape from 14.3 to 10.9, but cost five
//! fine products an iteration instead of three, and the step took longer.
//! Block Jacobi is symmetric, the post-smoother repeats the pre-smoother, restriction is the
//! transpose of prolongation and the coarsest solve is exact, so the cycle is a symmetric
//! positive definite preconditioner for CG. A held node (zero diagonal block) is in no
//! aggregate and its smoother block is zero, so it never moves.
//!
//! Every pass is parallel over rows, each row summed in a fixed order (the coarsest solve is
//! serial), so the result is bitwise the same for any number of threads.

mod aggregate;
mod csr;
mod galerkin;

use rayon::prelude::*;

use super::cg::BlockOperator;
use super::dense::DenseCholesky;
use super::reduce::REDUCE_CHUNK;
use super::{SpringMatrix, Sym3};
use crate::soa::Vec3s;
pub use csr::{BlockCsr, BlockRows, Transfer};
use galerkin::Galerkin;

/// Coarsening stops at this many nodes (3 unknowns each), solved by a dense Cholesky factor
/// refactored every update: a larger coarsest level costs `(3n)^3 / 3` flops a step, a smaller
/// one more levels.
pub const COARSEST: usize = 64;

/// Coarsening also stops when a level keeps more than this fraction of the nodes above it.
const STALLED: f64 = 0.8;

/// Damping of the block-Jacobi smoother (as the grid's multigrid).
pub const OMEGA: f32 = 0.7;

/// A level with a coarser one below: the prolongator to it, its Galerkin plan, its matrix and
/// this level's workspace.
#[derive(Clone, Debug)]
struct Level {
    transfer: Transfer,
    galerkin: Galerkin,
    /// The next level's matrix.
    coarse: BlockCsr,
    /// This level's smoother `omega D^-1`.
    smoother: Vec<Sym3>,
    /// This level's residual, and the next level's right-hand side and solution.
    r: Vec3s,
    coarse_b: Vec3s,
    coarse_x: Vec3s,
}

impl Level {
    /// The level that coarsens `a` by aggregation, with the Galerkin product of `a`; None when
    /// `a` does not coarsen (no aggregate, or more than [`STALLED`] of its nodes kept).
    fn below<A: BlockRows>(a: &A) -> Option<Level> {
        let (agg, count) = aggregate::aggregate(a);
        if count == 0 || count as f64 > STALLED * a.rows() as f64 {
            return None;
        }
        let transfer = aggregate::smoothed_prolongator(a, &agg, count);
        let (mut galerkin, mut coarse) = Galerkin::new(a, &transfer);
        galerkin.apply(a, &transfer, &mut coarse);
        let (n, nc) = (a.rows(), coarse.rows());
        Some(Level {
            transfer,
            galerkin,
            coarse,
            smoother: vec![Sym3::ZERO; n],
            r: Vec3s::zeros(n),
            coarse_b: Vec3s::zeros(nc),
            coarse_x: Vec3s::zeros(nc),
        })
    }
}

/// See the module docs.
#[derive(Clone, Debug, Default)]
pub struct Amg {
    levels: Vec<Level>,
    /// The finest level's smoother when there is no coarser level.
    smoother: Vec<Sym3>,
    coarsest: DenseCholesky,
    dense: Vec<f64>,
    rhs: Vec<f64>,
}

impl Amg {
    /// The hierarchy of `reference` (a [`SpringMatrix`] with the pattern of the matrices it
    /// will precondition), with its Galerkin coarse operators.
    pub fn new(reference: &SpringMatrix) -> Self {
        let mut amg = Amg::default();
        amg.levels.extend(Level::below(reference));
        while let Some(level) = (amg.levels.last())
            .filter(|above| above.coarse.rows() > COARSEST)
            .and_then(|above| Level::below(&above.coarse))
        {
            amg.levels.push(level);
        }
        // Building the levels took the reference's Galerkin products already.
        amg.refresh_smoothers_and_coarsest(reference);
        amg
    }

    /// Nodes per level, finest first.
    pub fn sizes(&self) -> Vec<usize> {
        let mut sizes: Vec<usize> = self.levels.iter().map(|l| l.transfer.fine()).collect();
        sizes.extend(self.levels.last().map(|l| l.coarse.rows()));
        sizes
    }

    /// The coarse operators, smoothers and coarsest factor for `fine`, which must have the
    /// pattern of the reference the hierarchy was built on.
    pub fn update(&mut self, fine: &SpringMatrix) {
        let mut above: Option<&BlockCsr> = None;
        for level in self.levels.iter_mut() {
            match above {
                None => level
                    .galerkin
                    .apply(fine, &level.transfer, &mut level.coarse),
                Some(a) => level.galerkin.apply(a, &level.transfer, &mut level.coarse),
            }
            above = Some(&level.coarse);
        }
        self.refresh_smoothers_and_coarsest(fine);
    }

    /// Every level's smoother and the coarsest level's factor, from `fine` and the coarse
    /// operators as they are.
    fn refresh_smoothers_and_coarsest(&mut self, fine: &SpringMatrix) {
        self.update_smoother(fine);
        for pair in 1..self.levels.len() {
            let (above, below) = self.levels.split_at_mut(pair);
            set_smoother(&above[pair - 1].coarse, &mut below[0].smoother);
        }
        if let Some(last) = self.levels.last() {
            last.coarse.to_dense(&mut self.dense);
            self.coarsest.factor(&self.dense, 3 * last.coarse.rows());
        }
    }

    /// The finest level's smoother for `fine`, keeping the coarse operators as they are (those
    /// of the reference, or of an earlier update).
    pub fn update_smoother(&mut self, fine: &SpringMatrix) {
        match self.levels.first_mut() {
            Some(level) => set_smoother(fine, &mut level.smoother),
            None => {
                self.smoother.resize(fine.rows(), Sym3::ZERO);
                set_smoother(fine, &mut self.smoother);
            }
        }
    }

    /// `z = M^-1 r`, one V-cycle on `fine z = r` (`fine` the matrix of the last update).
    pub fn apply(&mut self, fine: &SpringMatrix, r: &Vec3s, z: &mut Vec3s) {
        let Amg {
            levels,
            coarsest,
            rhs,
            ..
        } = self;
        if levels.is_empty() {
            // No coarsening (every node held, or no coupling): block Jacobi alone.
            jacobi_start(&self.smoother, r, z);
            return;
        }
        cycle(fine, r, z, levels, coarsest, rhs);
    }
}

/// One V-cycle on `a x = b` from `x = 0`, `levels[0]` being `a`'s level.
fn cycle<A: BlockOperator>(
    a: &A,
    b: &Vec3s,
    x: &mut Vec3s,
    levels: &mut [Level],
    coarsest: &DenseCholesky,
    rhs: &mut Vec<f64>,
) {
    let (level, below) = levels.split_first_mut().expect("a level to cycle on");
    let Level {
        transfer,
        coarse,
        smoother,
        r,
        coarse_b,
        coarse_x,
        ..
    } = level;
    jacobi_start(smoother, b, x);
    residual(a, b, x, r);
    transfer.restrict(r, coarse_b);
    if below.is_empty() {
        solve_dense(coarsest, coarse_b, coarse_x, rhs);
    } else {
        cycle(&*coarse, coarse_b, coarse_x, below, coarsest, rhs);
    }
    transfer.prolong_add(coarse_x, x);
    jacobi_sweep(a, smoother, b, x, r);
}

/// `omega D^-1` of `a`, block by block (zero for a block that is not positive definite).
fn set_smoother<A: BlockRows + Sync>(a: &A, out: &mut [Sym3]) {
    out.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let inv = a.diagonal(c * REDUCE_CHUNK + k).inverse_or_zero();
                *o = Sym3(inv.0.map(|x| OMEGA * x));
            }
        });
}

/// `x = S b`, the first sweep from `x = 0`.
fn jacobi_start(smoother: &[Sym3], b: &Vec3s, x: &mut Vec3s) {
    x.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, mut x)| {
            for k in 0..x.len() {
                let v = c * REDUCE_CHUNK + k;
                x.set(k, smoother[v].mul(b.get(v)));
            }
        });
}

/// `r = b - a x`.
fn residual<A: BlockOperator>(a: &A, b: &Vec3s, x: &Vec3s, r: &mut Vec3s) {
    a.prepare(x);
    r.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, mut r)| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + r.len();
            crate::simd::dispatch!({
                a.apply_range(x, range.clone(), &mut r);
                let b = b.slices(range.clone());
                for (r, b) in [(&mut *r.x, b.x), (&mut *r.y, b.y), (&mut *r.z, b.z)] {
                    for (r, b) in r.iter_mut().zip(b) {
                        *r = b - *r;
                    }
                }
            })
        });
}

/// `x += S (b - a x)`, with `r` as scratch.
fn jacobi_sweep<A: BlockOperator>(
    a: &A,
    smoother: &[Sym3],
    b: &Vec3s,
    x: &mut Vec3s,
    r: &mut Vec3s,
) {
    residual(a, b, x, r);
    x.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, mut x)| {
            for k in 0..x.len() {
                let v = c * REDUCE_CHUNK + k;
                x.set(k, x.get(k) + smoother[v].mul(r.get(v)));
            }
        });
}

/// `x = A^-1 b` on the coarsest level, in f64.
fn solve_dense(factor: &DenseCholesky, b: &Vec3s, x: &mut Vec3s, rhs: &mut Vec<f64>) {
    rhs.clear();
    for v in 0..b.len() {
        let p = b.get(v);
        rhs.extend([p.x as f64, p.y as f64, p.z as f64]);
    }
    factor.solve(rhs);
    for v in 0..x.len() {
        x.set(
            v,
            glam::Vec3::new(
                rhs[3 * v] as f32,
                rhs[3 * v + 1] as f32,
                rhs[3 * v + 2] as f32,
            ),
        );
    }
}

#[cfg(test)]
mod tests;
