//! Geometric multigrid with Galerkin coarse operators, a preconditioner for the conjugate
//! gradient on [`BlockStencil`] systems.
//!
//! **Hierarchy.** Each level halves the grid in both directions (a dimension of three nodes or
//! fewer is kept): coarse node `c` sits on fine node `2c`, and `n` fine nodes have `n / 2 + 1`
//! coarse ones (for even `n` the last coarse node sits on a ghost node `n` just past the edge).
//! The prolongation `P` is bilinear interpolation, the tensor product of the 1-D maps "an even
//! node copies its coarse node, an odd node averages its two", acting on each of the three
//! components alike (`P = (P_y (x) P_x) (x) I_3`). The ghost keeps that pattern the same at
//! every node, so the Galerkin product is one fixed set of weighted sums over a zero-padded copy
//! of the fine matrix, with no boundary cases.
//! The coarse matrix is the Galerkin product `A_c = P^T A P`, rebuilt whenever `A` changes (every
//! implicit step); its reach stays two, so it is again a [`BlockStencil`]. Coarsening stops at
//! three nodes a side, where a dense Cholesky factorisation solves exactly.
//!
//! **Held nodes.** The systems this serves are filtered: a pinned or cut particle's rows and
//! columns are zero and its unknown stays zero. With `A` filtered, `P^T A P` equals
//! `(S P)^T A (S P)` for the selector `S` of free nodes, so the coarse space never acts on a held
//! node through the matrix; prolongation is masked by `S`, so it never moves one either. A coarse
//! node whose whole support is held gets a zero row and is held in turn (Tamstorf, Jones and
//! McCormick, "Smoothed aggregation multigrid for cloth simulation", 2015, section 4, on why the
//! constraints must be built into the coarse spaces rather than applied after).
//!
//! **Cycle.** One V-cycle with one damped block-Jacobi sweep (`x += omega D^-1 (b - A x)`,
//! `omega = 0.7`) before and after the coarse correction. Pre- and post-smoother are the same
//! symmetric operator, so the cycle is a symmetric positive definite preconditioner and CG may
//! use it. Measured on the stiff pinned drape (k dt^2 / m about 4500 at 1/60 s): 8 to 16 CG
//! iterations to a relative residual of 1e-4 at 64 x 64 and 128 x 128, where block Jacobi needs
//! 170 to 500.
//!
//! Every pass is parallel over fixed chunks of nodes and writes only its own chunk, so the
//! result is bitwise the same for any number of threads.

use rayon::prelude::*;

use super::dense::DenseCholesky;
use super::stencil::{add_product, set_product, BlockStencil, SlotArrays, Sym3, OFFSETS, SLOTS};
use crate::soa::{Floats, Vec3s};

/// Damping of the block-Jacobi smoother: 2/3 is optimal for the Laplacian; measured 0.6 to 0.8
/// give the same iteration counts on cloth, 0.7 in the middle.
pub const OMEGA: f32 = 0.7;

/// Largest side the coarsest grid may have.
const COARSEST_SIDE: usize = 3;

/// Up to three `(index, weight)` pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Taps {
    n: usize,
    e: [(i64, f32); 3],
}

impl Taps {
    fn push(&mut self, index: i64, weight: f32) {
        self.e[self.n] = (index, weight);
        self.n += 1;
    }

    fn iter(&self) -> impl Iterator<Item = (i64, f32)> + '_ {
        self.e[..self.n].iter().copied()
    }
}

/// Linear interpolation along one dimension, from `coarse` to `fine` nodes.
#[derive(Clone, Debug, PartialEq)]
struct Transfer1d {
    fine: usize,
    coarse: usize,
    /// For each fine node, the coarse nodes it interpolates from.
    parents: Vec<Taps>,
    /// For each coarse node, the fine nodes it contributes to.
    children: Vec<Taps>,
    /// `children` as three padded tap arrays (index, weight), weight 0 for a missing tap: the
    /// loops of restriction and prolongation then have no branches.
    child_index: [Vec<u32>; 3],
    child_weight: [Vec<f32>; 3],
    /// `parents` as two padded tap arrays.
    parent_index: [Vec<u32>; 2],
    parent_weight: [Vec<f32>; 2],
}

impl Transfer1d {
    fn new(n: usize) -> Self {
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

    fn coarsened(&self) -> bool {
        self.coarse != self.fine
    }
}

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
struct Term {
    weight: f32,
    fine_slot: usize,
    /// Fine node read, relative to `(2 ci, 2 cj)`.
    at: (i64, i64),
}

/// The interior pattern's terms per coarse slot, equal terms merged.
fn interior_table(present: &[bool; SLOTS]) -> [Vec<Term>; SLOTS] {
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

/// `b_c = P^T r`, as two 1-D passes: along i into `half`, then along j.
fn restrict(t: &(Transfer1d, Transfer1d), r: &Vec3s, half: &mut Vec3s, bc: &mut Vec3s) {
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
fn prolong(
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

/// Zero padding of the de-interleaved fine rows: the interior pattern reads fine nodes up to
/// three columns and rows past the edge (coarse node `c` reads fine `2c - 3 ..= 2c + 3`).
const PAD: usize = 4;

/// `coarse = P^T fine P` (diagonal and upper half). Where both dimensions are coarsened, every
/// row follows the one interior pattern (`interior_table`) over a zero-padded, de-interleaved
/// copy of the fine matrix, one parallel task per coarse slot and component; otherwise (a side of
/// three nodes or fewer, on the coarsest levels and on strips) row by row in general.
fn galerkin(
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
    use super::super::stencil::BlockStencil;
    use super::*;
    use glam::Vec3;

    /// A filtered SPD matrix with the cloth stencil's shape: a mass term plus springs of random
    /// direction to the six spring-kind neighbours, some nodes held.
    fn cloth_like(nx: usize, ny: usize, held: &[usize]) -> BlockStencil {
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

    fn dense(a: &BlockStencil) -> Vec<f64> {
        let mut out = Vec::new();
        dense_of(a, &mut out);
        out
    }

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
