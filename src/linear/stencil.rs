//! Symmetric 3 x 3 block matrices on a grid stencil of reach two.
//!
//! Row `p` of the matrix couples node `p = (i, j)` with the nodes `(i + di, j + dj)`,
//! `|di|, |dj| <= 2`: the 12-neighbour spring stencil of the cloth fits, and so does every
//! Galerkin coarsening of it by [`super::Multigrid`] (bilinear interpolation keeps the reach at
//! two). The matrix is symmetric and so is every block, so only the diagonal and the upper half of
//! the 5 x 5 neighbourhood are stored ([`OFFSETS`]), one array per block component and slot, and
//! the lower half is read from the partner's slot.
//!
//! Invariant: a block whose partner lies off the grid is zero. The products then run over whole
//! index ranges with linear offsets, without row-boundary branches (a wrapped-around partner is
//! multiplied by a zero block), like the spring kernels in `forces/springs.rs`.

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use crate::soa::{Floats, Vec3Slice, Vec3SliceMut, Vec3s};

/// Block slots per node: the diagonal and twelve neighbours.
pub const SLOTS: usize = 13;

/// `(di, dj)` of each slot: slot `s` of node `p` holds the block `A[p, p + OFFSETS[s]]`. Slot 0 is
/// the diagonal; the others are the upper half of the 5 x 5 neighbourhood (`dj > 0`, or `dj == 0`
/// and `di > 0`), so each has a positive index offset `di + dj * nx` for `nx >= 3`.
pub const OFFSETS: [(i32, i32); SLOTS] = [
    (0, 0),
    (1, 0),
    (2, 0),
    (-2, 1),
    (-1, 1),
    (0, 1),
    (1, 1),
    (2, 1),
    (-2, 2),
    (-1, 2),
    (0, 2),
    (1, 2),
    (2, 2),
];

/// The slot holding offset `(di, dj)` or its negation, and whether it was the negation (the block
/// is then read at the partner). None beyond reach two.
pub fn slot_of(di: i32, dj: i32) -> Option<(usize, bool)> {
    OFFSETS.iter().enumerate().find_map(|(s, &o)| {
        if o == (di, dj) {
            Some((s, false))
        } else if o == (-di, -dj) {
            Some((s, true))
        } else {
            None
        }
    })
}

/// A symmetric 3 x 3 block, as `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sym3(pub [f32; 6]);

impl Sym3 {
    pub const ZERO: Sym3 = Sym3([0.0; 6]);

    /// `alpha u u^T + beta I`.
    #[inline(always)]
    pub fn outer(alpha: f32, u: Vec3, beta: f32) -> Sym3 {
        Sym3([
            alpha * u.x * u.x + beta,
            alpha * u.y * u.y + beta,
            alpha * u.z * u.z + beta,
            alpha * u.x * u.y,
            alpha * u.x * u.z,
            alpha * u.y * u.z,
        ])
    }

    #[inline(always)]
    pub fn mul(&self, v: Vec3) -> Vec3 {
        let b = &self.0;
        Vec3::new(
            b[0] * v.x + b[3] * v.y + b[4] * v.z,
            b[3] * v.x + b[1] * v.y + b[5] * v.z,
            b[4] * v.x + b[5] * v.y + b[2] * v.z,
        )
    }

    #[inline(always)]
    pub fn add_scaled(&mut self, w: f32, other: &Sym3) {
        for (a, b) in self.0.iter_mut().zip(other.0) {
            *a += w * b;
        }
    }

    pub fn to_dmat3(self) -> DMat3 {
        let b = self.0.map(|x| x as f64);
        DMat3::from_cols(
            DVec3::new(b[0], b[3], b[4]),
            DVec3::new(b[3], b[1], b[5]),
            DVec3::new(b[4], b[5], b[2]),
        )
    }

    /// The inverse, computed in f64; zero for a block that is not positive definite (a held
    /// node's zero block, which the solvers leave untouched), so that a preconditioner built from
    /// it never moves such a node.
    pub fn inverse_or_zero(self) -> Sym3 {
        let m = self.to_dmat3();
        let (a, d, f) = (m.x_axis.x, m.y_axis.y, m.z_axis.z);
        let minor = a * d - m.y_axis.x * m.y_axis.x;
        let det = m.determinant();
        // Sylvester's criterion: all leading minors positive.
        if !(a > 0.0 && minor > 0.0 && det > 0.0 && f.is_finite() && det.is_finite()) {
            return Sym3::ZERO;
        }
        let inv = m.inverse();
        Sym3([
            inv.x_axis.x as f32,
            inv.y_axis.y as f32,
            inv.z_axis.z as f32,
            inv.y_axis.x as f32,
            inv.z_axis.x as f32,
            inv.z_axis.y as f32,
        ])
    }
}

/// Six component arrays of one slot, or empty ones for a slot that is not stored.
pub type SlotArrays = [Floats; 6];

/// The six component arrays of a slot in parallel chunks of `chunk` nodes: one array of six
/// chunk slices per work item.
pub fn par_chunks6(
    arrays: &mut SlotArrays,
    chunk: usize,
) -> impl IndexedParallelIterator<Item = [&mut [f32]; 6]> + '_ {
    let [a, b, c, d, e, f] = arrays;
    a.par_chunks_mut(chunk)
        .zip(b.par_chunks_mut(chunk))
        .zip(c.par_chunks_mut(chunk))
        .zip(d.par_chunks_mut(chunk))
        .zip(e.par_chunks_mut(chunk))
        .zip(f.par_chunks_mut(chunk))
        .map(|(((((a, b), c), d), e), f)| [a, b, c, d, e, f])
}

/// A symmetric block matrix on an `nx` x `ny` grid; see the module docs.
#[derive(Clone, Debug)]
pub struct BlockStencil {
    pub nx: usize,
    pub ny: usize,
    blocks: [SlotArrays; SLOTS],
    present: [bool; SLOTS],
}

impl BlockStencil {
    /// A zero matrix that stores the slots `present` (the diagonal always).
    pub fn new(nx: usize, ny: usize, present: &[usize]) -> Self {
        let n = nx * ny;
        let mut flags = [false; SLOTS];
        flags[0] = true;
        for &s in present {
            flags[s] = true;
        }
        let blocks = std::array::from_fn(|s| {
            let len = if flags[s] { n } else { 0 };
            std::array::from_fn(|_| Floats::zeros(len))
        });
        BlockStencil {
            nx,
            ny,
            blocks,
            present: flags,
        }
    }

    /// Every slot stored: the shape of a Galerkin coarse matrix.
    pub fn full(nx: usize, ny: usize) -> Self {
        let all: Vec<usize> = (0..SLOTS).collect();
        Self::new(nx, ny, &all)
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn is_present(&self, s: usize) -> bool {
        self.present[s]
    }

    /// The index offset of slot `s >= 1`, or None where it cannot be nonzero (a slot reaching
    /// two columns left on a grid two columns wide lands on the node itself).
    #[inline]
    pub fn linear_offset(&self, s: usize) -> Option<usize> {
        let (di, dj) = OFFSETS[s];
        let o = di as i64 + dj as i64 * self.nx as i64;
        (s > 0 && self.present[s] && o > 0 && (di.unsigned_abs() as usize) < self.nx)
            .then_some(o as usize)
    }

    pub fn slot(&self, s: usize) -> &SlotArrays {
        &self.blocks[s]
    }

    pub fn slot_mut(&mut self, s: usize) -> &mut SlotArrays {
        &mut self.blocks[s]
    }

    /// All slot arrays at once, for passes that write several slots.
    pub fn slots_mut(&mut self) -> &mut [SlotArrays; SLOTS] {
        &mut self.blocks
    }

    #[inline]
    pub fn block(&self, s: usize, p: usize) -> Sym3 {
        if !self.present[s] {
            return Sym3::ZERO;
        }
        let b = &self.blocks[s];
        Sym3(std::array::from_fn(|c| b[c][p]))
    }

    #[inline]
    pub fn set_block(&mut self, s: usize, p: usize, value: Sym3) {
        for (component, v) in self.blocks[s].iter_mut().zip(value.0) {
            component[p] = v;
        }
    }

    /// The block `A[p, q]` for any two nodes (zero beyond reach two).
    pub fn entry(&self, p: usize, q: usize) -> Sym3 {
        let (pi, pj) = ((p % self.nx) as i32, (p / self.nx) as i32);
        let (qi, qj) = ((q % self.nx) as i32, (q / self.nx) as i32);
        match slot_of(qi - pi, qj - pj) {
            Some((s, false)) => self.block(s, p),
            Some((s, true)) => self.block(s, q),
            None => Sym3::ZERO,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.blocks.iter().flatten().map(Floats::heap_bytes).sum()
    }

    /// `out = A x` over the rows `range` (`out` covers exactly `range`).
    #[inline(always)]
    pub fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        self.strips::<false>(x, None, range, out)
    }

    /// `out = b - A x` over the rows `range`.
    #[inline(always)]
    pub fn residual_range(
        &self,
        x: &Vec3s,
        b: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        self.strips::<true>(x, Some(b), range, out)
    }

    /// The product strip by strip: every block's contribution to a strip of [`STRIP`] rows is
    /// summed in registers and stored once (thirteen read-modify-write passes over the output
    /// cost a fifth of the product's time), in the same order as a pass per slot would.
    #[inline(always)]
    fn strips<const RESIDUAL: bool>(
        &self,
        x: &Vec3s,
        b: Option<&Vec3s>,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        let n = self.len();
        let mut slots = [(0usize, 0usize); SLOTS];
        let mut count = 0;
        for s in 1..SLOTS {
            if let Some(o) = self.linear_offset(s) {
                slots[count] = (s, o);
                count += 1;
            }
        }
        let slots = &slots[..count];
        let d = &self.blocks[0];
        let mut start = range.start;
        while start < range.end {
            let end = (start + STRIP).min(range.end);
            let mut acc = [[0.0f32; STRIP]; 3];
            let diag: [&[f32]; 6] = std::array::from_fn(|c| &d[c][start..end]);
            strip_product::<false>(diag, x.slices(start..end), &mut acc, 0);
            for &(s, o) in slots {
                let blocks = &self.blocks[s];
                // Rows that anchor the block (partner p + o), then rows at its far end (p - o).
                let anchors = start..end.min(n.saturating_sub(o));
                if !anchors.is_empty() {
                    let b: [&[f32]; 6] = std::array::from_fn(|c| &blocks[c][anchors.clone()]);
                    let xs = x.slices(anchors.start + o..anchors.end + o);
                    strip_product::<true>(b, xs, &mut acc, 0);
                }
                let ends = start.max(o)..end;
                if !ends.is_empty() {
                    let b: [&[f32]; 6] =
                        std::array::from_fn(|c| &blocks[c][ends.start - o..ends.end - o]);
                    let xs = x.slices(ends.start - o..ends.end - o);
                    strip_product::<true>(b, xs, &mut acc, ends.start - start);
                }
            }
            let dst = start - range.start..end - range.start;
            for (c, acc) in acc.iter().enumerate() {
                let o = &mut out.component_mut(c)[dst.clone()];
                match b {
                    Some(b) if RESIDUAL => {
                        let b = b.component(c, &(start..end));
                        for ((o, a), b) in o.iter_mut().zip(acc).zip(b) {
                            *o = b - a;
                        }
                    }
                    _ => o.copy_from_slice(&acc[..o.len()]),
                }
            }
            start = end;
        }
    }

    /// The inverse of every diagonal block ([`Sym3::inverse_or_zero`]) into `out`.
    pub fn diagonal_inverse(&self, out: &mut SlotArrays, chunk: usize) {
        let n = self.len();
        for c in out.iter_mut() {
            if c.len() != n {
                *c = Floats::zeros(n);
            }
        }
        let d0 = &self.blocks[0];
        par_chunks6(out, chunk)
            .enumerate()
            .for_each(|(ci, mut out)| {
                for i in 0..out[0].len() {
                    let p = ci * chunk + i;
                    let inv = Sym3(std::array::from_fn(|k| d0[k][p])).inverse_or_zero().0;
                    for (o, v) in out.iter_mut().zip(inv) {
                        o[i] = v;
                    }
                }
            });
    }
}

/// Rows per strip of [`BlockStencil::apply_range`]: three accumulators of 64 floats, twelve
/// AVX-512 registers.
const STRIP: usize = 64;

/// `acc[.][at..] (+)= B x` for a run of at most a strip.
#[inline(always)]
fn strip_product<const ADD: bool>(
    b: [&[f32]; 6],
    x: Vec3Slice,
    acc: &mut [[f32; STRIP]; 3],
    at: usize,
) {
    let n = x.x.len();
    let [bxx, byy, bzz, bxy, bxz, byz] = b.map(|s| &s[..n]);
    let (xx, xy, xz) = (&x.x[..n], &x.y[..n], &x.z[..n]);
    let [ax, ay, az] = acc;
    let (ax, ay, az) = (
        &mut ax[at..at + n],
        &mut ay[at..at + n],
        &mut az[at..at + n],
    );
    for i in 0..n {
        let px = bxx[i] * xx[i] + bxy[i] * xy[i] + bxz[i] * xz[i];
        let py = bxy[i] * xx[i] + byy[i] * xy[i] + byz[i] * xz[i];
        let pz = bxz[i] * xx[i] + byz[i] * xy[i] + bzz[i] * xz[i];
        (ax[i], ay[i], az[i]) = if ADD {
            (ax[i] + px, ay[i] + py, az[i] + pz)
        } else {
            (px, py, pz)
        };
    }
}

/// `out = B x` for a run of blocks and vectors of equal length.
#[inline(always)]
pub fn set_product(b: [&[f32]; 6], x: Vec3Slice, out: &mut Vec3SliceMut) {
    product::<false>(b, x, out)
}

/// `out += B x` for a run of blocks and vectors of equal length.
#[inline(always)]
pub fn add_product(b: [&[f32]; 6], x: Vec3Slice, out: &mut Vec3SliceMut) {
    product::<true>(b, x, out)
}

#[inline(always)]
fn product<const ADD: bool>(b: [&[f32]; 6], x: Vec3Slice, out: &mut Vec3SliceMut) {
    let n = out.len();
    let [bxx, byy, bzz, bxy, bxz, byz] = b.map(|s| &s[..n]);
    let (xx, xy, xz) = (&x.x[..n], &x.y[..n], &x.z[..n]);
    let (ox, oy, oz) = (&mut out.x[..n], &mut out.y[..n], &mut out.z[..n]);
    for i in 0..n {
        let px = bxx[i] * xx[i] + bxy[i] * xy[i] + bxz[i] * xz[i];
        let py = bxy[i] * xx[i] + byy[i] * xy[i] + byz[i] * xz[i];
        let pz = bxz[i] * xx[i] + byz[i] * xy[i] + bzz[i] * xz[i];
        // ADD is a constant: each instance is one straight, vectorised loop.
        (ox[i], oy[i], oz[i]) = if ADD {
            (ox[i] + px, oy[i] + py, oz[i] + pz)
        } else {
            (px, py, pz)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear::cg::BlockOperator;

    /// A random symmetric matrix with the stencil's shape and zero blocks off the grid.
    pub(crate) fn random_stencil(nx: usize, ny: usize, seed: u32) -> BlockStencil {
        let mut a = BlockStencil::full(nx, ny);
        let mut state = seed.wrapping_mul(2654435761).wrapping_add(1);
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state as f32 / u32::MAX as f32) - 0.5
        };
        for p in 0..nx * ny {
            let (i, j) = ((p % nx) as i32, (p / nx) as i32);
            for (s, &(di, dj)) in OFFSETS.iter().enumerate() {
                let (qi, qj) = (i + di, j + dj);
                if (0..nx as i32).contains(&qi) && (0..ny as i32).contains(&qj) {
                    a.set_block(s, p, Sym3(std::array::from_fn(|_| next())));
                }
            }
        }
        a
    }

    #[test]
    fn the_product_matches_a_dense_product_on_small_and_narrow_grids() {
        for (nx, ny) in [(2, 2), (2, 5), (3, 4), (7, 5)] {
            let a = random_stencil(nx, ny, (nx * 31 + ny) as u32);
            let n = nx * ny;
            let x = Vec3s::from_fn(n, |p| Vec3::new(p as f32, 1.0 - p as f32 * 0.5, 0.25));
            let mut y = Vec3s::zeros(n);
            a.apply(&x, &mut y, 3);
            for p in 0..n {
                let mut want = Vec3::ZERO;
                for q in 0..n {
                    want += a.entry(p, q).mul(x.get(q));
                }
                assert!((y.get(p) - want).length() < 1e-4, "{nx}x{ny} row {p}");
            }
        }
    }

    #[test]
    fn the_block_inverse_inverts_and_is_zero_for_an_indefinite_block() {
        let b = Sym3::outer(2.0, Vec3::new(0.6, 0.8, 0.0), 0.5);
        let inv = b.inverse_or_zero();
        let v = Vec3::new(0.3, -1.0, 2.0);
        assert!((inv.mul(b.mul(v)) - v).length() < 1e-5);
        assert_eq!(Sym3::ZERO.inverse_or_zero(), Sym3::ZERO);
        assert_eq!(
            Sym3::outer(-3.0, Vec3::X, 1.0).inverse_or_zero(),
            Sym3::ZERO
        );
    }
}
