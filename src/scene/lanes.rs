//! The springs touching each vertex of a mesh cloth, laid out for the vector unit.
//!
//! The force pass sums, for each vertex, the forces of its springs in increasing spring order
//! (the incidence lists of [`super::MeshCloth`]). Summed vertex by vertex, each sum is a chain
//! of dependent additions that a processor cannot overlap much. Here the vertices go in groups
//! of [`LANES`], and a group's lists are stored row by row, one entry per lane (a sliced ELLPACK
//! layout): row `r` holds each lane's `r`-th spring. One vector addition per row then advances
//! all the group's sums, each lane still in its own vertex's order. A list shorter than its
//! group's longest is padded with [`IncidenceLanes::pad`], a spring one past the last whose
//! force table entry is `-0.0`: `x + -0.0` is `x` for every `x`, so the padding leaves every
//! sum bitwise what the list alone gives.

/// Vertices per group: the `f32` lanes of an AVX-512 register.
pub const LANES: usize = 16;

/// See the module documentation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IncidenceLanes {
    /// Group `g`'s rows are `slots[starts[g]..starts[g + 1]]`, [`LANES`] entries a row, each
    /// `spring << 1 | end` as in the incidence lists.
    starts: Vec<u32>,
    slots: Vec<u32>,
    /// The padding spring's index: the number of springs.
    pad: u32,
}

impl IncidenceLanes {
    /// The layout of the lists `incident[offsets[v]..offsets[v + 1]]` of `offsets.len() - 1`
    /// vertices, over `springs` springs (every entry's spring below it).
    pub fn new(offsets: &[u32], incident: &[u32], springs: usize) -> Self {
        let n = offsets.len().saturating_sub(1);
        let pad = springs as u32;
        // The force pass reads a table entry per slot unchecked, relying on this.
        assert!(
            incident.iter().all(|&e| e >> 1 < pad),
            "an incident spring beyond {springs}"
        );
        let mut lanes = IncidenceLanes {
            starts: vec![0],
            slots: Vec::new(),
            pad,
        };
        for first in (0..n).step_by(LANES) {
            let list = |lane: usize| {
                let v = first + lane;
                match v < n {
                    true => &incident[offsets[v] as usize..offsets[v + 1] as usize],
                    false => &[][..],
                }
            };
            let rows = (0..LANES).map(|lane| list(lane).len()).max().unwrap_or(0);
            for row in 0..rows {
                lanes.slots.extend(
                    (0..LANES).map(|lane| list(lane).get(row).copied().unwrap_or(pad << 1)),
                );
            }
            lanes.starts.push(lanes.slots.len() as u32);
        }
        lanes
    }

    /// The rows of group `g` (vertices `g * LANES..`), [`LANES`] entries each.
    pub fn group(&self, g: usize) -> &[u32] {
        &self.slots[self.starts[g] as usize..self.starts[g + 1] as usize]
    }

    /// The padding spring, whose entry in a force table must be `-0.0`: the number of springs,
    /// so a table holds one entry more than there are springs.
    pub fn pad(&self) -> usize {
        self.pad as usize
    }

    pub fn heap_bytes(&self) -> usize {
        (self.starts.capacity() + self.slots.capacity()) * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_lane_holds_its_vertex_list_in_order_then_only_padding() {
        // Two whole groups and a partial one, lists of 1 to 5 entries.
        let springs = 40;
        let lists: Vec<Vec<u32>> = (0..37u32)
            .map(|v| {
                (0..v * 7 % 5 + 1)
                    .map(|k| ((v * 3 + k) % springs) << 1 | (k & 1))
                    .collect()
            })
            .collect();
        let mut offsets = vec![0u32];
        offsets.extend(lists.iter().scan(0, |end, l| {
            *end += l.len() as u32;
            Some(*end)
        }));
        let incident: Vec<u32> = lists.concat();
        let lanes = IncidenceLanes::new(&offsets, &incident, springs as usize);
        let pad = (lanes.pad() as u32) << 1;
        assert_eq!(lanes.pad(), springs as usize);
        for g in 0..lists.len().div_ceil(LANES) {
            let rows = lanes.group(g);
            assert_eq!(rows.len() % LANES, 0);
            for lane in 0..LANES {
                let column: Vec<u32> = rows.chunks_exact(LANES).map(|r| r[lane]).collect();
                let list = lists.get(g * LANES + lane).map_or(&[][..], |l| &l[..]);
                assert_eq!(&column[..list.len()], list, "vertex {}", g * LANES + lane);
                assert!(column[list.len()..].iter().all(|&e| e == pad));
            }
            // A group is as long as its longest list.
            let longest = (0..LANES)
                .filter_map(|k| lists.get(g * LANES + k))
                .map(Vec::len);
            assert_eq!(rows.len() / LANES, longest.max().unwrap());
        }
    }
}
