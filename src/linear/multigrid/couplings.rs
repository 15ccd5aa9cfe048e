//! The self-contact pairs' couplings in the V-cycle's finest level.
//!
//! A pair adds `s (c c^T) (x) n n^T` to the operator: weights `c` on its four vertices, a unit
//! normal `n` and a stiffness `s`, kg. Its diagonal blocks `s c_i^2 n n^T` are in the caller's
//! matrix; its couplings `i != j` are not (its vertices may lie anywhere on the grid) and are
//! applied matrix-free. CG's product has them; a V-cycle whose finest residuals leave them out
//! smooths and corrects for another operator, and CG must then resolve the stiff couplings
//! itself. So the finest level's residuals subtract them too.
//!
//! The smoother must then stay convergent for the whole operator: block Jacobi on a rank-one
//! term over four vertices of like weights amplifies its mode up to fourfold, beyond what
//! `omega = 0.7` damps. Its diagonal is raised by `s |c_i| (sum_j |c_j| - |c_i|) n n^T`: by
//! Cauchy-Schwarz `(sum c_i y_i)^2 <= (sum |c_j|) sum |c_i| y_i^2`, so the raised diagonal
//! bounds each pair's term from above (an l1-Jacobi bound), `2 / omega D - A` stays positive
//! definite, and the V-cycle is a symmetric positive definite preconditioner whatever the coarse
//! levels hold.

use glam::Vec3;
use rayon::prelude::*;

use crate::linear::stencil::SlotArrays;
use crate::linear::Sym3;
use crate::soa::Vec3s;

/// One pair's rank-one term: `s (c c^T) (x) n n^T` over `verts`.
#[derive(Clone, Copy, Debug)]
pub struct Coupling {
    pub verts: [u32; 4],
    /// Weights, zero at held nodes (which get no row).
    pub c: [f32; 4],
    pub n: Vec3,
    /// Stiffness, kg.
    pub s: f32,
}

/// The pairs of one build, with each node's entries among them.
#[derive(Clone, Debug, Default)]
pub(super) struct Couplings {
    pairs: Vec<Coupling>,
    /// Node `p`'s entries are `entries[start[p]..start[p + 1]]`, in pair order, each
    /// `4 k + i`: vertex `i` of pair `k`.
    start: Vec<u32>,
    entries: Vec<u32>,
    /// Per pair, `n . sum_i c_i x_i` of the vector a product was last taken of.
    sums: Vec<f32>,
}

impl Couplings {
    pub(super) fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Holds `pairs` over `n` nodes.
    pub(super) fn set(&mut self, pairs: &[Coupling], n: usize) {
        self.pairs.clear();
        self.pairs.extend_from_slice(pairs);
        self.start.clear();
        self.entries.clear();
        if pairs.is_empty() {
            return;
        }
        self.start.resize(n + 1, 0);
        for pair in pairs {
            for (&v, &c) in pair.verts.iter().zip(&pair.c) {
                if c != 0.0 {
                    self.start[v as usize + 1] += 1;
                }
            }
        }
        for p in 0..n {
            self.start[p + 1] += self.start[p];
        }
        self.entries.resize(self.start[n] as usize, 0);
        let mut next: Vec<u32> = self.start[..n].to_vec();
        for (k, pair) in pairs.iter().enumerate() {
            for (i, (&v, &c)) in pair.verts.iter().zip(&pair.c).enumerate() {
                if c != 0.0 {
                    let at = &mut next[v as usize];
                    self.entries[*at as usize] = 4 * k as u32 + i as u32;
                    *at += 1;
                }
            }
        }
        self.sums.resize(pairs.len(), 0.0);
    }

    /// `s |c_i| (sum_j |c_j| - |c_i|) n n^T` of every pair onto its vertices' blocks of `d`:
    /// what raises the matrix's diagonal to the smoother's.
    pub(super) fn add_smoother_bound(&self, d: &mut SlotArrays) {
        for pair in &self.pairs {
            let block = Sym3::outer(1.0, pair.n, 0.0);
            let total: f32 = pair.c.iter().map(|c| c.abs()).sum();
            for (&p, &c) in pair.verts.iter().zip(&pair.c) {
                let w = pair.s * c.abs() * (total - c.abs());
                for (column, v) in d.iter_mut().zip(block.0) {
                    column[p as usize] += w * v;
                }
            }
        }
    }

    /// `r_i -= s c_i n (n . sum_{j != i} c_j x_j)` over every pair and each of its vertices `i`:
    /// the couplings a residual `b - A x` of the caller's matrix leaves out. Each pair's sum is
    /// taken once, then each row gathers its entries in pair order: the same for any number of
    /// threads.
    pub(super) fn subtract(&mut self, x: &Vec3s, r: &mut Vec3s, chunk: usize) {
        let pairs = &self.pairs;
        self.sums
            .par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(k0, sums)| {
                for (k, sum) in sums.iter_mut().enumerate() {
                    let pair = &pairs[k0 * chunk + k];
                    let mut all = 0.0;
                    for (&v, &c) in pair.verts.iter().zip(&pair.c) {
                        if c != 0.0 {
                            all += c * pair.n.dot(x.get(v as usize));
                        }
                    }
                    *sum = all;
                }
            });
        let (start, entries, sums) = (&self.start, &self.entries, &self.sums);
        r.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c0, mut out)| {
                for i in 0..out.len() {
                    let p = c0 * chunk + i;
                    let (xp, mut acc) = (x.get(p), out.get(i));
                    for &e in &entries[start[p] as usize..start[p + 1] as usize] {
                        let (k, v) = ((e / 4) as usize, (e % 4) as usize);
                        let pair = &pairs[k];
                        let c = pair.c[v];
                        let own = c * pair.n.dot(xp);
                        acc -= (pair.s * c) * (sums[k] - own) * pair.n;
                    }
                    out.set(i, acc);
                }
            });
    }
}
