//! The coarse operator: the Galerkin product `A_c = P^T A P` of a level's matrix and the
//! prolongation (`transfer.rs`), rebuilt whenever `A` changes (every implicit step). Its reach
//! stays two, so it is again a [`BlockStencil`].
//!
//! **Held nodes.** The systems multigrid serves are filtered: a pinned or cut particle's rows and
//! columns are zero and its unknown stays zero. With `A` filtered, `P^T A P` equals
//! `(S P)^T A (S P)` for the selector `S` of free nodes, so the coarse space never acts on a held
//! node through the matrix. A coarse node whose whole support is held gets a zero row and is
//! held in turn (Tamstorf, Jones and McCormick, "Smoothed aggregation multigrid for cloth
//! simulation", 2015, section 4, on why the constraints must be built into the coarse spaces
//! rather than applied after).
//!
//! Because the ghost node keeps the interpolation pattern the same at every node, an interior
//! coarse row is one fixed set of weighted sums (`interior_table`) over a zero-padded copy of
//! the fine matrix, with no boundary cases; only levels with a side of three nodes or fewer are
//! summed row by row.

use rayon::prelude::*;

use super::transfer::{Taps, Transfer1d};
use crate::linear::stencil::{BlockStencil, Sym3, OFFSETS, SLOTS};
use crate::soa::Floats;

/// Where the Galerkin sum reads its blocks: the children and parents along each axis.
trait Axes {
    fn children(&self, axis: usize, c: i64) -> Taps;
    /// None when fine node `f` is off the grid.
    fn parents(&self, axis: usize, f: i64) -> Option<Taps>;
}

impl Axes for (Transfer1d, Transfer1d) {
    fn children(&self, axis: usize, c: i64) -> Taps {
        let t = if axis == 0 { &self.0 } else { &self.1 };
        t.children[c as usize]
    }

    fn parents(&self, axis: usize, f: i64) -> Option<Taps> {
        let t = if axis == 0 { &self.0 } else { &self.1 };
        (0..t.fine as i64)
            .contains(&f)
            .then(|| t.parents[f as usize])
    }
}

/// The interior pattern on an unbounded grid, coarse node 0 at fine node 0.
struct Regular;

impl Regular {
    fn taps_of_fine(f: i64) -> Taps {
        let mut t = Taps::default();
        if f % 2 == 0 {
            t.push(f.div_euclid(2), 1.0);
        } else {
            t.push((f - 1).div_euclid(2), 0.5);
            t.push((f + 1).div_euclid(2), 0.5);
        }
        t
    }
}

impl Axes for Regular {
    fn children(&self, _axis: usize, c: i64) -> Taps {
        let mut t = Taps::default();
        t.push(2 * c - 1, 0.5);
        t.push(2 * c, 1.0);
        t.push(2 * c + 1, 0.5);
        t
    }

    fn parents(&self, _axis: usize, f: i64) -> Option<Taps> {
        Some(Self::taps_of_fine(f))
    }
}

/// Slot of each offset of the 5 x 5 neighbourhood, by `(dj + 2) * 5 + di + 2`, for the diagonal
/// and the upper half; `SLOTS` for the lower half.
const UPPER_SLOT: [usize; 25] = {
    let mut table = [SLOTS; 25];
    let mut s = 0;
    while s < SLOTS {
        let (di, dj) = OFFSETS[s];
        table[((dj + 2) * 5 + di + 2) as usize] = s;
        s += 1;
    }
    table
};

/// Coarse slot of coarse offset `(di, dj)` if it is the diagonal or in the upper half.
#[inline]
fn upper_slot(di: i64, dj: i64) -> Option<usize> {
    if di.abs() > 2 || dj.abs() > 2 {
        return None;
    }
    let s = UPPER_SLOT[((dj + 2) * 5 + di + 2) as usize];
    (s < SLOTS).then_some(s)
}

/// Visits every term of row `(ci, cj)` of `P^T A P`: `emit(coarse slot, weight, fine slot,
/// (i, j) of the fine node whose stored block of that slot is read)`. Only the diagonal and the
/// upper half of the coarse row are emitted; the rest is their transpose.
fn galerkin_terms(
    axes: &impl Axes,
    present: &[bool; SLOTS],
    (ci, cj): (i64, i64),
    mut emit: impl FnMut(usize, f32, usize, (i64, i64)),
) {
    for (pi, wi) in axes.children(0, ci).iter() {
        for (pj, wj) in axes.children(1, cj).iter() {
            let wp = wi * wj;
            // The fine row's entries: (slot, (qi, qj), where the block is stored).
            let mut visit = |s: usize, q: (i64, i64), at: (i64, i64)| {
                let (Some(tx), Some(ty)) = (axes.parents(0, q.0), axes.parents(1, q.1)) else {
                    return;
                };
                for (qi, wqi) in tx.iter() {
                    for (qj, wqj) in ty.iter() {
                        if let Some(t) = upper_slot(qi - ci, qj - cj) {
                            emit(t, wp * wqi * wqj, s, at);
                        }
                    }
                }
            };
            visit(0, (pi, pj), (pi, pj));
            for s in 1..SLOTS {
                if !present[s] {
                    continue;
                }
                let (di, dj) = (OFFSETS[s].0 as i64, OFFSETS[s].1 as i64);
                visit(s, (pi + di, pj + dj), (pi, pj));
                visit(s, (pi - di, pj - dj), (pi - di, pj - dj));
            }
        }
    }
}

/// One term of the interior Galerkin pattern.
#[derive(Clone, Copy, Debug)]
pub(super) struct Term {
    weight: f32,
    fine_slot: usize,
    /// Fine node read, relative to `(2 ci, 2 cj)`.
    at: (i64, i64),
}

/// The interior pattern's terms per coarse slot, equal terms merged.
pub(super) fn interior_table(present: &[bool; SLOTS]) -> [Vec<Term>; SLOTS] {
    let mut table: [Vec<Term>; SLOTS] = Default::default();
    galerkin_terms(&Regular, present, (0, 0), |t, w, s, at| {
        match table[t]
            .iter_mut()
            .find(|term| term.fine_slot == s && term.at == at)
        {
            Some(term) => term.weight += w,
            None => table[t].push(Term {
                weight: w,
                fine_slot: s,
                at,
            }),
        }
    });
    table
}

/// Zero padding of the de-interleaved fine rows: the interior pattern reads fine nodes up to
/// three columns and rows past the edge (coarse node `c` reads fine `2c - 3 ..= 2c + 3`).
const PAD: usize = 4;

/// `coarse = P^T fine P` (diagonal and upper half). Where both dimensions are coarsened, every
/// row follows the one interior pattern (`interior_table`) over a zero-padded, de-interleaved
/// copy of the fine matrix, one parallel task per coarse slot and component; otherwise (a side of
/// three nodes or fewer, on the coarsest levels and on strips) row by row in general.
pub(super) fn galerkin(
    fine: &BlockStencil,
    t: &(Transfer1d, Transfer1d),
    table: &[Vec<Term>; SLOTS],
    coarse: &mut BlockStencil,
    boundary: &mut Vec<(usize, [Sym3; SLOTS])>,
    split: &mut Vec<Floats>,
) {
    let (tx, ty) = t;
    let (nx, ny, ncx, ncy) = (fine.nx, fine.ny, tx.coarse, ty.coarse);
    let present: [bool; SLOTS] = std::array::from_fn(|s| fine.is_present(s));
    if !(tx.coarsened() && ty.coarsened()) {
        boundary.clear();
        for cj in 0..ncy {
            for ci in 0..ncx {
                let mut acc = [Sym3::ZERO; SLOTS];
                galerkin_terms(t, &present, (ci as i64, cj as i64), |s, w, fs, at| {
                    let p = at.1 as usize * nx + at.0 as usize;
                    acc[s].add_scaled(w, &fine.block(fs, p));
                });
                boundary.push((cj * ncx + ci, acc));
            }
        }
        for (node, acc) in boundary.iter() {
            for (s, block) in acc.iter().enumerate() {
                coarse.set_block(s, *node, *block);
            }
        }
        return;
    }
    // Row j of each fine slot component, padded by PAD zero rows, as [even columns | odd
    // columns], each half padded by PAD / 2 zero columns on both sides.
    let even = nx.div_ceil(2) + PAD;
    let stride = even + nx / 2 + PAD;
    let rows = ny + 2 * PAD;
    split.resize_with(SLOTS * 6, Floats::default);
    split.par_iter_mut().enumerate().for_each(|(k, out)| {
        let (s, c) = (k / 6, k % 6);
        if !present[s] {
            return;
        }
        if out.len() != rows * stride {
            *out = Floats::zeros(rows * stride);
        }
        let src = &fine.slot(s)[c];
        for j in 0..ny {
            let row = &src[j * nx..(j + 1) * nx];
            let dst = &mut out[(j + PAD) * stride..(j + PAD + 1) * stride];
            let (e, o) = dst.split_at_mut(even);
            for (d, v) in e[PAD / 2..].iter_mut().zip(row.iter().step_by(2)) {
                *d = *v;
            }
            for (d, v) in o[PAD / 2..].iter_mut().zip(row.iter().skip(1).step_by(2)) {
                *d = *v;
            }
        }
    });
    let split = &*split;
    let slots = coarse.slots_mut();
    let task = |s: usize, c: usize, out: &mut Floats| {
        out.fill(0.0);
        crate::simd::dispatch!({
            for cj in 0..ncy {
                let dst = &mut out[cj * ncx..(cj + 1) * ncx];
                for term in &table[s] {
                    let src = &split[term.fine_slot * 6 + c];
                    let row = (2 * cj as i64 + term.at.1 + PAD as i64) as usize;
                    // Fine column 2 ci + a is entry ci + (a - parity) / 2 of its parity's half.
                    let a = term.at.0;
                    let parity = a.rem_euclid(2);
                    let half = if parity == 0 { 0 } else { even };
                    let start = (row * stride + half + PAD / 2) as i64 + (a - parity) / 2;
                    let src = &src[start as usize..start as usize + ncx];
                    for (d, v) in dst.iter_mut().zip(src) {
                        *d += term.weight * v;
                    }
                }
            }
        })
    };
    slots.par_iter_mut().enumerate().for_each(|(s, arrays)| {
        arrays
            .par_iter_mut()
            .enumerate()
            .for_each(|(c, out)| task(s, c, out))
    });
}

#[cfg(test)]
mod tests {
    use super::super::tests::{cloth_like, dense};
    use super::super::Multigrid;
    use super::*;

    fn prolongation(t: &(Transfer1d, Transfer1d)) -> Vec<Vec<f64>> {
        let (nx, ny, ncx, ncy) = (t.0.fine, t.1.fine, t.0.coarse, t.1.coarse);
        let mut p = vec![vec![0.0; ncx * ncy]; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                for (cj, wj) in t.1.parents[j].iter() {
                    for (ci, wi) in t.0.parents[i].iter() {
                        p[j * nx + i][cj as usize * ncx + ci as usize] = (wi * wj) as f64;
                    }
                }
            }
        }
        p
    }

    #[test]
    fn the_coarse_matrix_is_the_galerkin_product_on_every_kind_of_grid() {
        for (nx, ny) in [(4, 5), (9, 8), (12, 13), (16, 16)] {
            let a = cloth_like(nx, ny, &[0, nx - 1]);
            let mut mg = Multigrid::new();
            mg.build(&a, 7);
            let coarse = &mg.levels[1].matrix;
            let t = &mg.transfers[0];
            let p = prolongation(t);
            let (n, nc) = (nx * ny, coarse.len());
            let ad = dense(&a);
            let cd = dense(coarse);
            for ci in 0..nc {
                for cj in 0..nc {
                    for r in 0..3 {
                        for c in 0..3 {
                            let mut want = 0.0;
                            for fp in 0..n {
                                if p[fp][ci] == 0.0 {
                                    continue;
                                }
                                for fq in 0..n {
                                    if p[fq][cj] != 0.0 {
                                        want += p[fp][ci]
                                            * ad[(3 * fp + r) * 3 * n + 3 * fq + c]
                                            * p[fq][cj];
                                    }
                                }
                            }
                            let got = cd[(3 * ci + r) * 3 * nc + 3 * cj + c];
                            assert!(
                                (got - want).abs() < 1e-3 * (1.0 + want.abs()),
                                "{nx}x{ny}: coarse ({ci},{cj}) [{r},{c}] {got} vs {want}"
                            );
                        }
                    }
                }
            }
        }
    }
}
