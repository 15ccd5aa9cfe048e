//! The springs touching each vertex of a mesh cloth, laid out for the vector unit.
//!
//! The force pass sums, for each vertex, the forces of its springs in increasing spring order
//! (the incidence lists of [`super::MeshCloth`]). Summed vertex by vertex, each sum is a chain
//! of dependent additions that a processor cannot overlap much. Here the vertices go in groups
//! of [`LANES`], and a group's lists are stored row by row, one entry per lane (a sliced ELLPACK
//! layout): row `r` holds each lane's `r`-th spring. One vector addition per row then advances
//! all the group's sums, each lane still in its own vertex's order. A list shorter than its
//! group's longest is padded with [`IncidenceLanes::pad`], a spring one past the last, whose
//! slot adds `-0.0` ([`SpringSlots::PADDING`]): `x + -0.0` is `x` for every `x`, so the
//! padding leaves every sum bitwise what the list alone gives.
//!
//! A padding slot costs the force pass a whole spring's arithmetic, so a group's vertices are
//! not simply 16 consecutive ones: within each [`WINDOW`] of consecutive vertices they are
//! ordered by the length of their lists (then by index), and each group takes the next
//! [`LANES`] of that order, so that its lists are of nearly one length. Each list and its
//! order are unchanged, so every sum is too.

/// Vertices per group: the `f32` lanes of an AVX-512 register.
pub const LANES: usize = 16;

/// Consecutive vertices a group's vertices are drawn from, a multiple of [`LANES`]. A longer
/// window sorts the lists' lengths more evenly (less padding) but puts a group's vertices, and
/// the other ends they gather, further apart; the force pass splits its work only at windows'
/// edges, so that a group's sums stay in one work item. At 256 a jittered mesh's slots are 2 %
/// padding against a fifth for groups of consecutive vertices.
pub const WINDOW: usize = 256;

/// See the module documentation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IncidenceLanes {
    /// Group `g`'s vertices, lane by lane, are `members[g * LANES..]` (fewer in the last group
    /// only): each window's vertices ordered by the length of their lists, then by index.
    members: Vec<u32>,
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
        let mut members: Vec<u32> = (0..n as u32).collect();
        for window in members.chunks_mut(WINDOW) {
            // A stable sort: vertices of one length stay in index order, near each other.
            window.sort_by_key(|&v| offsets[v as usize + 1] - offsets[v as usize]);
        }
        let mut lanes = IncidenceLanes {
            members,
            starts: vec![0],
            slots: Vec::new(),
            pad,
        };
        for first in (0..n).step_by(LANES) {
            let list = |lane: usize| match lanes.members.get(first + lane) {
                Some(&v) => {
                    &incident[offsets[v as usize] as usize..offsets[v as usize + 1] as usize]
                }
                None => &[][..],
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

    /// The vertices of group `g`, one a lane: [`LANES`] of them but in the last group, all
    /// from the window of vertices `g * LANES / WINDOW * WINDOW..`.
    pub fn members(&self, g: usize) -> &[u32] {
        let start = g * LANES;
        &self.members[start..(start + LANES).min(self.members.len())]
    }

    /// The rows of group `g` ([`IncidenceLanes::members`]), [`LANES`] entries each.
    pub fn group(&self, g: usize) -> &[u32] {
        &self.slots[self.group_slots(g)]
    }

    /// The slots of group `g`, as a range of the layout (and of its [`SpringSlots`]).
    pub fn group_slots(&self, g: usize) -> std::ops::Range<usize> {
        self.starts[g] as usize..self.starts[g + 1] as usize
    }

    /// The padding spring, which must add `-0.0`: the number of springs.
    pub fn pad(&self) -> usize {
        self.pad as usize
    }

    pub fn heap_bytes(&self) -> usize {
        (self.members.capacity() + self.starts.capacity() + self.slots.capacity()) * 4
    }
}

/// What the single force pass reads per slot of an [`IncidenceLanes`] layout, in the same
/// order: the spring's other end and a copy of the spring's parameters, so that a group's row
/// loads them as contiguous vectors and only looks up the other end's position and velocity
/// (from the packed state, [`crate::mesh_cloth::packed`]).
/// Each spring is computed at both of its ends (twice the arithmetic, no per-spring table and
/// no second pass). The copies follow the spring list only through [`SpringSlots::refresh`]
/// or [`SpringSlots::refresh_springs`], which whatever changes a spring's parameters calls
/// ([`super::MeshCloth::refresh_cut_springs`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpringSlots {
    /// Per slot, the vertex at the spring's other end; a padding slot's is its own vertex.
    other: Vec<u32>,
    /// Per slot, the spring's index (the padding spring's for padding), for the refresh.
    spring: Vec<u32>,
    /// Per spring, its slots at its ends `a` and `b`: a severing refreshes only its springs'.
    slots_of: Vec<[u32; 2]>,
    /// Per slot, the spring's rest length (m), stiffness (N/m), damping (N s/m) and flags
    /// ([`SpringSlots::SECOND_END`], [`SpringSlots::SEAM`], [`SpringSlots::ACTIVE`], [`SpringSlots::PADDING`]).
    pub rest: Vec<f32>,
    pub k: Vec<f32>,
    pub c: Vec<f32>,
    pub flags: Vec<u8>,
    /// Per slot, isometric bending's linear stiffness of the spring (N/m); empty without it.
    pub linear: Vec<f32>,
    /// The vertices of the numbering: every `other` is below it.
    vertices: usize,
    /// Whether the lanes are a [`super::LocalNumbering`]'s (else the user's numbering).
    pub local: bool,
}

impl SpringSlots {
    /// A slot's flag: the vertex is the spring's second end (`b`).
    pub const SECOND_END: u8 = 1;
    /// A slot's flag: its spring is a seam.
    pub const SEAM: u8 = 2;
    /// A slot's flag: its spring holds (not severed).
    pub const ACTIVE: u8 = 4;
    /// A slot's flag: padding, which adds `-0.0`.
    pub const PADDING: u8 = 8;

    /// The slots of `lanes` over `vertices` vertices, whose springs `springs` have their ends
    /// `ends` in the lanes' numbering (a local numbering's with `local`), with isometric
    /// bending's per-spring `linear` where the cloth has it.
    pub fn new(
        (lanes, local): (&IncidenceLanes, bool),
        ends: (&[u32], &[u32]),
        springs: &super::EdgeSprings,
        linear: Option<&[f32]>,
        vertices: usize,
    ) -> Self {
        let mut other = Vec::with_capacity(lanes.slots.len());
        let mut flags = Vec::with_capacity(lanes.slots.len());
        for g in 0..lanes.starts.len() - 1 {
            for row in lanes.group(g).chunks_exact(LANES) {
                for (lane, &e) in row.iter().enumerate() {
                    let (spring, end) = ((e >> 1) as usize, e & 1);
                    if spring == lanes.pad() {
                        // Inside the numbering, so that its loads stay in bounds, and near.
                        let own = lanes.members(g).get(lane).map(|&v| v as usize);
                        let own = own.unwrap_or(g * LANES + lane);
                        other.push(own.min(vertices.saturating_sub(1)) as u32);
                        flags.push(Self::PADDING);
                    } else {
                        let (a, b) = (ends.0[spring], ends.1[spring]);
                        other.push(if end == 0 { b } else { a });
                        flags.push(end as u8 * Self::SECOND_END);
                    }
                }
            }
        }
        assert!(
            other.iter().all(|&v| (v as usize) < vertices.max(1)) && vertices <= i32::MAX as usize,
            "a spring's end beyond the {vertices} vertices"
        );
        let n = other.len();
        let mut slots_of = vec![[u32::MAX; 2]; springs.len()];
        for (slot, &e) in lanes.slots.iter().enumerate() {
            if let Some(ends) = slots_of.get_mut((e >> 1) as usize) {
                ends[(e & 1) as usize] = slot as u32;
            }
        }
        let mut slots = SpringSlots {
            other,
            spring: lanes.slots.iter().map(|&e| e >> 1).collect(),
            slots_of,
            rest: vec![0.0; n],
            k: vec![0.0; n],
            c: vec![0.0; n],
            flags,
            linear: Vec::new(),
            vertices,
            local,
        };
        slots.refresh(springs, linear);
        slots
    }

    /// Copies each slot's spring's parameters from `springs` (and `linear`) again: after
    /// isometric bending's refresh, which changes the springs of every element a cut ends.
    pub fn refresh(&mut self, springs: &super::EdgeSprings, linear: Option<&[f32]>) {
        for slot in 0..self.spring.len() {
            self.copy_spring(slot, springs);
        }
        self.linear = match linear {
            Some(linear) => (self.spring.iter())
                .map(|&e| linear.get(e as usize).copied().unwrap_or(0.0))
                .collect(),
            None => Vec::new(),
        };
    }

    /// Copies the parameters of `changed` springs (indices into `springs`, repeats allowed)
    /// into their two slots: after a cut or a tear, `O(changed)` where [`SpringSlots::refresh`]
    /// is `O(slots)`, which at 16k vertices costs more than the step a tear happens in.
    pub fn refresh_springs(&mut self, springs: &super::EdgeSprings, changed: &[u32]) {
        for &e in changed {
            for slot in self.slots_of[e as usize] {
                self.copy_spring(slot as usize, springs);
            }
        }
    }

    /// Copies `slot`'s spring's rest length, stiffness, damping and flags from `springs`
    /// (zeros for padding), keeping which end the slot is.
    fn copy_spring(&mut self, slot: usize, springs: &super::EdgeSprings) {
        let e = self.spring[slot] as usize;
        let kept = self.flags[slot] & (Self::SECOND_END | Self::PADDING);
        if e == springs.len() {
            (self.rest[slot], self.k[slot], self.c[slot]) = (0.0, 0.0, 0.0);
            self.flags[slot] = kept;
            return;
        }
        (self.rest[slot], self.k[slot], self.c[slot]) =
            (springs.rest[e], springs.k[e], springs.c[e]);
        let seam = springs.kind[e] == super::EdgeKind::Seam;
        self.flags[slot] =
            kept | (seam as u8 * Self::SEAM) | (springs.active[e] as u8 * Self::ACTIVE);
    }

    /// The other ends of the slots `range`, each below [`SpringSlots::vertices`].
    pub fn other(&self, range: std::ops::Range<usize>) -> &[u32] {
        &self.other[range]
    }

    /// The number of vertices of the numbering.
    pub fn vertices(&self) -> usize {
        self.vertices
    }

    pub fn heap_bytes(&self) -> usize {
        (self.other.capacity() + self.spring.capacity()) * 4
            + self.slots_of.capacity() * 8
            + (self.rest.capacity() + self.k.capacity() + self.c.capacity()) * 4
            + self.linear.capacity() * 4
            + self.flags.capacity()
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
        let mut seen = vec![false; lists.len()];
        for g in 0..lists.len().div_ceil(LANES) {
            let rows = lanes.group(g);
            let members = lanes.members(g);
            assert_eq!(rows.len() % LANES, 0);
            for lane in 0..LANES {
                let column: Vec<u32> = rows.chunks_exact(LANES).map(|r| r[lane]).collect();
                let v = members.get(lane).map(|&v| v as usize);
                let list = v.map_or(&[][..], |v| &lists[v][..]);
                assert_eq!(&column[..list.len()], list, "vertex {v:?}");
                assert!(column[list.len()..].iter().all(|&e| e == pad));
            }
            for &v in members {
                assert!(!seen[v as usize], "vertex {v} in two lanes");
                seen[v as usize] = true;
            }
            // A group is as long as its longest list.
            let longest = members.iter().map(|&v| lists[v as usize].len());
            assert_eq!(rows.len() / LANES, longest.max().unwrap());
        }
        assert!(seen.iter().all(|&s| s), "a vertex in no lane");
    }

    #[test]
    fn a_groups_vertices_come_from_one_window_in_order_of_their_lists_length() {
        // Three windows, the last partial, lists of 1 to 12 entries in a scattered pattern, so
        // that groups of consecutive vertices would each be padded up to about 12 rows.
        let n = 2 * WINDOW + 40;
        let springs = 100u32;
        let length = |v: usize| (v * 7919 % 12 + 1) as u32;
        let mut offsets = vec![0u32];
        let mut incident = Vec::new();
        for v in 0..n {
            incident.extend((0..length(v)).map(|k| ((v as u32 + k) % springs) << 1));
            offsets.push(incident.len() as u32);
        }
        let lanes = IncidenceLanes::new(&offsets, &incident, springs as usize);
        let groups = n.div_ceil(LANES);
        let mut last = (0, 0);
        for g in 0..groups {
            let members = lanes.members(g);
            let window = g * LANES / WINDOW;
            assert!(
                members.iter().all(|&v| v as usize / WINDOW == window),
                "group {g}"
            );
            // In a window, each group's shortest list is at least the last group's longest.
            let lengths = members.iter().map(|&v| length(v as usize));
            let (short, long) = (lengths.clone().min().unwrap(), lengths.max().unwrap());
            if last.0 == window && g > 0 {
                assert!(short >= last.1, "group {g}: {short} after {}", last.1);
            }
            last = (window, long);
        }
        // So few slots pad: in each window at most `LANES - 1` lanes short by the 11 steps of
        // length in all, and the last group's empty lanes.
        let entries = incident.len();
        let slots = (0..groups).map(|g| lanes.group(g).len()).sum::<usize>();
        let bound = 3 * (LANES - 1) * 11 + LANES * 12;
        assert!(
            slots - entries <= bound,
            "{slots} slots for {entries} entries"
        );
    }
}
