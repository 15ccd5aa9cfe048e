//! The broad phase: a spatial hash of axis-aligned boxes. Each box is entered in every cell it
//! overlaps, a query visits every cell its box overlaps; the cell is about the mean box, so a
//! typical box overlaps two cells along each axis. Built by a counting sort in item order, so the
//! buckets (and every answer) are the same for any thread count.

use glam::Vec3;

/// An axis-aligned box, in m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// Closed boxes: touching counts as overlapping (the test must never miss a pair).
    #[inline]
    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }
}

/// Boxes bucketed by the cells they overlap.
#[derive(Default)]
pub struct HashGrid {
    inv_cell: f32,
    mask: usize,
    /// Bucket `h` holds `entries[start[h]..start[h + 1]]`: each item with its box, so that a
    /// query tests the boxes of a bucket in one sweep through memory.
    start: Vec<u32>,
    entries: Vec<(Aabb, u32)>,
    fill: Vec<u32>,
}

impl HashGrid {
    /// Buckets `boxes` (all finite) by cell.
    pub fn build(&mut self, boxes: &[Aabb]) {
        let (mut largest, mut sum) = (0.0f32, 0.0f64);
        for b in boxes {
            let e = (b.max - b.min).max_element();
            largest = largest.max(e);
            sum += e as f64;
        }
        let mean = (sum / boxes.len().max(1) as f64) as f32;
        // About the mean box: a query then meets few items per cell. Never below an eighth of
        // the largest, so that one stretched box spans at most nine cells along an axis; never
        // zero (a cloth of coincident points).
        self.inv_cell = 1.0 / mean.max(largest / 8.0).max(1e-9);
        let buckets = (2 * boxes.len()).next_power_of_two().max(16);
        self.mask = buckets - 1;
        self.start.clear();
        self.start.resize(buckets + 1, 0);
        let (inv, mask) = (self.inv_cell, self.mask);
        for b in boxes {
            for_cells(inv, mask, b, |h| self.start[h + 1] += 1);
        }
        for h in 0..buckets {
            self.start[h + 1] += self.start[h];
        }
        self.fill.clear();
        self.fill.extend_from_slice(&self.start[..buckets]);
        self.entries.clear();
        self.entries
            .resize(self.start[buckets] as usize, (Aabb::EMPTY, 0));
        for (item, b) in boxes.iter().enumerate() {
            for_cells(inv, mask, b, |h| {
                self.entries[self.fill[h] as usize] = (*b, item as u32);
                self.fill[h] += 1;
            });
        }
    }

    /// Calls `f` with every item whose box overlaps `query`, possibly more than once (once per
    /// cell both overlap: the caller deduplicates).
    pub fn query(&self, query: &Aabb, mut f: impl FnMut(u32)) {
        for_cells(self.inv_cell, self.mask, query, |h| {
            for (b, item) in &self.entries[self.start[h] as usize..self.start[h + 1] as usize] {
                if b.overlaps(query) {
                    f(*item);
                }
            }
        });
    }

    pub fn heap_bytes(&self) -> usize {
        (self.start.capacity() + self.fill.capacity()) * 4
            + self.entries.capacity() * size_of::<(Aabb, u32)>()
    }
}

/// The distinct buckets of the cells `b` overlaps (a cell's bucket visited once per cell; two
/// cells may share a bucket, which only adds candidates).
fn for_cells(inv_cell: f32, mask: usize, b: &Aabb, mut f: impl FnMut(usize)) {
    let lo = (b.min * inv_cell).floor();
    let hi = (b.max * inv_cell).floor();
    let (lo, hi) = (
        [lo.x as i64, lo.y as i64, lo.z as i64],
        [hi.x as i64, hi.y as i64, hi.z as i64],
    );
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                let h = (x.wrapping_mul(73_856_093)
                    ^ y.wrapping_mul(19_349_663)
                    ^ z.wrapping_mul(83_492_791)) as usize;
                f(h & mask);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(c: Vec3, r: f32) -> Aabb {
        Aabb {
            min: c - Vec3::splat(r),
            max: c + Vec3::splat(r),
        }
    }

    #[test]
    fn every_overlapping_box_is_found() {
        // A jittered lattice of boxes of several sizes; the hash must report every overlapping
        // pair a brute-force test finds.
        let boxes: Vec<Aabb> = (0..300)
            .map(|k| {
                let f = k as f32;
                let c = Vec3::new((f * 0.37).sin(), (f * 0.11).cos(), (f * 0.73).sin()) * 2.0;
                cube(c, 0.05 + 0.1 * ((f * 1.3).sin().abs()))
            })
            .collect();
        let mut grid = HashGrid::default();
        grid.build(&boxes);
        for (a, ba) in boxes.iter().enumerate() {
            let mut found = Vec::new();
            grid.query(ba, |b| {
                assert!(boxes[b as usize].overlaps(ba));
                found.push(b as usize)
            });
            found.sort_unstable();
            found.dedup();
            let brute: Vec<usize> = (0..boxes.len())
                .filter(|&b| boxes[b].overlaps(ba))
                .collect();
            assert_eq!(found, brute, "box {a}");
        }
    }
}
