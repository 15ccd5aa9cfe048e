//! A symmetric matrix of 3 x 3 blocks over the springs of a mesh: a block-CSR whose rows are
//! the vertices and whose entries in row `a` are the springs touching `a`, in increasing spring
//! order. A spring's two off-diagonal blocks `A[a, b]` and `A[b, a]` are one symmetric block
//! (`C_s = alpha u u^T + beta I` is its own transpose), written once per spring ([`SpringMatrix::off`])
//! and copied into each of its two rows by [`SpringMatrix::gather`], so that a product streams
//! each row's blocks instead of looking them up by spring; two springs joining the same pair
//! are two entries that add up. The rows are stored for the vector unit, sixteen at a time
//! ([`BlockLanes`]). Each row's product sums its entries in a
//! fixed order, so `A x` is bitwise the same for any number of threads.

use super::block_lanes::{BlockLanes, Packed};
use super::cg::BlockOperator;
use super::stencil::Sym3;
use crate::soa::{Vec3SliceMut, Vec3s};

/// See the module docs.
#[derive(Clone, Debug, Default)]
pub struct SpringMatrix {
    /// Row `v`'s entries are `offsets[v]..offsets[v + 1]` of `spring` and `column`.
    offsets: Vec<u32>,
    spring: Vec<u32>,
    column: Vec<u32>,
    /// The diagonal block of each row.
    pub diagonal: Vec<Sym3>,
    /// The off-diagonal block of each spring.
    pub off: Vec<Sym3>,
    /// The off-diagonal blocks in row order, as [`SpringMatrix::gather`] copied them, laid out
    /// for the product.
    values: BlockLanes,
}

impl SpringMatrix {
    /// The zero matrix over `n` vertices and the springs `(a[e], b[e])`, with each vertex's
    /// incident springs `incident[offsets[v]..offsets[v + 1]]` as `spring << 1 | end` (`end` 1
    /// at the spring's `b`), as [`crate::mesh_cloth::MeshCloth`] lists them.
    pub fn new(a: &[u32], b: &[u32], offsets: &[u32], incident: &[u32]) -> Self {
        let n = offsets.len() - 1;
        let spring: Vec<u32> = incident.iter().map(|&e| e >> 1).collect();
        let column: Vec<u32> = incident
            .iter()
            .map(|&e| {
                let s = (e >> 1) as usize;
                if e & 1 == 0 {
                    b[s]
                } else {
                    a[s]
                }
            })
            .collect();
        SpringMatrix {
            values: BlockLanes::new(offsets, &column, &spring, n),
            offsets: offsets.to_vec(),
            spring,
            column,
            diagonal: vec![Sym3::ZERO; n],
            off: vec![Sym3::ZERO; a.len()],
        }
    }

    /// Copies each spring's block [`SpringMatrix::off`] into its two rows: call after writing
    /// `off`, before a product.
    pub fn gather(&mut self) {
        self.values.refill(&self.off, |b| b.0);
    }

    /// Rows (vertices).
    pub fn len(&self) -> usize {
        self.diagonal.len()
    }

    pub fn is_empty(&self) -> bool {
        self.diagonal.is_empty()
    }

    /// The entries of row `v`: `(spring, column)`.
    pub fn row(&self, v: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let r = self.offsets[v] as usize..self.offsets[v + 1] as usize;
        self.spring[r.clone()]
            .iter()
            .zip(&self.column[r])
            .map(|(&s, &c)| (s as usize, c as usize))
    }

    /// The off-diagonal entries of row `v`, `(column, block)`: the blocks [`SpringMatrix::off`]
    /// holds, which the product's copy holds too after [`SpringMatrix::gather`]. Read from
    /// `off` (a block's six components together) rather than from the product's layout (each
    /// component in a line of its own).
    pub fn row_blocks(&self, v: usize) -> impl Iterator<Item = (usize, Sym3)> + '_ {
        self.row(v).map(|(s, c)| (c, self.off[s]))
    }

    pub fn heap_bytes(&self) -> usize {
        self.offsets.capacity() * 4
            + self.spring.capacity() * 4
            + self.column.capacity() * 4
            + (self.diagonal.capacity() + self.off.capacity()) * size_of::<Sym3>()
            + self.values.heap_bytes()
    }
}

impl BlockOperator for SpringMatrix {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        (self.values).apply_blocks_from_diagonal((x, None), range, out, &self.diagonal);
    }

    fn packs(&self) -> bool {
        true
    }

    #[inline(always)]
    fn apply_range_packed(
        &self,
        (x, packed): (&Vec3s, &Packed),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        let operand = (x, Some(packed));
        (self.values).apply_blocks_from_diagonal(operand, range, out, &self.diagonal);
    }
}

impl SpringMatrix {
    /// `y = A x` over every row, serially (tests and residual checks).
    pub fn apply(&self, x: &Vec3s, y: &mut Vec3s) {
        let n = self.len();
        let mut out = y.slices_mut(0..n);
        self.apply_range(x, 0..n, &mut out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn the_product_is_the_dense_product_of_the_springs_blocks() {
        // A triangle (0, 1, 2) with springs 0-1, 1-2, 0-2 and a repeated 0-1.
        let (a, b) = ([0u32, 1, 0, 0], [1u32, 2, 2, 1]);
        let offsets = [0u32, 3, 6, 8];
        let incident = [0u32, 4, 6, 1, 2, 7, 3, 5];
        let mut m = SpringMatrix::new(&a, &b, &offsets, &incident);
        for (v, d) in m.diagonal.iter_mut().enumerate() {
            *d = Sym3::outer(1.0, Vec3::X, 2.0 + v as f32);
        }
        for (s, o) in m.off.iter_mut().enumerate() {
            *o = Sym3::outer(-0.5, Vec3::new(0.6, 0.8, 0.0), -(s as f32) * 0.1);
        }
        m.gather();
        let x = Vec3s::from_fn(3, |v| Vec3::new(v as f32, 1.0, -2.0 * v as f32));
        let mut y = Vec3s::zeros(3);
        m.apply(&x, &mut y);
        for v in 0..3 {
            let mut want = m.diagonal[v].mul(x.get(v));
            for s in 0..4 {
                let (p, q) = (a[s] as usize, b[s] as usize);
                if p == v {
                    want += m.off[s].mul(x.get(q));
                } else if q == v {
                    want += m.off[s].mul(x.get(p));
                }
            }
            assert!((y.get(v) - want).length() < 1e-5, "row {v}");
        }
    }
}
