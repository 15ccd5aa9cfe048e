//! The rows of a sparse matrix laid out for the vector unit (a sliced ELLPACK layout, as the
//! force pass's [`crate::scene::IncidenceLanes`]): the rows go in groups of [`LANES`], and slot
//! `k` of a group holds each lane's `k`-th entry, its column and its value's components apart,
//! so that one vector operation advances the group's [`LANES`] row sums together. The values
//! are symmetric 3 x 3 blocks ([`BlockLanes`], the multigrid's matrices) or scalars acting on
//! x, y and z alike ([`WeightLanes`], its transfers). Each lane still adds its own row's entries
//! in row order, each computed as [`Sym3::mul`] or `w * x` computes it, so a product is bitwise
//! what a row-by-row product gives; a slot past a row's end is masked, not added.
//!
//! A product streams the blocks once and gathers its operand by column [`LANES`] rows at a
//! time, which row by row it could not (measured in docs/mesh_cloth.md, "Implicit solvers").
//! The copy is laid out once per pattern and refilled when the values change.

use glam::Vec3;

use super::stencil::Sym3;
use crate::soa::{Vec3SliceMut, Vec3s};

/// Rows per group: the `f32` lanes of an AVX-512 register.
pub const LANES: usize = 16;

/// The source of a padding slot.
const PAD: u32 = u32::MAX;

/// Symmetric 3 x 3 blocks, six components a slot.
pub type BlockLanes = Lanes<6>;

/// Scalar weights, one component a slot.
pub type WeightLanes = Lanes<1>;

/// See the module docs: `C` components a value.
#[derive(Clone, Debug, Default)]
pub struct Lanes<const C: usize> {
    rows: usize,
    /// The length of the vectors a product reads (every column is below it).
    width: usize,
    /// Group `g`'s slots are `starts[g]..starts[g + 1]`.
    starts: Vec<u32>,
    /// Per slot and lane: the index of its block in the array [`BlockLanes::refill`] copies
    /// from ([`PAD`] past the row's end), its column (the lane's own row, or 0, there) and
    /// its block's components.
    source: Vec<[u32; LANES]>,
    columns: Vec<[u32; LANES]>,
    values: Vec<[[f32; LANES]; C]>,
    /// Each group's row lengths.
    lengths: Vec<[u32; LANES]>,
}

impl<const C: usize> Lanes<C> {
    /// The layout of the compressed rows `offsets[v]..offsets[v + 1]` of `columns` (each
    /// below `width`, the length of the vectors it will multiply) and `sources` (each entry's
    /// index into the values that [`Lanes::refill`] takes), with zero values.
    pub fn new(offsets: &[u32], columns: &[u32], sources: &[u32], width: usize) -> Self {
        let n = offsets.len().saturating_sub(1);
        assert!(
            columns.iter().all(|&c| (c as usize) < width) && width <= i32::MAX as usize,
            "a column beyond the {width} columns"
        );
        let mut lanes = Lanes {
            rows: n,
            width,
            starts: vec![0],
            ..Lanes::default()
        };
        for first in (0..n).step_by(LANES) {
            let lengths: [u32; LANES] = std::array::from_fn(|lane| {
                let v = first + lane;
                if v < n {
                    offsets[v + 1] - offsets[v]
                } else {
                    0
                }
            });
            for k in 0..lengths.iter().copied().max().unwrap_or(0) {
                let entry = |lane: usize| {
                    (k < lengths[lane]).then(|| offsets[first + lane] as usize + k as usize)
                };
                (lanes.source).push(std::array::from_fn(|l| {
                    entry(l).map_or(PAD, |i| sources[i])
                }));
                (lanes.columns).push(std::array::from_fn(|l| entry(l).map_or(0, |i| columns[i])));
            }
            lanes.lengths.push(lengths);
            lanes.starts.push(lanes.source.len() as u32);
        }
        lanes.values = vec![[[0.0; LANES]; C]; lanes.source.len()];
        lanes
    }

    /// Copies each entry's value from `values` (by the sources given to [`Lanes::new`]), its
    /// components as `components` gives them.
    pub fn refill<T: Sync>(&mut self, values: &[T], components: impl Fn(&T) -> [f32; C] + Sync) {
        use rayon::prelude::*;
        const CHUNK: usize = 1024;
        self.values
            .par_chunks_mut(CHUNK)
            .zip(self.source.par_chunks(CHUNK))
            .for_each(|(slots, sources)| {
                for (slot, sources) in slots.iter_mut().zip(sources) {
                    for (lane, &s) in sources.iter().enumerate() {
                        let value = values.get(s as usize).map_or([0.0; C], &components);
                        for (c, slot) in slot.iter_mut().enumerate() {
                            slot[lane] = value[c];
                        }
                    }
                }
            });
    }

    /// The entries of row `v` as [`Lanes::refill`] left them: `(column, components)`.
    pub fn entries(&self, v: usize) -> impl Iterator<Item = (usize, [f32; C])> + '_ {
        let (g, lane) = (v / LANES, v % LANES);
        let first = self.starts[g] as usize;
        (first..first + self.lengths[g][lane] as usize).map(move |k| {
            let values = &self.values[k];
            (
                self.columns[k][lane] as usize,
                std::array::from_fn(|c| values[c][lane]),
            )
        })
    }

    /// `out = start(v, out_v) + (sum of row v's entries) x` over the rows `range`, each
    /// entry's term `term(components, x_column)` added in row order, `start` given each row
    /// and its value in `out` as it was.
    #[inline(always)]
    pub fn apply_range(
        &self,
        x: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: impl Fn(usize, Vec3) -> Vec3,
        term: impl Fn([f32; C], Vec3) -> Vec3,
    ) {
        // Whole groups; a range that starts or ends inside a group takes its part of it.
        let mut v = range.start;
        while v < range.end {
            let g = v / LANES;
            let first = g * LANES;
            let mut acc = [[0.0f32; LANES]; 3];
            for (lane, u) in (first..self.rows.min(first + LANES)).enumerate() {
                let current = match range.contains(&u) {
                    true => Vec3::new(
                        out.x[u - range.start],
                        out.y[u - range.start],
                        out.z[u - range.start],
                    ),
                    false => Vec3::ZERO,
                };
                let s = start(u, current);
                (acc[0][lane], acc[1][lane], acc[2][lane]) = (s.x, s.y, s.z);
            }
            self.add_group(x, g, &mut acc, &term);
            let end = range.end.min(first + LANES);
            for u in v..end {
                let (i, lane) = (u - range.start, u - first);
                out.x[i] = acc[0][lane];
                out.y[i] = acc[1][lane];
                out.z[i] = acc[2][lane];
            }
            v = end;
        }
    }

    /// Adds group `g`'s terms with `x` to `acc`, lane by lane, in each row's order.
    #[inline(always)]
    fn add_group(
        &self,
        x: &Vec3s,
        g: usize,
        acc: &mut [[f32; LANES]; 3],
        term: &impl Fn([f32; C], Vec3) -> Vec3,
    ) {
        let n = self.width;
        let (xs, ys, zs) = (&x.x[..n], &x.y[..n], &x.z[..n]);
        let lengths = &self.lengths[g];
        let slots = self.starts[g] as usize..self.starts[g + 1] as usize;
        let rows = self.columns[slots.clone()].iter().zip(&self.values[slots]);
        for (k, (columns, b)) in rows.enumerate() {
            for lane in 0..LANES {
                // As a signed 32-bit offset, which the vector unit's gathers take directly
                // (an unsigned one is widened to 64 bits, and gathered half as wide).
                let c = columns[lane] as i32 as isize;
                // SAFETY: every column is below `n` and `i32::MAX` (checked in `new`), and so
                // within `x`'s slices cut to `n` above.
                let (vx, vy, vz) = unsafe {
                    (
                        *xs.as_ptr().offset(c),
                        *ys.as_ptr().offset(c),
                        *zs.as_ptr().offset(c),
                    )
                };
                let p = term(std::array::from_fn(|c| b[c][lane]), Vec3::new(vx, vy, vz));
                let live = (k as u32) < lengths[lane];
                acc[0][lane] = if live {
                    acc[0][lane] + p.x
                } else {
                    acc[0][lane]
                };
                acc[1][lane] = if live {
                    acc[1][lane] + p.y
                } else {
                    acc[1][lane]
                };
                acc[2][lane] = if live {
                    acc[2][lane] + p.z
                } else {
                    acc[2][lane]
                };
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.starts.capacity() * 4
            + (self.source.capacity() + self.columns.capacity() + self.lengths.capacity())
                * size_of::<[u32; LANES]>()
            + self.values.capacity() * size_of::<[[f32; LANES]; C]>()
    }
}

impl BlockLanes {
    /// [`Lanes::apply_range`] of the blocks, each term `block x_column` as [`Sym3::mul`]
    /// computes it.
    #[inline(always)]
    pub fn apply_blocks(
        &self,
        x: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: impl Fn(usize, Vec3) -> Vec3,
    ) {
        self.apply_range(x, range, out, start, |b, x| Sym3(b).mul(x));
    }
}

impl WeightLanes {
    /// [`Lanes::apply_range`] of the weights, each term `w x_column`.
    #[inline(always)]
    pub fn apply_weights(
        &self,
        x: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: impl Fn(usize, Vec3) -> Vec3,
    ) {
        self.apply_range(x, range, out, start, |[w], x| w * x);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of 0 to 19 entries (so groups of uneven rows and a last partial group), columns
    /// and blocks from a fixed hash, some entries repeating a column.
    fn rows(n: usize) -> (Vec<u32>, Vec<u32>, Vec<Sym3>) {
        let hash = |i: usize| (i as u32).wrapping_mul(2654435761) >> 7;
        let (mut offsets, mut columns, mut blocks) = (vec![0u32], Vec::new(), Vec::new());
        for v in 0..n {
            for k in 0..hash(v) % 20 {
                columns.push(hash(v * 31 + k as usize) % n as u32);
                let b = |c: usize| (hash(columns.len() * 7 + c) % 2001) as f32 / 1000.0 - 1.0;
                blocks.push(Sym3(std::array::from_fn(b)));
            }
            offsets.push(columns.len() as u32);
        }
        (offsets, columns, blocks)
    }

    #[test]
    fn a_product_is_bitwise_the_row_by_row_product_over_any_range() {
        let n = 83;
        let (offsets, columns, blocks) = rows(n);
        let sources: Vec<u32> = (0..columns.len() as u32).collect();
        let mut lanes = BlockLanes::new(&offsets, &columns, &sources, n);
        lanes.refill(&blocks, |b| b.0);
        let x = Vec3s::from_fn(n, |v| {
            Vec3::new(v as f32 * 0.37 - 9.0, 1.5, -(v as f32).sqrt())
        });
        let start = |v: usize| Vec3::splat(v as f32 * 0.01);
        let want: Vec<Vec3> = (0..n)
            .map(|v| {
                let mut acc = start(v);
                for k in offsets[v] as usize..offsets[v + 1] as usize {
                    acc += blocks[k].mul(x.get(columns[k] as usize));
                }
                acc
            })
            .collect();
        for range in [0..n, 0..16, 5..40, 16..32, 17..18, 70..83, 80..83] {
            let mut y = Vec3s::zeros(n);
            lanes.apply_blocks(
                &x,
                range.clone(),
                &mut y.slices_mut(range.clone()),
                |v, _| start(v),
            );
            for v in range {
                assert_eq!(
                    y.get(v).to_array().map(f32::to_bits),
                    want[v].to_array().map(f32::to_bits),
                    "row {v}"
                );
            }
        }
        for v in 0..n {
            let entries: Vec<(usize, Sym3)> = lanes.entries(v).map(|(c, b)| (c, Sym3(b))).collect();
            let k = offsets[v] as usize..offsets[v + 1] as usize;
            let stored: Vec<(usize, Sym3)> = k.map(|k| (columns[k] as usize, blocks[k])).collect();
            assert_eq!(entries, stored, "row {v}");
        }
    }
}
