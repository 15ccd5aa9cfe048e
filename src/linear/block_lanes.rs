//! The rows of a sparse matrix laid out for the vector unit (a sliced ELLPACK layout, as the
//! force pass's [`crate::scene::IncidenceLanes`]): the rows go in groups of [`LANES`], and slot
//! `k` of a group holds each lane's `k`-th entry, its column and its value's components apart,
//! so that one vector operation advances the group's [`LANES`] row sums together. The values
//! are symmetric 3 x 3 blocks ([`BlockLanes`], the multigrid's matrices) or scalars acting on
//! x, y and z alike ([`WeightLanes`], its transfers). Each lane still adds its own row's entries
//! in row order, each computed as [`Sym3::mul`] or `w * x` computes it, so a product is bitwise
//! what a row-by-row product gives; a slot past a row's end adds `-0.0`, which leaves any sum
//! bitwise as it is.
//!
//! A product streams the blocks once and gathers its operand by column [`LANES`] rows at a
//! time, which row by row it could not (measured in docs/notes/mesh_cloth.md, "How the multigrid
//! was chosen and tuned").
//! The copy is laid out once per pattern and refilled when the values change.
//!
//! A group is as long as its longest row, and a product streams its padding too: on an
//! irregular mesh consecutive rows differ in length by up to half. So the rows of each
//! [`WINDOW`] of consecutive rows are grouped by length, longest first (ties in row order),
//! and a group's lanes hold rows from anywhere in its window: a product still reads its
//! operand near the window, and writes each row where it belongs.

use glam::Vec3;

use super::stencil::Sym3;
use crate::soa::{Vec3SliceMut, Vec3s};

/// Rows per group: the `f32` lanes of an AVX-512 register.
pub const LANES: usize = 16;

/// Consecutive rows whose groups are formed by length: a multiple of [`LANES`]. Larger leaves
/// less padding (on the 16k-vertex jittered mesh, 21 % of the slots with groups of
/// consecutive rows, 7.5 % with windows of 64 rows, 2 % with 256) but spreads a group's
/// operand wider, and a range of rows that cuts a window computes all of that window's
/// groups that hold a row of the range.
pub const WINDOW: usize = 256;

/// The source of a padding slot, and the row of an empty lane.
const PAD: u32 = u32::MAX;

/// Symmetric 3 x 3 blocks, six components a slot.
pub type BlockLanes = Lanes<6>;

/// Scalar weights, one component a slot.
pub type WeightLanes = Lanes<1>;

/// See the module docs: `C` components a value.
#[derive(Clone, Debug, Default)]
pub struct Lanes<const C: usize> {
    /// The length of the vectors a product reads (every column is below it).
    width: usize,
    /// Group `g`'s slots are `starts[g]..starts[g + 1]`.
    starts: Vec<u32>,
    /// Per slot and lane: the index of its block in the array [`BlockLanes::refill`] copies
    /// from ([`PAD`] past the row's end), its column (the lane's own row, or 0, there) and
    /// its block's components.
    source: Vec<[u32; LANES]>,
    columns: Columns,
    values: Vec<[[f32; LANES]; C]>,
    /// Each group's row lengths, and the row each of its lanes holds ([`PAD`] for none).
    lengths: Vec<[u32; LANES]>,
    lane_rows: Vec<[u32; LANES]>,
    /// Each row's group and lane, as `group * LANES + lane`.
    place: Vec<u32>,
    /// Each group's least column and one past its greatest (`[0, 0]` for no entry): the
    /// operand's rows a product of the group reads (packed products only, on x86-64).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    spans: Vec<[u32; 2]>,
}

/// Each slot's columns: where every group's columns span less than 2^16, as 16-bit offsets
/// from a base per group (a product then streams two bytes a column instead of four, and an
/// offset and its base make the same signed 32-bit index); as they are otherwise.
#[derive(Clone, Debug)]
enum Columns {
    Narrow {
        base: Vec<u32>,
        offset: Vec<[u16; LANES]>,
    },
    Wide(Vec<[u32; LANES]>),
}

impl Default for Columns {
    fn default() -> Self {
        Columns::Wide(Vec::new())
    }
}

impl Columns {
    /// `wide` (group `g`'s slots `starts[g]..starts[g + 1]`, lane `l` live in its first
    /// `lengths[g][l]`), narrowed where it can be; a dead slot gets its group's base.
    fn narrowed(wide: Vec<[u32; LANES]>, starts: &[u32], lengths: &[[u32; LANES]]) -> Self {
        let live = |g: usize| {
            let first = starts[g] as usize;
            (first..starts[g + 1] as usize).flat_map(move |k| {
                (0..LANES)
                    .filter_map(move |l| ((k - first) < lengths[g][l] as usize).then_some((k, l)))
            })
        };
        let mut base = Vec::with_capacity(lengths.len());
        for g in 0..lengths.len() {
            let columns = || live(g).map(|(k, l)| wide[k][l]);
            let (low, high) = (columns().min().unwrap_or(0), columns().max().unwrap_or(0));
            if high - low > u16::MAX as u32 {
                return Columns::Wide(wide);
            }
            base.push(low);
        }
        let mut offset = vec![[0u16; LANES]; wide.len()];
        for (g, &low) in base.iter().enumerate() {
            for (k, l) in live(g) {
                offset[k][l] = (wide[k][l] - low) as u16;
            }
        }
        Columns::Narrow { base, offset }
    }

    /// The column of slot `k` (of group `g`) in lane `l`.
    fn get(&self, g: usize, k: usize, l: usize) -> usize {
        match self {
            Columns::Narrow { base, offset } => base[g] as usize + offset[k][l] as usize,
            Columns::Wide(wide) => wide[k][l] as usize,
        }
    }

    fn heap_bytes(&self) -> usize {
        match self {
            Columns::Narrow { base, offset } => base.capacity() * 4 + offset.capacity() * 2 * LANES,
            Columns::Wide(wide) => wide.capacity() * 4 * LANES,
        }
    }
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
            width,
            starts: vec![0],
            ..Lanes::default()
        };
        lanes.place = vec![0; n];
        let length = |v: usize| offsets[v + 1] - offsets[v];
        let mut window: Vec<u32> = Vec::with_capacity(WINDOW);
        let mut wide: Vec<[u32; LANES]> = Vec::new();
        for first in (0..n).step_by(WINDOW) {
            window.clear();
            window.extend(first as u32..n.min(first + WINDOW) as u32);
            window.sort_by_key(|&v| std::cmp::Reverse(length(v as usize)));
            for rows in window.chunks(LANES) {
                let g = lanes.lengths.len();
                let lane_rows: [u32; LANES] =
                    std::array::from_fn(|lane| rows.get(lane).copied().unwrap_or(PAD));
                let lengths = lane_rows.map(|v| if v == PAD { 0 } else { length(v as usize) });
                for (lane, &v) in rows.iter().enumerate() {
                    lanes.place[v as usize] = (g * LANES + lane) as u32;
                }
                for k in 0..lengths.iter().copied().max().unwrap_or(0) {
                    let entry = |lane: usize| {
                        (k < lengths[lane])
                            .then(|| offsets[lane_rows[lane] as usize] as usize + k as usize)
                    };
                    (lanes.source).push(std::array::from_fn(|l| {
                        entry(l).map_or(PAD, |i| sources[i])
                    }));
                    wide.push(std::array::from_fn(|l| entry(l).map_or(0, |i| columns[i])));
                }
                lanes.lengths.push(lengths);
                lanes.lane_rows.push(lane_rows);
                lanes.starts.push(lanes.source.len() as u32);
            }
        }
        lanes.values = vec![[[0.0; LANES]; C]; lanes.source.len()];
        lanes.spans = (0..lanes.lengths.len())
            .map(|g| {
                let first = lanes.starts[g] as usize;
                let live = (first..lanes.starts[g + 1] as usize).flat_map(|k| {
                    let lengths = &lanes.lengths[g];
                    (0..LANES).filter_map(move |l| {
                        ((k - first) < lengths[l] as usize).then_some(k * LANES + l)
                    })
                });
                let columns = || live.clone().map(|i| wide[i / LANES][i % LANES]);
                match columns().min() {
                    Some(low) => [low, columns().max().unwrap_or(low) + 1],
                    None => [0, 0],
                }
            })
            .collect();
        lanes.columns = Columns::narrowed(wide, &lanes.starts, &lanes.lengths);
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
        let (g, lane) = (
            self.place[v] as usize / LANES,
            self.place[v] as usize % LANES,
        );
        let first = self.starts[g] as usize;
        (first..first + self.lengths[g][lane] as usize).map(move |k| {
            let values = &self.values[k];
            (
                self.columns.get(g, k, lane),
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
        let groups = self.groups(&range);
        self.apply_groups(groups, range, out, Some(start), |g, acc| {
            self.add_group(x, g, acc, &term)
        });
    }

    /// The groups of every window the rows `range` meet.
    fn groups(&self, range: &std::ops::Range<usize>) -> std::ops::Range<usize> {
        let per_window = WINDOW / LANES;
        range.start / WINDOW * per_window
            ..self
                .lengths
                .len()
                .min(range.end.div_ceil(WINDOW) * per_window)
    }

    /// [`Lanes::apply_range`] with each group's terms added by `add(g, acc)`; without `start`,
    /// `add` sets the sums' starts itself.
    #[inline(always)]
    fn apply_groups(
        &self,
        groups: std::ops::Range<usize>,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: Option<impl Fn(usize, Vec3) -> Vec3>,
        mut add: impl FnMut(usize, &mut [[f32; LANES]; 3]),
    ) {
        if range.is_empty() {
            return;
        }
        // A group that holds a row of the range is computed whole, and only the range's rows
        // are written.
        let per_window = WINDOW / LANES;
        let whole = |g: usize| {
            let first = g / per_window * WINDOW;
            range.start <= first && first + WINDOW <= range.end
        };
        for g in groups {
            let rows = &self.lane_rows[g];
            let inside = |u: u32| u != PAD && range.contains(&(u as usize));
            if !whole(g) && !rows.iter().any(|&u| inside(u)) {
                continue;
            }
            let mut acc = [[0.0f32; LANES]; 3];
            let lanes = rows.iter().enumerate().filter(|_| start.is_some());
            for (lane, &u) in lanes {
                if u == PAD {
                    continue;
                }
                let u = u as usize;
                let current = match range.contains(&u) {
                    true => Vec3::new(
                        out.x[u - range.start],
                        out.y[u - range.start],
                        out.z[u - range.start],
                    ),
                    false => Vec3::ZERO,
                };
                let s = start.as_ref().map_or(Vec3::ZERO, |start| start(u, current));
                (acc[0][lane], acc[1][lane], acc[2][lane]) = (s.x, s.y, s.z);
            }
            add(g, &mut acc);
            for (lane, &u) in rows.iter().enumerate() {
                if inside(u) {
                    let i = u as usize - range.start;
                    out.x[i] = acc[0][lane];
                    out.y[i] = acc[1][lane];
                    out.z[i] = acc[2][lane];
                }
            }
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
        match &self.columns {
            Columns::Narrow { base, offset } => {
                let base = base[g] as i32;
                let column = |k: usize| offset[k].map(|o| base + o as i32);
                self.add_slots(x, g, acc, term, column)
            }
            Columns::Wide(wide) => {
                self.add_slots(x, g, acc, term, |k: usize| wide[k].map(|c| c as i32))
            }
        }
    }

    /// [`Lanes::add_group`] with slot `k`'s columns `column(k)`.
    #[inline(always)]
    fn add_slots(
        &self,
        x: &Vec3s,
        g: usize,
        acc: &mut [[f32; LANES]; 3],
        term: &impl Fn([f32; C], Vec3) -> Vec3,
        column: impl Fn(usize) -> [i32; LANES],
    ) {
        let n = self.width;
        let (xs, ys, zs) = (&x.x[..n], &x.y[..n], &x.z[..n]);
        let lengths = &self.lengths[g];
        let first = self.starts[g] as usize;
        let slots = first..self.starts[g + 1] as usize;
        // The sums in locals, not in `acc`: a sum kept in memory and written back under a
        // mask each slot is a masked store, which the next slot's load must wait out (no
        // store forwarding from it).
        let [mut sx, mut sy, mut sz] = *acc;
        for (k, b) in slots.clone().zip(&self.values[slots]) {
            let columns = column(k);
            for lane in 0..LANES {
                // As a signed 32-bit offset, which the vector unit's gathers take directly
                // (an unsigned one is widened to 64 bits, and gathered half as wide).
                let c = columns[lane] as isize;
                // SAFETY: every column is below `n` and `i32::MAX` (checked in `new`), and so
                // within `x`'s slices cut to `n` above; a narrowed one is its base plus its
                // offset, the same column.
                let (vx, vy, vz) = unsafe {
                    (
                        *xs.as_ptr().offset(c),
                        *ys.as_ptr().offset(c),
                        *zs.as_ptr().offset(c),
                    )
                };
                let p = term(std::array::from_fn(|c| b[c][lane]), Vec3::new(vx, vy, vz));
                // A slot past the row's end adds `-0.0`, which leaves every sum bitwise as
                // it is (`-0.0` too), so the lane's sum needs no select.
                let live = ((k - first) as u32) < lengths[lane];
                let p = if live { p } else { Vec3::splat(-0.0) };
                sx[lane] += p.x;
                sy[lane] += p.y;
                sz[lane] += p.z;
            }
        }
        *acc = [sx, sy, sz];
    }

    pub fn heap_bytes(&self) -> usize {
        self.starts.capacity() * 4
            + self.columns.heap_bytes()
            + (self.source.capacity() + self.lengths.capacity() + self.lane_rows.capacity())
                * size_of::<[u32; LANES]>()
            + self.place.capacity() * 4
            + self.spans.capacity() * 8
            + self.values.capacity() * size_of::<[[f32; LANES]; C]>()
    }
}

/// A product packs its operand unless the operand's rows its groups read outnumber their
/// slots' lanes by more than this: packing a row costs less than the gather of an element it
/// saves, so packing pays even where every range reads every row (a numbering at random: a
/// range of 1,024 rows of the 129 x 129 mesh reads its 16,641 rows through 14,500 lanes, and
/// the stiff step was 12 % shorter packed in two rounds, docs/notes/mesh_cloth.md, "Speed",
/// 2026-12-06), but a short range of a large scattered matrix would pack far more rows than
/// it multiplies.
#[cfg(target_arch = "x86_64")]
const PACKED_ROWS_A_LANE: usize = 2;

#[cfg(target_arch = "x86_64")]
thread_local! {
    /// A packed product's operand rows, `[x, y, z, 0]` each, kept for the thread's next one.
    static PACKED: std::cell::RefCell<Vec<[f32; 4]>> = const {
        std::cell::RefCell::new(Vec::new())
    };
}

/// An operand packed whole as `[x, y, z, 0]` rows, once for all the ranges of a product
/// ([`crate::linear::cg::BlockOperator::apply_range_packed`]), where each range would otherwise
/// pack the rows its groups read: the rows near a range's ends again for its neighbours (about
/// 1.5 times over in row order), and nearly every row for every range of 1,024 in a numbering
/// at random. Filled by its caller from the operand just before the product, and read by that
/// product only, so it cannot be stale.
#[derive(Clone, Debug, Default)]
pub struct Packed(Vec<[f32; 4]>);

/// Rows per parallel work item of [`Packed::pack`].
const PACK_CHUNK: usize = 4096;

impl Packed {
    /// Packs every row of `x`.
    pub fn pack(&mut self, x: &Vec3s) {
        use rayon::prelude::*;
        self.0.resize(x.len(), [0.0; 4]);
        (self.0.par_chunks_mut(PACK_CHUNK).enumerate()).for_each(|(c, rows)| {
            let range = c * PACK_CHUNK..c * PACK_CHUNK + rows.len();
            let (xs, ys, zs) = (&x.x[range.clone()], &x.y[range.clone()], &x.z[range]);
            for (i, row) in rows.iter_mut().enumerate() {
                *row = [xs[i], ys[i], zs[i], 0.0];
            }
        });
    }

    pub fn heap_bytes(&self) -> usize {
        self.0.capacity() * size_of::<[f32; 4]>()
    }
}

/// Adds group `g`'s terms from the rows packed from `low` to the group's sums (the functions
/// `packed_kernel!` defines).
#[cfg(target_arch = "x86_64")]
type PackedKernel<const C: usize> =
    unsafe fn(&Lanes<C>, &[[f32; 4]], usize, usize, Option<&[Sym3]>, &mut [[f32; LANES]; 3]);

impl<const C: usize> Lanes<C> {
    /// [`Lanes::apply_range`] with the operand packed, where [`Lanes::packed_span`] allows
    /// (returning whether it did), each group's terms added by `kernel`.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn apply_packed(
        &self,
        x: &Vec3s,
        range: &std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: Option<&impl Fn(usize, Vec3) -> Vec3>,
        kernel: PackedKernel<C>,
        (diagonal, whole): (Option<&[Sym3]>, Option<&Packed>),
    ) -> bool {
        // Packed whole by the caller: every column (below `width`) and row (below the rows'
        // count) is in it.
        let whole = whole.filter(|w| w.0.len() >= self.width.max(self.place.len()));
        if let Some(whole) = whole.filter(|_| self.packs()) {
            let groups = self.groups(range);
            self.apply_groups(groups, range.clone(), out, start, |g, acc| {
                // SAFETY: `packs` found AVX2 and narrow columns, and `whole` holds every row.
                unsafe { kernel(self, &whole.0, 0, g, diagonal, acc) }
            });
            return true;
        }
        let Some(mut span) = self.packed_span(range) else {
            return false;
        };
        if diagonal.is_some() {
            // The diagonal's terms read each group's own rows too.
            let groups = self.groups(range);
            let per_window = WINDOW / LANES;
            let rows = groups.start / per_window * WINDOW
                ..self
                    .place
                    .len()
                    .min(groups.end.div_ceil(per_window) * WINDOW);
            span = span.start.min(rows.start)..span.end.max(rows.end);
        }
        PACKED.with_borrow_mut(|packed| {
            packed.clear();
            let (xs, ys, zs) = (&x.x[span.clone()], &x.y[span.clone()], &x.z[span.clone()]);
            let rows = xs.iter().zip(ys).zip(zs);
            packed.extend(rows.map(|((&x, &y), &z)| [x, y, z, 0.0]));
            let groups = self.groups(range);
            self.apply_groups(groups, range.clone(), out, start, |g, acc| {
                // SAFETY: `packed_span` found AVX2, narrow columns and every column of these
                // groups in `span`, packed from its start (their rows too, with a diagonal).
                unsafe { kernel(self, packed, span.start, g, diagonal, acc) }
            });
        });
        true
    }

    /// Whether a product can read a packed operand: the CPU has AVX2 and the columns are
    /// narrow.
    #[cfg(target_arch = "x86_64")]
    fn packs(&self) -> bool {
        crate::simd::isa() != crate::simd::Isa::Baseline
            && is_x86_feature_detected!("avx2")
            && matches!(self.columns, Columns::Narrow { .. })
    }

    /// The operand's rows a product over `range` reads, where it is to be packed: the CPU
    /// has AVX2, the columns are narrow and the rows few enough ([`PACKED_ROWS_A_LANE`]).
    #[cfg(target_arch = "x86_64")]
    fn packed_span(&self, range: &std::ops::Range<usize>) -> Option<std::ops::Range<usize>> {
        if range.is_empty() || !self.packs() {
            return None;
        }
        let groups = self.groups(range);
        let slots = (self.starts[groups.end] - self.starts[groups.start]) as usize;
        let (low, high) = self.spans[groups]
            .iter()
            .filter(|s| s[0] < s[1])
            .fold((u32::MAX, 0), |(l, h), s| (l.min(s[0]), h.max(s[1])));
        let (low, high) = (low as usize, high as usize);
        (low < high && high - low <= PACKED_ROWS_A_LANE * slots * LANES).then_some(low..high)
    }
}

/// Defines `$name`, which adds group `g`'s slots from the packed rows `packed` (row `low`
/// first) to `acc`, eight lanes at a time: each slot's operands read as 16-byte loads and
/// transposed into x, y and z by shuffles, `$term` (given the slot's values `$b`, the half's
/// first lane `$half` and the operand `$x`, `$y`, `$z`) giving the slot's terms, added where
/// the lane's row reaches the slot and `-0.0` past it (as the gathered product).
///
/// Written out as a macro, not with closures or a function argument: a closure is not compiled
/// with its function's AVX2 (its intrinsics would become calls), and a function compiled
/// for AVX2 is not a closure's type.
#[cfg(target_arch = "x86_64")]
macro_rules! packed_kernel {
    ($name:ident, $c:literal, |$b:ident, $half:ident, $x:ident, $y:ident, $z:ident| $term:expr) => {
        /// With `diagonal`, each lane's sum starts from its row's diagonal term instead of
        /// `acc` ([`diagonal_terms`]).
        ///
        /// # Safety
        /// The CPU has AVX2, the columns are [`Columns::Narrow`], and `packed` holds the rows
        /// `low..` through every column of group `g` (and its rows, with `diagonal`, which then
        /// has a block for each of them).
        #[target_feature(enable = "avx2")]
        unsafe fn $name(
            lanes: &Lanes<$c>,
            packed: &[[f32; 4]],
            low: usize,
            g: usize,
            diagonal: Option<&[Sym3]>,
            acc: &mut [[f32; LANES]; 3],
        ) {
            use std::arch::x86_64::*;
            let Columns::Narrow { base, offset } = &lanes.columns else {
                unreachable!("a packed product of wide columns")
            };
            let (first, end) = (lanes.starts[g] as usize, lanes.starts[g + 1] as usize);
            if first == end && diagonal.is_none() {
                return;
            }
            // Every live column, and a dead slot's (its group's base), is in `low..low + len`;
            // a group with no slot (its rows' diagonal terms only) reads no column, and its
            // base may lie outside: no pointer is made from it.
            debug_assert!(
                first == end
                    || base[g] as usize >= low
                        && lanes.spans[g][1] as usize <= low + packed.len()
            );
            let origin = match first == end {
                true => packed.as_ptr(),
                false => packed.as_ptr().add(base[g] as usize - low),
            } as *const f32;
            let negative_zero = _mm256_set1_ps(-0.0);
            for $half in [0, 8] {
                let lengths = lanes.lengths[g][$half..].as_ptr() as *const __m256i;
                let lengths = _mm256_loadu_si256(lengths);
                let (mut sx, mut sy, mut sz) = match diagonal {
                    Some(d) => diagonal_terms(&lanes.lane_rows[g], $half, packed, low, d),
                    None => (
                        _mm256_loadu_ps(acc[0][$half..].as_ptr()),
                        _mm256_loadu_ps(acc[1][$half..].as_ptr()),
                        _mm256_loadu_ps(acc[2][$half..].as_ptr()),
                    ),
                };
                for (k, $b) in (first..end).zip(&lanes.values[first..end]) {
                    let o = &offset[k][$half..$half + 8];
                    // Register `e`'s 128-bit half `j` holds lane `4 j + e`'s `x, y, z, 0`.
                    macro_rules! pair {
                        ($e:literal) => {
                            _mm256_insertf128_ps::<1>(
                                _mm256_castps128_ps256(_mm_loadu_ps(
                                    origin.add(4 * o[$e] as usize),
                                )),
                                _mm_loadu_ps(origin.add(4 * o[$e + 4] as usize)),
                            )
                        };
                    }
                    let (q0, q1, q2, q3) = (pair!(0), pair!(1), pair!(2), pair!(3));
                    let (t0, t1) = (_mm256_unpacklo_ps(q0, q1), _mm256_unpackhi_ps(q0, q1));
                    let (t2, t3) = (_mm256_unpacklo_ps(q2, q3), _mm256_unpackhi_ps(q2, q3));
                    let $x = _mm256_shuffle_ps::<0x44>(t0, t2);
                    let $y = _mm256_shuffle_ps::<0xEE>(t0, t2);
                    let $z = _mm256_shuffle_ps::<0x44>(t1, t3);
                    let (px, py, pz) = $term;
                    let live = _mm256_set1_epi32((k - first) as i32);
                    let live = _mm256_castsi256_ps(_mm256_cmpgt_epi32(lengths, live));
                    sx = _mm256_add_ps(sx, _mm256_blendv_ps(negative_zero, px, live));
                    sy = _mm256_add_ps(sy, _mm256_blendv_ps(negative_zero, py, live));
                    sz = _mm256_add_ps(sz, _mm256_blendv_ps(negative_zero, pz, live));
                }
                _mm256_storeu_ps(acc[0][$half..].as_mut_ptr(), sx);
                _mm256_storeu_ps(acc[1][$half..].as_mut_ptr(), sy);
                _mm256_storeu_ps(acc[2][$half..].as_mut_ptr(), sz);
            }
        }
    };
}

/// The rows `rows[half..half + 8]`' diagonal terms `diagonal[v] x_v`, as [`Sym3::mul`] computes
/// them: each row's operand read as one 16-byte load from `packed` (row `low` first), its block
/// as two overlapping ones (components 0 to 3 and 2 to 5), and both turned into components
/// across the eight lanes by shuffles, as the slots' operands are. An empty lane ([`PAD`])
/// reads the group's first row and its sums are never written.
///
/// # Safety
/// The CPU has AVX2, `packed` holds every live row of `rows` from `low`, `diagonal` has a block
/// for each, and `rows[0]` is live (a group's first lane always is).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn diagonal_terms(
    rows: &[u32; LANES],
    half: usize,
    packed: &[[f32; 4]],
    low: usize,
    diagonal: &[Sym3],
) -> (
    std::arch::x86_64::__m256,
    std::arch::x86_64::__m256,
    std::arch::x86_64::__m256,
) {
    use std::arch::x86_64::*;
    let row = |l: usize| match rows[half + l] {
        PAD => rows[0] as usize,
        v => v as usize,
    };
    debug_assert!((0..8).all(|l| row(l) >= low && row(l) - low < packed.len()));
    debug_assert!((0..8).all(|l| row(l) < diagonal.len()));
    let operand = |l: usize| _mm_loadu_ps(packed.as_ptr().add(row(l) - low) as *const f32);
    let block = diagonal.as_ptr() as *const f32;
    let low_half = |l: usize| _mm_loadu_ps(block.add(6 * row(l)));
    let high_half = |l: usize| _mm_loadu_ps(block.add(6 * row(l) + 2));
    let [x, y, z, _] = transpose(std::array::from_fn(operand));
    let [m0, m1, m2, m3] = transpose(std::array::from_fn(low_half));
    let [_, _, m4, m5] = transpose(std::array::from_fn(high_half));
    let px = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(m0, x), _mm256_mul_ps(m3, y)),
        _mm256_mul_ps(m4, z),
    );
    let py = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(m3, x), _mm256_mul_ps(m1, y)),
        _mm256_mul_ps(m5, z),
    );
    let pz = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(m4, x), _mm256_mul_ps(m5, y)),
        _mm256_mul_ps(m2, z),
    );
    (px, py, pz)
}

/// Eight lanes' four components, lane `l`'s in `q[l]`, as four vectors of a component each.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn transpose(q: [std::arch::x86_64::__m128; 8]) -> [std::arch::x86_64::__m256; 4] {
    use std::arch::x86_64::*;
    // Register `e`'s 128-bit half `j` holds lane `4 j + e`.
    let pair = |e: usize| _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(q[e]), q[e + 4]);
    let (q0, q1, q2, q3) = (pair(0), pair(1), pair(2), pair(3));
    let (t0, t1) = (_mm256_unpacklo_ps(q0, q1), _mm256_unpackhi_ps(q0, q1));
    let (t2, t3) = (_mm256_unpacklo_ps(q2, q3), _mm256_unpackhi_ps(q2, q3));
    [
        _mm256_shuffle_ps::<0x44>(t0, t2),
        _mm256_shuffle_ps::<0xEE>(t0, t2),
        _mm256_shuffle_ps::<0x44>(t1, t3),
        _mm256_shuffle_ps::<0xEE>(t1, t3),
    ]
}

// Each block's term as `Sym3::mul` computes it: each component's three products added left
// to right.
#[cfg(target_arch = "x86_64")]
packed_kernel!(add_packed_blocks, 6, |b, half, x, y, z| {
    let m = |c: usize| b[c][half..].as_ptr();
    let (m0, m1, m2) = (
        _mm256_loadu_ps(m(0)),
        _mm256_loadu_ps(m(1)),
        _mm256_loadu_ps(m(2)),
    );
    let (m3, m4, m5) = (
        _mm256_loadu_ps(m(3)),
        _mm256_loadu_ps(m(4)),
        _mm256_loadu_ps(m(5)),
    );
    let (mx, my, mz) = (
        _mm256_mul_ps(m0, x),
        _mm256_mul_ps(m3, y),
        _mm256_mul_ps(m4, z),
    );
    let px = _mm256_add_ps(_mm256_add_ps(mx, my), mz);
    let (mx, my, mz) = (
        _mm256_mul_ps(m3, x),
        _mm256_mul_ps(m1, y),
        _mm256_mul_ps(m5, z),
    );
    let py = _mm256_add_ps(_mm256_add_ps(mx, my), mz);
    let (mx, my, mz) = (
        _mm256_mul_ps(m4, x),
        _mm256_mul_ps(m5, y),
        _mm256_mul_ps(m2, z),
    );
    let pz = _mm256_add_ps(_mm256_add_ps(mx, my), mz);
    (px, py, pz)
});

// Each weight's term `w x`.
#[cfg(target_arch = "x86_64")]
packed_kernel!(add_packed_weights, 1, |b, half, x, y, z| {
    let w = _mm256_loadu_ps(b[0][half..].as_ptr());
    (
        _mm256_mul_ps(w, x),
        _mm256_mul_ps(w, y),
        _mm256_mul_ps(w, z),
    )
});

impl BlockLanes {
    /// [`Lanes::apply_range`] of the blocks, each term `block x_column` as [`Sym3::mul`]
    /// computes it.
    ///
    /// Where the rows read are few enough ([`PACKED_ROWS_A_LANE`]) and the CPU has AVX2, the
    /// operand's rows are first packed as `[x, y, z, 0]`, and each slot's sixteen operands
    /// read as sixteen 16-byte loads turned into x, y and z vectors by shuffles, not by three
    /// 16-wide gathers, which cost about a load an element: 16 loads a slot against 48
    /// (docs/notes/mesh_cloth.md, "Speed", 2026-12-06). Each lane adds the same terms in the same
    /// order either way, so the product is bitwise the same.
    #[inline(always)]
    pub fn apply_blocks(
        &self,
        x: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: impl Fn(usize, Vec3) -> Vec3,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.apply_packed(
            x,
            &range,
            out,
            Some(&start),
            add_packed_blocks,
            (None, None),
        ) {
            return;
        }
        self.apply_range(x, range, out, start, |b, x| Sym3(b).mul(x));
    }

    /// [`BlockLanes::apply_blocks`] of a square matrix whose diagonal blocks are kept apart:
    /// each row `v`'s sum starts from `diagonal[v] x_v` (as [`Sym3::mul`] computes it). Packed,
    /// the diagonal's terms are taken eight rows at a time beside the slots', not row by row;
    /// `whole`, where given, is `x` packed whole ([`Packed`]), read instead of packing the
    /// range's rows.
    #[inline(always)]
    pub fn apply_blocks_from_diagonal(
        &self,
        (x, whole): (&Vec3s, Option<&Packed>),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        diagonal: &[Sym3],
    ) {
        debug_assert_eq!(diagonal.len(), self.place.len());
        #[cfg(target_arch = "x86_64")]
        if (self.width == diagonal.len())
            && self.apply_packed(
                x,
                &range,
                out,
                None::<&fn(usize, Vec3) -> Vec3>,
                add_packed_blocks,
                (Some(diagonal), whole),
            )
        {
            return;
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = whole;
        let start = |v: usize, _| diagonal[v].mul(x.get(v));
        self.apply_range(x, range, out, start, |b, x| Sym3(b).mul(x));
    }
}

impl WeightLanes {
    /// [`Lanes::apply_range`] of the weights, each term `w x_column`; packed as
    /// [`BlockLanes::apply_blocks`] is, where it pays.
    #[inline(always)]
    pub fn apply_weights(
        &self,
        x: &Vec3s,
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
        start: impl Fn(usize, Vec3) -> Vec3,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.apply_packed(
            x,
            &range,
            out,
            Some(&start),
            add_packed_weights,
            (None, None),
        ) {
            return;
        }
        self.apply_range(x, range, out, start, |[w], x| w * x);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of 0 to 19 entries (so groups of uneven rows, windows of them, and a last partial
    /// group and window), columns and blocks from a fixed hash, some entries repeating a
    /// column.
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

    /// A banded matrix (each row's columns within 40 of it, so that a product packs its
    /// operand where the CPU allows) with rows of 0 to 19 entries, of blocks and of weights,
    /// multiplied packed and gathered over ranges that cut windows and groups: bitwise the same, a lane whose sum
    /// starts at `-0.0` and adds only padding included; and with each row's sum started from
    /// its diagonal block's term, taken eight rows at a time where packed, as the row-by-row
    /// start gives it (rows of no entry and zero blocks included).
    #[test]
    fn a_packed_product_is_bitwise_the_gathered_product() {
        let n = 1500;
        let hash = |i: usize| (i as u32).wrapping_mul(2654435761) >> 7;
        let (mut offsets, mut columns, mut blocks) = (vec![0u32], Vec::new(), Vec::new());
        for v in 0..n {
            for k in 0..hash(v) % 20 {
                let c = (v + (hash(v * 31 + k as usize) % 81) as usize).saturating_sub(40);
                columns.push(c.min(n - 1) as u32);
                let b = |c: usize| (hash(columns.len() * 7 + c) % 2001) as f32 / 1000.0 - 1.0;
                blocks.push(Sym3(std::array::from_fn(b)));
            }
            offsets.push(columns.len() as u32);
        }
        let sources: Vec<u32> = (0..columns.len() as u32).collect();
        let mut lanes = BlockLanes::new(&offsets, &columns, &sources, n);
        lanes.refill(&blocks, |b| b.0);
        let mut weights = WeightLanes::new(&offsets, &columns, &sources, n);
        weights.refill(&blocks, |b| [b.0[3]]);
        let x = Vec3s::from_fn(n, |v| {
            Vec3::new(v as f32 * 0.37 - 9.0, -1.5, (v as f32).sin())
        });
        // Diagonal blocks of every sign, some zero (a held row: its sum starts from `+-0`).
        let diagonal: Vec<Sym3> = (0..n)
            .map(|v| match v % 7 {
                0 => Sym3::ZERO,
                _ => Sym3(std::array::from_fn(|c| {
                    (hash(v * 11 + c) % 2001) as f32 / 500.0 - 2.0
                })),
            })
            .collect();
        let start = |v: usize, _| match v % 3 {
            0 => Vec3::splat(-0.0),
            _ => Vec3::splat(v as f32 * 0.01),
        };
        #[cfg(target_arch = "x86_64")]
        let packs =
            crate::simd::isa() != crate::simd::Isa::Baseline && is_x86_feature_detected!("avx2");
        for range in [
            0..n,
            0..1024,
            1024..n,
            3..17,
            255..257,
            700..1300,
            1499..1500,
        ] {
            #[cfg(target_arch = "x86_64")]
            assert_eq!(lanes.packed_span(&range).is_some(), packs, "{range:?}");
            #[cfg(target_arch = "x86_64")]
            assert_eq!(weights.packed_span(&range).is_some(), packs, "{range:?}");
            let (mut packed, mut gathered) = (Vec3s::zeros(n), Vec3s::zeros(n));
            let mut out = packed.slices_mut(range.clone());
            lanes.apply_blocks(&x, range.clone(), &mut out, start);
            let mut out = gathered.slices_mut(range.clone());
            lanes.apply_range(&x, range.clone(), &mut out, start, |b, x| Sym3(b).mul(x));
            let (mut packed_w, mut gathered_w) = (Vec3s::zeros(n), Vec3s::zeros(n));
            let mut out = packed_w.slices_mut(range.clone());
            weights.apply_weights(&x, range.clone(), &mut out, start);
            let mut out = gathered_w.slices_mut(range.clone());
            weights.apply_range(&x, range.clone(), &mut out, start, |[w], x| w * x);
            let (mut packed_d, mut gathered_d) = (Vec3s::zeros(n), Vec3s::zeros(n));
            let mut out = packed_d.slices_mut(range.clone());
            lanes.apply_blocks_from_diagonal((&x, None), range.clone(), &mut out, &diagonal);
            let mut out = gathered_d.slices_mut(range.clone());
            let from_diagonal = |v: usize, _| diagonal[v].mul(x.get(v));
            lanes.apply_range(&x, range.clone(), &mut out, from_diagonal, |b, x| {
                Sym3(b).mul(x)
            });
            for v in range {
                let bits = |y: &Vec3s| y.get(v).to_array().map(f32::to_bits);
                assert_eq!(bits(&packed), bits(&gathered), "row {v}");
                assert_eq!(bits(&packed_w), bits(&gathered_w), "row {v}, weights");
                assert_eq!(bits(&packed_d), bits(&gathered_d), "row {v}, diagonal");
            }
        }
    }

    #[test]
    fn a_row_shorter_than_its_group_keeps_a_negative_zero_sum() {
        // Row 0 has one entry, row 1 three, so row 0's lane is padded for two slots; its sum
        // starts at -0.0 and adds -0.0 (a zero block times a negative operand), which must
        // stay -0.0 past the padding, as the row-by-row sum gives it.
        let offsets = [0u32, 1, 4];
        let columns = [1u32, 0, 1, 0];
        let blocks = [Sym3::ZERO, Sym3([1.0; 6]), Sym3([2.0; 6]), Sym3([3.0; 6])];
        let mut lanes = BlockLanes::new(&offsets, &columns, &[0, 1, 2, 3], 2);
        lanes.refill(&blocks, |b| b.0);
        let x = Vec3s::from_fn(2, |v| Vec3::splat(-1.0 - v as f32));
        let mut y = Vec3s::zeros(2);
        lanes.apply_blocks(&x, 0..2, &mut y.slices_mut(0..2), |_, _| Vec3::splat(-0.0));
        assert_eq!(
            y.get(0).to_array().map(f32::to_bits),
            [(-0.0f32).to_bits(); 3]
        );
        assert_eq!(y.get(1), Vec3::splat(-3.0 - 12.0 - 9.0));
    }

    #[test]
    fn a_product_is_bitwise_the_row_by_row_product_over_any_range() {
        // Columns within 600 (stored as 16-bit offsets) and spread 1,000 apart (as they are).
        for spread in [1, 1000] {
            let n = 600;
            let (offsets, columns, blocks) = rows(n);
            let columns: Vec<u32> = columns.iter().map(|c| c * spread).collect();
            let width = n * spread as usize;
            let sources: Vec<u32> = (0..columns.len() as u32).collect();
            let mut lanes = BlockLanes::new(&offsets, &columns, &sources, width);
            assert_eq!(matches!(lanes.columns, Columns::Narrow { .. }), spread == 1);
            lanes.refill(&blocks, |b| b.0);
            let x = Vec3s::from_fn(width, |v| {
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
            let ranges = [
                0..n,
                0..16,
                5..40,
                17..18,
                250..260,
                256..512,
                300..599,
                512..600,
                590..600,
            ];
            for range in ranges {
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
                        "row {v}, spread {spread}"
                    );
                }
            }
            for v in 0..n {
                let entries: Vec<(usize, Sym3)> =
                    lanes.entries(v).map(|(c, b)| (c, Sym3(b))).collect();
                let k = offsets[v] as usize..offsets[v + 1] as usize;
                let stored: Vec<(usize, Sym3)> =
                    k.map(|k| (columns[k] as usize, blocks[k])).collect();
                assert_eq!(entries, stored, "row {v}, spread {spread}");
            }
        }
    }
}
