//! The grid transfers between one level and the next: the prolongation `P` and the
//! restriction `P^T`.
//!
//! Each level halves the grid in both directions (a dimension of three nodes or fewer is kept):
//! coarse node `c` sits on fine node `2c`, and `n` fine nodes have `n / 2 + 1` coarse ones (for
//! even `n` the last coarse node sits on a ghost node `n` just past the edge). `P` is bilinear
//! interpolation, the tensor product of the 1-D maps "an even node copies its coarse node, an
//! odd node averages its two", acting on each of the three components alike
//! (`P = (P_y (x) P_x) (x) I_3`). The ghost keeps that pattern the same at every node, which is
//! what lets the Galerkin product (`galerkin.rs`) be one fixed set of weighted sums.
//!
//! Both transfers run as two 1-D passes, one along each axis, so each pass reads whole rows.
//! Prolongation is masked by the selector `S` of free nodes, so a correction never moves a held
//! node.

use rayon::prelude::*;

use crate::soa::{Floats, Vec3s};

/// Largest side the coarsest grid may have.
pub(super) const COARSEST_SIDE: usize = 3;

/// Up to three `(index, weight)` pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Taps {
    n: usize,
    e: [(i64, f32); 3],
}

impl Taps {
    pub(super) fn push(&mut self, index: i64, weight: f32) {
        self.e[self.n] = (index, weight);
        self.n += 1;
    }

    pub(super) fn iter(&self) -> impl Iterator<Item = (i64, f32)> + '_ {
        self.e[..self.n].iter().copied()
    }
}

/// Linear interpolation along one dimension, from `coarse` to `fine` nodes.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Transfer1d {
    pub(super) fine: usize,
    pub(super) coarse: usize,
    /// For each fine node, the coarse nodes it interpolates from.
    pub(super) parents: Vec<Taps>,
    /// For each coarse node, the fine nodes it contributes to.
    pub(super) children: Vec<Taps>,
    /// `children` as three padded tap arrays (index, weight), weight 0 for a missing tap: the
    /// loops of restriction and prolongation then have no branches.
    pub(super) child_index: [Vec<u32>; 3],
    pub(super) child_weight: [Vec<f32>; 3],
    /// `parents` as two padded tap arrays.
    pub(super) parent_index: [Vec<u32>; 2],
    pub(super) parent_weight: [Vec<f32>; 2],
}

impl Transfer1d {
    pub(super) fn new(n: usize) -> Self {
        let coarsened = n > COARSEST_SIDE;
        let coarse = if coarsened { n / 2 + 1 } else { n };
        let parents: Vec<Taps> = (0..n)
            .map(|f| {
                let mut t = Taps::default();
                if !coarsened {
                    t.push(f as i64, 1.0);
                } else if f % 2 == 0 {
                    t.push(f as i64 / 2, 1.0);
                } else {
                    t.push(f as i64 / 2, 0.5);
                    t.push(f as i64 / 2 + 1, 0.5);
                }
                t
            })
            .collect();
        let mut children = vec![Taps::default(); coarse];
        for (f, taps) in parents.iter().enumerate() {
            for (c, w) in taps.iter() {
                children[c as usize].push(f as i64, w);
            }
        }
        let padded = |taps: &[Taps], k: usize| -> (Vec<u32>, Vec<f32>) {
            taps.iter()
                .map(|t| {
                    if k < t.n {
                        (t.e[k].0 as u32, t.e[k].1)
                    } else {
                        (t.e[0].0 as u32, 0.0)
                    }
                })
                .unzip()
        };
        let (c0, c1, c2) = (
            padded(&children, 0),
            padded(&children, 1),
            padded(&children, 2),
        );
        let (p0, p1) = (padded(&parents, 0), padded(&parents, 1));
        Transfer1d {
            fine: n,
            coarse,
            parents,
            children,
            child_index: [c0.0, c1.0, c2.0],
            child_weight: [c0.1, c1.1, c2.1],
            parent_index: [p0.0, p1.0],
            parent_weight: [p0.1, p1.1],
        }
    }

    pub(super) fn coarsened(&self) -> bool {
        self.coarse != self.fine
    }
}

/// `b_c = P^T r`, as two 1-D passes: along i into `half`, then along j.
pub(super) fn restrict(t: &(Transfer1d, Transfer1d), r: &Vec3s, half: &mut Vec3s, bc: &mut Vec3s) {
    let (tx, ty) = t;
    let (nx, ncx) = (tx.fine, tx.coarse);
    half.par_chunks_mut(ncx).enumerate().for_each(|(j, row)| {
        let src = r.slices(j * nx..(j + 1) * nx);
        for (dst, src) in [
            (&mut *row.x, src.x),
            (&mut *row.y, src.y),
            (&mut *row.z, src.z),
        ] {
            if tx.coarsened() {
                restrict_row(src, dst);
                continue;
            }
            for (ci, d) in dst.iter_mut().enumerate() {
                let mut sum = 0.0;
                for k in 0..3 {
                    sum += tx.child_weight[k][ci] * src[tx.child_index[k][ci] as usize];
                }
                *d = sum;
            }
        }
    });
    let half = &*half;
    bc.par_chunks_mut(ncx)
        .enumerate()
        .for_each(|(cj, mut row)| {
            let taps: [(usize, f32); 3] =
                std::array::from_fn(|k| (ty.child_index[k][cj] as usize, ty.child_weight[k][cj]));
            crate::simd::dispatch!(weighted_rows(&taps, half, ncx, &mut row))
        });
}

/// `dst = sum_k w_k src[row_k]` for rows of `width` nodes: one pass along j of a transfer.
#[inline(always)]
fn weighted_rows<const K: usize>(
    taps: &[(usize, f32); K],
    src: &Vec3s,
    width: usize,
    dst: &mut crate::soa::Vec3SliceMut,
) {
    let rows = taps.map(|(j, _)| src.slices(j * width..(j + 1) * width));
    for c in 0..3 {
        let out = dst.component_mut(c);
        let rows = rows.map(|r| [r.x, r.y, r.z][c]);
        for (i, o) in out.iter_mut().enumerate() {
            let mut sum = 0.0;
            for (row, &(_, w)) in rows.iter().zip(taps) {
                sum += w * row[i];
            }
            *o = sum;
        }
    }
}

/// One row of the restriction along a coarsened axis: coarse `c` is fine `2c` plus half of
/// `2c - 1` and `2c + 1`, where they exist (the taps of [`Transfer1d`], without their indices).
fn restrict_row(fine: &[f32], coarse: &mut [f32]) {
    let n = fine.len();
    let at = |i: usize| if i < n { fine[i] } else { 0.0 };
    coarse[0] = fine[0] + 0.5 * at(1);
    // Interior: every coarse node with both odd neighbours on the grid.
    let interior = (n - 1) / 2;
    for (d, w) in coarse[1..interior.max(1)]
        .iter_mut()
        .zip(fine[1..].windows(3).step_by(2))
    {
        *d = w[1] + 0.5 * (w[0] + w[2]);
    }
    for (c, d) in coarse.iter_mut().enumerate().skip(interior.max(1)) {
        *d = at(2 * c) + 0.5 * (fine[2 * c - 1] + at(2 * c + 1));
    }
}

/// One row of the prolongation along a coarsened axis, masked: fine `2c` copies coarse `c`,
/// fine `2c + 1` averages `c` and `c + 1`.
fn prolong_row(coarse: &[f32], free: &[f32], fine: &mut [f32]) {
    let pairs = fine.len() / 2;
    let (head, tail) = fine.split_at_mut(2 * pairs);
    for (((out, f), c), w) in head
        .chunks_exact_mut(2)
        .zip(free.chunks_exact(2))
        .zip(coarse)
        .zip(coarse.windows(2))
    {
        out[0] += f[0] * c;
        out[1] += f[1] * (0.5 * (w[0] + w[1]));
    }
    if let Some(last) = tail.first_mut() {
        *last += free[2 * pairs] * coarse[pairs];
    }
}

/// `x += S P x_c`, as two 1-D passes: along j into `half`, then along i.
pub(super) fn prolong(
    t: &(Transfer1d, Transfer1d),
    xc: &Vec3s,
    half: &mut Vec3s,
    free: &Floats,
    x: &mut Vec3s,
) {
    let (tx, ty) = t;
    let (nx, ncx) = (tx.fine, tx.coarse);
    half.par_chunks_mut(ncx)
        .enumerate()
        .for_each(|(j, mut row)| {
            let taps: [(usize, f32); 2] =
                std::array::from_fn(|k| (ty.parent_index[k][j] as usize, ty.parent_weight[k][j]));
            crate::simd::dispatch!(weighted_rows(&taps, xc, ncx, &mut row))
        });
    let half = &*half;
    x.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        let src = half.slices(j * ncx..(j + 1) * ncx);
        let f = &free[j * nx..(j + 1) * nx];
        for (dst, src) in [
            (&mut *row.x, src.x),
            (&mut *row.y, src.y),
            (&mut *row.z, src.z),
        ] {
            if tx.coarsened() {
                prolong_row(src, f, dst);
                continue;
            }
            for (i, d) in dst.iter_mut().enumerate() {
                let sum = tx.parent_weight[0][i] * src[tx.parent_index[0][i] as usize]
                    + tx.parent_weight[1][i] * src[tx.parent_index[1][i] as usize];
                *d += f[i] * sum;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_row_transfers_are_the_taps_of_the_interpolation() {
        for n in 4..13 {
            let t = Transfer1d::new(n);
            let fine: Vec<f32> = (0..n).map(|i| (i as f32 * 0.7).sin()).collect();
            let mut coarse = vec![0.0; t.coarse];
            restrict_row(&fine, &mut coarse);
            for (c, taps) in t.children.iter().enumerate() {
                let want: f32 = taps.iter().map(|(f, w)| w * fine[f as usize]).sum();
                assert!((coarse[c] - want).abs() < 1e-6, "n {n}, restrict {c}");
            }
            let free: Vec<f32> = (0..n).map(|i| (i % 5 != 3) as u32 as f32).collect();
            let mut out = vec![1.0; n];
            prolong_row(&coarse, &free, &mut out);
            for (f, taps) in t.parents.iter().enumerate() {
                let sum: f32 = taps.iter().map(|(c, w)| w * coarse[c as usize]).sum();
                assert!(
                    (out[f] - (1.0 + free[f] * sum)).abs() < 1e-6,
                    "n {n}, prolong {f}"
                );
            }
        }
    }
}
