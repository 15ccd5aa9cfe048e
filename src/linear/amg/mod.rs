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
//! (`x += omega D^-1 (b - A x)`, `omega` = [`OMEGA`], or less where [`Amg::bound_damping`]
//! finds it too much) before and after the coarse correction.
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
mod order;

use rayon::prelude::*;

use super::block_lanes::Packed;
use super::cg::{BlockOperator, Packing};
use super::dense::DenseCholesky;
use super::reduce::REDUCE_CHUNK;
use super::{SpringMatrix, Sym3};
use crate::soa::Vec3s;
pub use csr::{BlockCsr, BlockRows, Transfer};
use galerkin::Galerkin;
pub use order::{local_order, places};

/// Coarsening stops at this many nodes (3 unknowns each), solved by a dense Cholesky factor
/// refactored every update: a larger coarsest level costs `(3n)^3 / 3` flops a step, a smaller
/// one more levels.
pub const COARSEST: usize = 64;

/// Coarsening also stops when a level keeps more than this fraction of the nodes above it.
const STALLED: f64 = 0.8;

/// Damping of the block-Jacobi smoother (as the grid's multigrid).
pub const OMEGA: f32 = 0.7;

/// With its damping bounded ([`Amg::bound_damping`]), a smoother whose Gershgorin bound `g` on
/// `rho(D^-1 A)` exceeds `2 / OMEGA` damps by `SLACK / g`: below 2, so the sweep contracts
/// every error, and near it because `g` overstates `rho` (the usual `4/3 / rho` took the
/// isometric cantilever's CG from 44 to 53 iterations a solve, the 16k mesh's from 19.6 to 23.2).
const SLACK: f32 = 1.9;

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
    /// The operand of this level's products, packed where its matrix [`BlockOperator::packs`].
    packed: Packed,
    coarse_b: Vec3s,
    coarse_x: Vec3s,
}

impl Level {
    /// The level that coarsens `a` by aggregation, with the Galerkin product of `a`; None when
    /// `a` does not coarsen (no aggregate, or more than [`STALLED`] of its nodes kept).
    fn below<A: BlockRows>(a: &A, numbering: Option<&[u32]>) -> Option<Level> {
        let (agg, count) = aggregate::aggregate(a, numbering);
        if count == 0 || count as f64 > STALLED * a.rows() as f64 {
            return None;
        }
        let transfer = aggregate::smoothed_prolongator(a, &agg, count);
        let (mut galerkin, mut coarse) = Galerkin::new(a, &transfer);
        galerkin.apply(a, &mut coarse);
        let (n, nc) = (a.rows(), coarse.rows());
        Some(Level {
            transfer,
            galerkin,
            coarse,
            smoother: vec![Sym3::ZERO; n],
            r: Vec3s::zeros(n),
            packed: Packed::default(),
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
    /// Whether each smoother's damping is bounded by its level's `rho(D^-1 A)` (see
    /// [`Amg::bound_damping`]); off, every level smooths with [`OMEGA`].
    bounded: bool,
}

impl Amg {
    /// The hierarchy of `reference` (a [`SpringMatrix`] with the pattern of the matrices it
    /// will precondition), with its Galerkin coarse operators.
    pub fn new(reference: &SpringMatrix) -> Self {
        Amg::renumbered(reference, None)
    }

    /// The hierarchy of `reference` whose rows are a renumbering of a matrix's (row `k` is
    /// that matrix's row `vertices[k]`): its aggregates are those of that matrix, renumbered
    /// (the visiting order is chosen on the matrix as first numbered, [`aggregate::aggregate`]),
    /// so that solving in another numbering changes the order of the sums and not the
    /// preconditioner.
    pub fn renumbered(reference: &SpringMatrix, vertices: Option<&[u32]>) -> Self {
        let mut amg = Amg::default();
        amg.levels.extend(Level::below(reference, vertices));
        while let Some(level) = (amg.levels.last())
            .filter(|above| above.coarse.rows() > COARSEST)
            .and_then(|above| Level::below(&above.coarse, None))
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
                None => level.galerkin.apply(fine, &mut level.coarse),
                Some(a) => level.galerkin.apply(a, &mut level.coarse),
            }
            above = Some(&level.coarse);
        }
        self.refresh_smoothers_and_coarsest(fine);
    }

    /// Bounds each level's smoothing by a Gershgorin estimate of its `rho(D^-1 A)`, from the
    /// next update on. [`OMEGA`] damps a block-Jacobi sweep enough while `rho(D^-1 A) < 2 /
    /// OMEGA`, which holds for a matrix of springs (mass plus weighted graph Laplacians:
    /// `rho < 2`), but not for a fourth-order term such as isometric bending, whose positive
    /// couplings to the second ring take `rho` to about 3.2: there the sweep amplifies the
    /// roughest error and CG stalls. Costs one pass over each level's blocks an update, so
    /// only a matrix that may need it asks.
    pub fn bound_damping(&mut self, on: bool) {
        self.bounded = on;
    }

    /// Every level's smoother and the coarsest level's factor, from `fine` and the coarse
    /// operators as they are.
    fn refresh_smoothers_and_coarsest(&mut self, fine: &SpringMatrix) {
        self.update_smoother(fine);
        for pair in 1..self.levels.len() {
            let (above, below) = self.levels.split_at_mut(pair);
            set_smoother(
                &above[pair - 1].coarse,
                &mut below[0].smoother,
                self.bounded,
            );
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
            Some(level) => set_smoother(fine, &mut level.smoother, self.bounded),
            None => {
                self.smoother.resize(fine.rows(), Sym3::ZERO);
                set_smoother(fine, &mut self.smoother, self.bounded);
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
        packed,
        coarse_b,
        coarse_x,
        ..
    } = level;
    jacobi_start(smoother, b, x);
    residual(a, b, (x, packed), r);
    transfer.restrict(r, coarse_b);
    if below.is_empty() {
        solve_dense(coarsest, coarse_b, coarse_x, rhs);
    } else {
        cycle(&*coarse, coarse_b, coarse_x, below, coarsest, rhs);
    }
    transfer.prolong_add(coarse_x, x);
    jacobi_sweep(a, smoother, b, (x, packed), r);
}

/// `omega D^-1` of `a`, block by block (zero for a block that is not positive definite):
/// `omega` is [`OMEGA`], or with `bounded` [`SLACK`] over [`jacobi_bound`] where that is less,
/// so that the sweep contracts every error (it does while `omega rho(D^-1 A) < 2`).
fn set_smoother<A: BlockRows + Sync>(a: &A, out: &mut [Sym3], bounded: bool) {
    let scale = |out: &mut [Sym3], omega: f32, invert: bool| {
        out.par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                for (k, o) in out.iter_mut().enumerate() {
                    let inv = if invert {
                        a.diagonal(c * REDUCE_CHUNK + k).inverse_or_zero()
                    } else {
                        *o
                    };
                    *o = Sym3(inv.0.map(|x| omega * x));
                }
            });
    };
    if !bounded {
        scale(out, OMEGA, true);
        return;
    }
    scale(out, 1.0, true);
    let bound = jacobi_bound(a, out);
    // Where OMEGA is provably damped enough the smoother is the unbounded one, bit for bit.
    let omega = if bound * OMEGA < 2.0 {
        OMEGA
    } else {
        SLACK / bound
    };
    scale(out, omega, false);
}

/// A bound on `rho(D^-1 A)` (`inverse` holding `D^-1` block by block): the infinity norm
/// of `D^-1 A`, the largest absolute row sum of its scalar rows (Gershgorin's circles; the
/// diagonal's own term is exactly 1). Rows of a held node (zero inverse) are left out. The
/// largest of the rows, so the same for any thread count.
fn jacobi_bound<A: BlockRows + Sync>(a: &A, inverse: &[Sym3]) -> f32 {
    (0..a.rows())
        .into_par_iter()
        .with_min_len(REDUCE_CHUNK)
        .map(|v| {
            let inv = inverse[v].0;
            if inv == [0.0; 6] {
                return 0.0;
            }
            let inv = [
                [inv[0], inv[3], inv[4]],
                [inv[3], inv[1], inv[5]],
                [inv[4], inv[5], inv[2]],
            ];
            let mut sums = [1.0f32; 3];
            a.for_each_entry(v, |w, block| {
                if w == v {
                    return;
                }
                let b = block.0;
                let columns = [[b[0], b[3], b[4]], [b[3], b[1], b[5]], [b[4], b[5], b[2]]];
                for (sum, row) in sums.iter_mut().zip(&inv) {
                    for column in &columns {
                        *sum +=
                            (row[0] * column[0] + row[1] * column[1] + row[2] * column[2]).abs();
                    }
                }
            });
            sums[0].max(sums[1]).max(sums[2])
        })
        .reduce(|| 0.0, f32::max)
}

/// `x = S b`, the first sweep from `x = 0`.
fn jacobi_start(smoother: &[Sym3], b: &Vec3s, x: &mut Vec3s) {
    x.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, x)| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + x.len();
            let (s, b) = (&smoother[range.clone()], b.slices(range));
            crate::simd::dispatch!(smooth(s, &b, x, |_, sb| sb))
        });
}

/// `out_k = add(out_k, S_k b_k)` for each node `k` of a chunk (`S_k b_k` as [`Sym3::mul`]
/// computes it), written a component at a time over slices of one length, so that the
/// compiler runs it across the vector unit's lanes (the nodes' blocks are read six apart).
#[inline(always)]
fn smooth(
    s: &[Sym3],
    b: &crate::soa::Vec3Slice,
    out: crate::soa::Vec3SliceMut,
    add: impl Fn(f32, f32) -> f32,
) {
    let n = s.len();
    let (bx, by, bz) = (&b.x[..n], &b.y[..n], &b.z[..n]);
    let (ox, oy, oz) = (&mut out.x[..n], &mut out.y[..n], &mut out.z[..n]);
    for k in 0..n {
        let m = &s[k].0;
        let (u, v, w) = (bx[k], by[k], bz[k]);
        ox[k] = add(ox[k], m[0] * u + m[3] * v + m[4] * w);
        oy[k] = add(oy[k], m[3] * u + m[1] * v + m[5] * w);
        oz[k] = add(oz[k], m[4] * u + m[5] * v + m[2] * w);
    }
}

/// `r = b - a x` (`packed`, scratch for `x` packed where `a` [`BlockOperator::packs`]).
fn residual<A: BlockOperator>(a: &A, b: &Vec3s, (x, packed): (&Vec3s, &mut Packed), r: &mut Vec3s) {
    if a.packs() && !a.adds_after() {
        a.prepare(x);
        packed.pack(x);
        return unpacked_residual(&Packing { a, packed }, b, x, r);
    }
    unpacked_residual(a, b, x, r)
}

/// `r = b - a x`, `a` read as it multiplies.
fn unpacked_residual<A: BlockOperator>(a: &A, b: &Vec3s, x: &Vec3s, r: &mut Vec3s) {
    if a.adds_after() {
        a.apply(x, r, REDUCE_CHUNK);
        r.par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(c, r)| {
                let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + r.len();
                let b = b.slices(range);
                for (r, b) in [(&mut *r.x, b.x), (&mut *r.y, b.y), (&mut *r.z, b.z)] {
                    for (r, b) in r.iter_mut().zip(b) {
                        *r = b - *r;
                    }
                }
            });
        return;
    }
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

/// `x += S (b - a x)`, with `r` and `packed` as scratch.
fn jacobi_sweep<A: BlockOperator>(
    a: &A,
    smoother: &[Sym3],
    b: &Vec3s,
    (x, packed): (&mut Vec3s, &mut Packed),
    r: &mut Vec3s,
) {
    residual(a, b, (x, packed), r);
    x.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, x)| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + x.len();
            let (s, r) = (&smoother[range.clone()], r.slices(range));
            crate::simd::dispatch!(smooth(s, &r, x, |x, sr| x + sr))
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
mod tests {
    //! The V-cycle on the systems implicit Euler builds for a stiff mesh cloth: a jittered square
    //! of the example's material (`examples/mesh_implicit.rs`) held by two corners, stretched 5 %
    //! one way and rippled out of its plane, so that some springs pull and some are slack.

    use std::collections::BTreeMap;

    use glam::Vec3;

    use super::*;
    use crate::linear::ConjugateGradient;
    use crate::mesh_cloth::{jittered_square, MeshCloth};
    use crate::scene::MeshSpec;

    const H: f32 = 1.0 / 60.0;

    /// The step's matrix (`M + sum C_s`, filtered at the held corners) and its isotropic part.
    fn stiff_system(n: usize) -> (SpringMatrix, SpringMatrix) {
        let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 0.0, 0.0], 0.3, 7);
        let spec = MeshSpec {
            vertices: vertices.iter().map(|v| [v[0], 0.0, v[1]]).collect(),
            triangles,
            density: 0.5,
            stretch: 1500.0,
            bend: 200.0,
            damping: 0.02,
            ..MeshSpec::default()
        };
        let mesh = MeshCloth::new(&spec).unwrap();
        let s = &mesh.springs;
        let held = |v: usize| v == n * (n - 1) || v == n * n - 1;
        let pos: Vec<Vec3> = mesh
            .rest
            .iter()
            .map(|r| {
                let (x, z) = (r[0] as f32, r[2] as f32);
                Vec3::new(1.05 * x, 0.05 * (9.0 * x).sin() * (7.0 * z).cos(), z)
            })
            .collect();
        let new = || SpringMatrix::new(&s.a, &s.b, &mesh.offsets, &mesh.incident);
        let (mut step, mut reference) = (new(), new());
        for v in 0..mesh.len() {
            let m = mesh.masses[v] as f32;
            step.diagonal[v] = Sym3([m, m, m, 0.0, 0.0, 0.0]);
            reference.diagonal[v] = step.diagonal[v];
        }
        for e in 0..s.len() {
            let (a, b) = (s.a[e] as usize, s.b[e] as usize);
            let (k, c) = (s.k[e], s.c[e]);
            let d = pos[b] - pos[a];
            let g = (1.0 - s.rest[e] / d.length()).max(0.0);
            let block = Sym3::outer(H * c + H * H * k * (1.0 - g), d.normalize(), H * H * k * g);
            let iso = Sym3::outer(0.0, Vec3::ZERO, H * c + H * H * k);
            for (matrix, block) in [(&mut step, block), (&mut reference, iso)] {
                matrix.diagonal[a].add_scaled(1.0, &block);
                matrix.diagonal[b].add_scaled(1.0, &block);
                let live = !held(a) && !held(b);
                matrix.off[e] = Sym3(block.0.map(|x| if live { -x } else { 0.0 }));
            }
        }
        for matrix in [&mut step, &mut reference] {
            for v in (0..mesh.len()).filter(|&v| held(v)) {
                matrix.diagonal[v] = Sym3::ZERO;
            }
            matrix.gather();
        }
        (step, reference)
    }

    /// A fixed pseudo-random vector, zero at the held vertices (zero diagonal).
    fn random(matrix: &SpringMatrix, seed: u64) -> Vec3s {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        Vec3s::from_fn(matrix.len(), |v| {
            let r = Vec3::new(next(), next(), next());
            if matrix.diagonal[v] == Sym3::ZERO {
                Vec3::ZERO
            } else {
                r
            }
        })
    }

    fn dot(a: &Vec3s, b: &Vec3s) -> f64 {
        (0..a.len()).map(|v| a.get(v).dot(b.get(v)) as f64).sum()
    }

    /// CG iterations to the solver's default tolerance (1e-4) on `step dv = b`, `b` random.
    fn iterations(amg: &mut Amg, step: &SpringMatrix) -> u32 {
        let b = random(step, 3);
        let mut x = Vec3s::zeros(step.len());
        let mut cg = ConjugateGradient::new(step.len());
        let (iterations, residual) =
            cg.solve(step, &b, &mut x, 1e-4, 500, |r, z| amg.apply(step, r, z));
        assert!(
            residual <= 1e-4,
            "not converged: {residual} after {iterations}"
        );
        iterations
    }

    /// `P^T A P` as a row-by-row product computes it: each row of `AP` added up term by term
    /// into its entries (`A`'s entries in order, each times `P`'s row), then each coarse row
    /// over `P^T`'s row and, for each, `AP`'s row by increasing column.
    fn row_by_row_product<A: BlockRows>(a: &A, p: &Transfer) -> Vec<BTreeMap<usize, Sym3>> {
        let ap: Vec<BTreeMap<usize, Sym3>> = (0..a.rows())
            .map(|i| {
                let mut row = BTreeMap::new();
                a.for_each_entry(i, |j, block| {
                    for (c, w) in p.p_row(j) {
                        row.entry(c).or_insert(Sym3::ZERO).add_scaled(w, block);
                    }
                });
                row
            })
            .collect();
        (0..p.coarse())
            .map(|c| {
                let mut row = BTreeMap::new();
                for (i, w) in p.r_row(c) {
                    for (&j, block) in &ap[i] {
                        row.entry(j).or_insert(Sym3::ZERO).add_scaled(w, block);
                    }
                }
                row
            })
            .collect()
    }

    /// `P^T A P` summed in f64 over every triple `P_iI A_ij P_jJ`.
    fn triple_sum<A: BlockRows>(a: &A, p: &Transfer) -> Vec<BTreeMap<usize, [f64; 6]>> {
        let mut out = vec![BTreeMap::new(); p.coarse()];
        for i in 0..a.rows() {
            a.for_each_entry(i, |j, block| {
                for (ci, wi) in p.p_row(i) {
                    for (cj, wj) in p.p_row(j) {
                        let entry: &mut [f64; 6] = out[ci].entry(cj).or_insert([0.0; 6]);
                        for (e, b) in entry.iter_mut().zip(block.0) {
                            *e += wi as f64 * wj as f64 * b as f64;
                        }
                    }
                }
            });
        }
        out
    }

    /// Checks `coarse` (what [`Galerkin::apply`] gave for `a` and `p`) against both products.
    fn check_galerkin<A: BlockRows>(a: &A, p: &Transfer, coarse: &BlockCsr) {
        let (row_by_row, exact) = (row_by_row_product(a, p), triple_sum(a, p));
        let largest = (coarse.values.iter())
            .flat_map(|b| b.0)
            .fold(0.0f32, |m, x| m.max(x.abs()));
        for c in 0..coarse.rows() {
            let columns: Vec<usize> = coarse
                .range(c)
                .map(|k| coarse.columns[k] as usize)
                .collect();
            let mut sorted = columns.clone();
            sorted.sort_unstable();
            let want: Vec<usize> = row_by_row[c].keys().copied().collect();
            assert_eq!(sorted, want, "row {c}'s pattern");
            for k in coarse.range(c) {
                let j = coarse.columns[k] as usize;
                let got = coarse.values[k].0;
                // On and above the diagonal, the row-by-row product's sum; below it, the
                // mirror's block bit for bit (the product in exact arithmetic is symmetric).
                let want = if j >= c {
                    row_by_row[c][&j].0
                } else {
                    let m = coarse.range(j).find(|&m| coarse.columns[m] as usize == c);
                    coarse.values[m.expect("a symmetric pattern")].0
                };
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "({c}, {j})");
                for (g, e) in got.iter().zip(exact[c][&j]) {
                    assert!(
                        (*g as f64 - e).abs() <= 1e-5 * largest as f64,
                        "({c}, {j}): {g} against {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_galerkin_product_is_exactly_symmetric_bitwise_and_near_the_exact_one() {
        let (step, reference) = stiff_system(33);
        let amg = Amg::new(&reference);
        assert!(amg.levels.len() >= 2, "levels {:?}", amg.sizes());
        let (fine, second) = (&amg.levels[0].transfer, &amg.levels[1].transfer);
        let (mut galerkin, mut coarse) = Galerkin::new(&step, fine);
        galerkin.apply(&step, &mut coarse);
        check_galerkin(&step, fine, &coarse);
        // A coarse level's matrix, read from a block CSR.
        let (mut galerkin, mut coarser) = Galerkin::new(&coarse, second);
        galerkin.apply(&coarse, &mut coarser);
        check_galerkin(&coarse, second, &coarser);
    }

    /// `matrix` with row and column `vertices[k]` moved to `k` (each row's entries in their
    /// order), and the permutation's inverse.
    fn renumber(matrix: &SpringMatrix, vertices: &[u32]) -> (SpringMatrix, Vec<u32>) {
        let place = places(vertices, matrix.len());
        let springs = matrix.off.len();
        let (mut a, mut b) = (vec![u32::MAX; springs], vec![0u32; springs]);
        let (mut offsets, mut incident) = (vec![0u32], Vec::new());
        for &v in vertices {
            for (s, c) in matrix.row(v as usize) {
                let (lo, hi) = (v.min(c as u32), v.max(c as u32));
                a[s] = place[lo as usize];
                b[s] = place[hi as usize];
                incident.push((s as u32) << 1 | u32::from(v == hi));
            }
            offsets.push(incident.len() as u32);
        }
        let mut renumbered = SpringMatrix::new(&a, &b, &offsets, &incident);
        for (k, &v) in vertices.iter().enumerate() {
            renumbered.diagonal[k] = matrix.diagonal[v as usize];
        }
        renumbered.off.clone_from(&matrix.off);
        renumbered.gather();
        (renumbered, place)
    }

    /// A mesh solved in a local numbering keeps the preconditioner of its own numbering: the
    /// fine level aggregated in the order the first numbering gives (not the renumbered
    /// matrix's own, whose aggregates took the 16k stiff mesh from 14.0 to 15.6 CG iterations
    /// a solve), so that each vertex joins the same aggregate, numbered the same, and CG
    /// takes as many iterations within one.
    #[test]
    fn a_renumbered_matrix_aggregates_as_first_numbered() {
        let (step, reference) = stiff_system(24);
        let n = step.len();
        // A scattered numbering: `vertices[k]` is the row moved to `k` (1297 is prime to 576).
        let vertices: Vec<u32> = (0..n).map(|k| (k * 1297 % n) as u32).collect();
        let (step_r, _) = renumber(&step, &vertices);
        let (reference_r, place) = renumber(&reference, &vertices);
        let (agg, count) = aggregate::aggregate(&reference, None);
        let (agg_r, count_r) = aggregate::aggregate(&reference_r, Some(&vertices));
        assert_eq!(count, count_r);
        for v in 0..n {
            assert_eq!(agg[v], agg_r[place[v] as usize], "vertex {v}");
        }
        let mut amg = Amg::new(&reference);
        amg.update(&step);
        let mut amg_r = Amg::renumbered(&reference_r, Some(&vertices));
        amg_r.update(&step_r);
        assert_eq!(amg.sizes(), amg_r.sizes());
        // The same right-hand side in both numberings.
        let b = random(&step, 3);
        let b_r = Vec3s::from_fn(n, |k| b.get(vertices[k] as usize));
        let solve = |amg: &mut Amg, step: &SpringMatrix, b: &Vec3s| {
            let (mut x, mut cg) = (Vec3s::zeros(n), ConjugateGradient::new(n));
            let (iterations, residual) =
                cg.solve(step, b, &mut x, 1e-4, 500, |r, z| amg.apply(step, r, z));
            assert!(
                residual <= 1e-4,
                "not converged: {residual} after {iterations}"
            );
            iterations
        };
        let first = solve(&mut amg, &step, &b);
        let renumbered = solve(&mut amg_r, &step_r, &b_r);
        assert!(
            first.abs_diff(renumbered) <= 1,
            "{first} and {renumbered} iterations"
        );
    }

    #[test]
    fn the_v_cycle_is_a_symmetric_positive_definite_preconditioner() {
        let (step, reference) = stiff_system(33);
        let mut amg = Amg::new(&reference);
        assert!(amg.sizes().len() >= 3, "levels {:?}", amg.sizes());
        amg.update(&step);
        for seed in 0..4 {
            let (x, y) = (random(&step, 2 * seed + 1), random(&step, 2 * seed + 2));
            let (mut mx, mut my) = (Vec3s::zeros(step.len()), Vec3s::zeros(step.len()));
            amg.apply(&step, &x, &mut mx);
            amg.apply(&step, &y, &mut my);
            let (xmy, ymx, xmx, ymy) = (dot(&x, &my), dot(&y, &mx), dot(&x, &mx), dot(&y, &my));
            assert!(xmx > 0.0 && ymy > 0.0, "x M x {xmx}, y M y {ymy}");
            assert!(
                (xmy - ymx).abs() <= 1e-5 * (xmx * ymy).sqrt(),
                "x M y {xmy} against y M x {ymx}"
            );
            for v in (0..step.len()).filter(|&v| step.diagonal[v] == Sym3::ZERO) {
                assert_eq!(mx.get(v), Vec3::ZERO, "held vertex {v} moved");
            }
        }
    }

    #[test]
    fn cg_iterations_grow_little_from_1k_to_16k_vertices() {
        let counts: Vec<u32> = [33, 129]
            .map(|n| {
                let (step, reference) = stiff_system(n);
                let mut amg = Amg::new(&reference);
                amg.update(&step);
                iterations(&mut amg, &step)
            })
            .to_vec();
        eprintln!("CG iterations at 1k and 16k vertices: {counts:?}");
        // Block Jacobi alone takes over a hundred at 1k and four hundred at 16k.
        assert!(counts.iter().all(|&c| c <= 25), "iterations {counts:?}");
        assert!(counts[1] <= counts[0] + 8, "iterations {counts:?}");
    }

    #[test]
    fn reusing_the_reference_coarse_operators_costs_iterations() {
        let (step, reference) = stiff_system(65);
        let mut rebuilt = Amg::new(&reference);
        rebuilt.update(&step);
        let mut reused = Amg::new(&reference);
        reused.update_smoother(&step);
        let (rebuilt, reused) = (
            iterations(&mut rebuilt, &step),
            iterations(&mut reused, &step),
        );
        eprintln!("CG iterations at 4k vertices: rebuilt {rebuilt}, reused {reused}");
        assert!(rebuilt < reused, "rebuilt {rebuilt}, reused {reused}");
    }
}
