//! The matrices of the aggregation hierarchy: the coarse levels' block-CSR matrix
//! ([`BlockCsr`]), the scalar prolongator between two levels with its transpose ([`Transfer`]),
//! and the row visitor ([`BlockRows`]) that lets the Galerkin product read the fine level's
//! [`SpringMatrix`] and a coarse [`BlockCsr`] alike. Each keeps a copy of its rows laid out for
//! the vector unit ([`crate::linear::block_lanes`]) for its products in the cycle.

use glam::Vec3;
use rayon::prelude::*;

use crate::linear::block_lanes::{BlockLanes, WeightLanes};
use crate::linear::cg::BlockOperator;
use crate::linear::reduce::REDUCE_CHUNK;
use crate::linear::{SpringMatrix, Sym3};
use crate::soa::{Vec3SliceMut, Vec3s};

/// A symmetric block matrix whose rows can be visited entry by entry.
pub trait BlockRows: BlockOperator {
    fn rows(&self) -> usize;

    /// Calls `f(column, block)` for each stored entry of row `v`: the diagonal block first,
    /// then the others in storage order (repeated columns are separate entries that add up).
    fn for_each_entry(&self, v: usize, f: impl FnMut(usize, &Sym3));

    /// The diagonal block of row `v`.
    fn diagonal(&self, v: usize) -> Sym3;

    /// Calls `f(column, id)` for each stored entry of row `v` after its diagonal block, in
    /// [`BlockRows::for_each_entry`]'s order, `id` naming its block for [`BlockRows::block`]
    /// while the pattern stays.
    fn for_each_off_diagonal_id(&self, v: usize, f: impl FnMut(usize, u32));

    /// The block of the entry [`BlockRows::for_each_off_diagonal_id`] named `id`.
    fn block(&self, id: u32) -> &Sym3;
}

impl BlockRows for SpringMatrix {
    fn rows(&self) -> usize {
        self.len()
    }

    fn for_each_entry(&self, v: usize, mut f: impl FnMut(usize, &Sym3)) {
        f(v, &self.diagonal[v]);
        for (column, block) in self.row_blocks(v) {
            f(column, &block);
        }
    }

    fn diagonal(&self, v: usize) -> Sym3 {
        self.diagonal[v]
    }

    /// An entry's spring.
    fn for_each_off_diagonal_id(&self, v: usize, mut f: impl FnMut(usize, u32)) {
        for (spring, column) in self.row(v) {
            f(column, spring as u32);
        }
    }

    #[inline(always)]
    fn block(&self, id: u32) -> &Sym3 {
        &self.off[id as usize]
    }
}

/// A symmetric matrix of symmetric 3 x 3 blocks in compressed rows, both halves stored, the
/// diagonal block first in each row (a Galerkin product of a [`SpringMatrix`] by a scalar
/// prolongator keeps every block symmetric).
#[derive(Clone, Debug, Default)]
pub struct BlockCsr {
    /// Row `v`'s entries are `offsets[v]..offsets[v + 1]` of `columns` and `values`.
    pub(super) offsets: Vec<u32>,
    pub(super) columns: Vec<u32>,
    pub(super) values: Vec<Sym3>,
    /// `values` laid out for the product ([`BlockCsr::lay_out`]).
    lanes: BlockLanes,
}

impl BlockCsr {
    /// The matrix of the pattern `offsets`, `columns` (the diagonal first in each row), zero.
    pub fn zeros(offsets: Vec<u32>, columns: Vec<u32>) -> Self {
        let entries: Vec<u32> = (0..columns.len() as u32).collect();
        let n = offsets.len().saturating_sub(1);
        BlockCsr {
            lanes: BlockLanes::new(&offsets, &columns, &entries, n),
            values: vec![Sym3::ZERO; columns.len()],
            offsets,
            columns,
        }
    }

    /// Copies `values` into the product's layout: call after writing them, before a product.
    pub fn lay_out(&mut self) {
        self.lanes.refill(&self.values, |b| b.0);
    }

    pub fn range(&self, v: usize) -> std::ops::Range<usize> {
        self.offsets[v] as usize..self.offsets[v + 1] as usize
    }

    /// The `3n` x `3n` row-major dense matrix, unknowns ordered node by node (x, y, z).
    pub fn to_dense(&self, out: &mut Vec<f64>) {
        let n = self.rows();
        let m = 3 * n;
        out.clear();
        out.resize(m * m, 0.0);
        for v in 0..n {
            for k in self.range(v) {
                let c = self.columns[k] as usize;
                let b = self.values[k].to_dmat3();
                for i in 0..3 {
                    for j in 0..3 {
                        out[(3 * v + i) * m + 3 * c + j] += b.col(j)[i];
                    }
                }
            }
        }
    }
}

impl BlockRows for BlockCsr {
    fn rows(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    fn for_each_entry(&self, v: usize, mut f: impl FnMut(usize, &Sym3)) {
        for k in self.range(v) {
            f(self.columns[k] as usize, &self.values[k]);
        }
    }

    fn diagonal(&self, v: usize) -> Sym3 {
        self.values[self.offsets[v] as usize]
    }

    /// An entry's position in `values` (the diagonal is each row's first).
    fn for_each_off_diagonal_id(&self, v: usize, mut f: impl FnMut(usize, u32)) {
        for k in self.range(v).skip(1) {
            f(self.columns[k] as usize, k as u32);
        }
    }

    #[inline(always)]
    fn block(&self, id: u32) -> &Sym3 {
        &self.values[id as usize]
    }
}

impl BlockOperator for BlockCsr {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        self.lanes.apply_blocks(x, range, out, |_, _| Vec3::ZERO);
    }
}

/// A scalar prolongator `P` from a coarse level to a fine one (the same weight on x, y and z:
/// the near-null space is the three translations) and its transpose, both in compressed rows.
#[derive(Clone, Debug, Default)]
pub struct Transfer {
    /// Fine row `i`'s entries `(coarse column, weight)`.
    pub(super) p_offsets: Vec<u32>,
    pub(super) p_columns: Vec<u32>,
    pub(super) p_values: Vec<f32>,
    /// Coarse row `c`'s entries `(fine column, weight)` of `P^T`, fine columns increasing.
    pub(super) r_offsets: Vec<u32>,
    pub(super) r_columns: Vec<u32>,
    pub(super) r_values: Vec<f32>,
    /// `P` and `P^T` laid out for their products.
    p_lanes: WeightLanes,
    r_lanes: WeightLanes,
}

impl Transfer {
    /// `P` from its rows, each `(coarse column, weight)` with distinct columns; builds `P^T`.
    pub fn from_rows(rows: &[Vec<(u32, f32)>], coarse: usize) -> Self {
        let mut t = Transfer {
            p_offsets: vec![0],
            ..Transfer::default()
        };
        let mut counts = vec![0u32; coarse + 1];
        for row in rows {
            for &(c, w) in row {
                t.p_columns.push(c);
                t.p_values.push(w);
                counts[c as usize + 1] += 1;
            }
            t.p_offsets.push(t.p_columns.len() as u32);
        }
        for c in 0..coarse {
            counts[c + 1] += counts[c];
        }
        t.r_offsets = counts.clone();
        t.r_columns = vec![0; t.p_columns.len()];
        t.r_values = vec![0.0; t.p_columns.len()];
        for (i, row) in rows.iter().enumerate() {
            for &(c, w) in row {
                let k = &mut counts[c as usize];
                t.r_columns[*k as usize] = i as u32;
                t.r_values[*k as usize] = w;
                *k += 1;
            }
        }
        let entries: Vec<u32> = (0..t.p_columns.len() as u32).collect();
        t.p_lanes = WeightLanes::new(&t.p_offsets, &t.p_columns, &entries, coarse);
        t.p_lanes.refill(&t.p_values, |&w| [w]);
        t.r_lanes = WeightLanes::new(&t.r_offsets, &t.r_columns, &entries, rows.len());
        t.r_lanes.refill(&t.r_values, |&w| [w]);
        t
    }

    pub fn fine(&self) -> usize {
        self.p_offsets.len() - 1
    }

    pub fn coarse(&self) -> usize {
        self.r_offsets.len() - 1
    }

    /// Row `i` of `P`: its coarse columns and weights.
    pub fn p_row(&self, i: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        sparse_row(&self.p_offsets, &self.p_columns, &self.p_values, i)
    }

    /// Row `c` of `R = P^T`: its fine columns and weights.
    pub fn r_row(&self, c: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        sparse_row(&self.r_offsets, &self.r_columns, &self.r_values, c)
    }

    /// `coarse = P^T fine`, each coarse row summed over its fine rows in increasing order.
    pub fn restrict(&self, fine: &Vec3s, coarse: &mut Vec3s) {
        coarse
            .par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(ci, mut out)| {
                let range = ci * REDUCE_CHUNK..ci * REDUCE_CHUNK + out.len();
                crate::simd::dispatch!((self.r_lanes).apply_weights(
                    fine,
                    range.clone(),
                    &mut out,
                    |_, _| Vec3::ZERO
                ))
            });
    }

    /// `fine += P coarse`.
    pub fn prolong_add(&self, coarse: &Vec3s, fine: &mut Vec3s) {
        fine.par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(ci, mut out)| {
                let range = ci * REDUCE_CHUNK..ci * REDUCE_CHUNK + out.len();
                crate::simd::dispatch!((self.p_lanes).apply_weights(
                    coarse,
                    range.clone(),
                    &mut out,
                    |_, current| current
                ))
            });
    }
}

/// Runs `f(row, values)` for each row of a compressed-row array (`offsets[v]..offsets[v + 1]`
/// of `values` belong to row `v`) in `rows`, in parallel over consecutive ranges split in halves
/// down to `chunk` rows, so that each call writes only its own row's values and nothing is
/// allocated.
pub fn for_each_row<T: Send>(
    values: &mut [T],
    offsets: &[u32],
    rows: std::ops::Range<usize>,
    chunk: usize,
    f: &(impl Fn(usize, &mut [T]) + Sync),
) {
    if rows.len() <= chunk {
        let base = offsets[rows.start] as usize;
        for v in rows {
            f(
                v,
                &mut values[offsets[v] as usize - base..offsets[v + 1] as usize - base],
            );
        }
        return;
    }
    let mid = rows.start + rows.len() / 2;
    let split = (offsets[mid] - offsets[rows.start]) as usize;
    let (left, right) = values.split_at_mut(split);
    rayon::join(
        || for_each_row(left, offsets, rows.start..mid, chunk, f),
        || for_each_row(right, offsets, mid..rows.end, chunk, f),
    );
}

/// Row `i` of a scalar compressed-row matrix: its columns and values.
fn sparse_row<'a>(
    offsets: &[u32],
    columns: &'a [u32],
    values: &'a [f32],
    i: usize,
) -> impl Iterator<Item = (usize, f32)> + 'a {
    let r = offsets[i] as usize..offsets[i + 1] as usize;
    columns[r.clone()]
        .iter()
        .zip(&values[r])
        .map(|(&c, &w)| (c as usize, w))
}
