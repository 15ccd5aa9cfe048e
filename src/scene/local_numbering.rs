//! A mesh cloth's springs by vertex (the incidence lists) and, where the user's vertex numbering
//! is scattered, a local numbering for the force pass.

use super::edge_springs::{EdgeKind, EdgeSprings};
use super::IncidenceLanes;

/// Each vertex's place in a local order of the mesh's springs (seams apart: they join pieces
/// that the order takes one after another; [`crate::linear::amg::local_order`]), or None where
/// that is the vertex numbering: a mesh numbered row by row is local already, one read from a
/// file in a scattered order gets a breadth-first order.
pub(super) fn local_order(n: usize, springs: &EdgeSprings) -> Option<Vec<u32>> {
    let mesh = (0..springs.len()).filter(|&e| springs.kind[e] != EdgeKind::Seam);
    let mut offsets = vec![0usize; n + 1];
    for e in mesh.clone() {
        offsets[springs.a[e] as usize + 1] += 1;
        offsets[springs.b[e] as usize + 1] += 1;
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut next = offsets.clone();
    let mut neighbours = vec![0u32; offsets[n]];
    for e in mesh {
        let (a, b) = (springs.a[e], springs.b[e]);
        for (v, other) in [(a, b), (b, a)] {
            neighbours[next[v as usize]] = other;
            next[v as usize] += 1;
        }
    }
    let order = crate::linear::amg::local_order(&vec![true; n], &offsets, &neighbours);
    if order.iter().enumerate().all(|(k, &v)| k == v as usize) {
        return None;
    }
    Some(crate::linear::amg::places(&order, n))
}

/// A local numbering of a mesh cloth's vertices, in which the force pass works where the
/// user's numbering is scattered: it gathers the positions and velocities into it, runs its
/// pass there ([`crate::mesh_cloth::forces`]) and scatters the forces back. Each
/// vertex's springs are the same, summed in the same order, so the forces are bitwise those of
/// the passes in the user's numbering; only the gathers come from a few cache lines instead
/// of the whole state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocalNumbering {
    /// `vertices[k]` is the vertex numbered `k` here, and `place[v]` vertex `v`'s number.
    pub vertices: Vec<u32>,
    pub place: Vec<u32>,
    /// Each spring's ends in this numbering (the lower vertex index first, as in the list).
    pub a: Vec<u32>,
    pub b: Vec<u32>,
    /// The springs touching each vertex of this numbering, as [`super::MeshCloth::incident`]
    /// lists them (offsets and entries), and laid out as [`super::MeshCloth::lanes`].
    pub offsets: Vec<u32>,
    pub incident: Vec<u32>,
    pub lanes: IncidenceLanes,
}

impl LocalNumbering {
    pub(super) fn new(
        place: Vec<u32>,
        springs: &EdgeSprings,
        offsets: &[u32],
        incident: &[u32],
    ) -> Self {
        let vertices = crate::linear::amg::places(&place, place.len());
        let mut local_offsets = vec![0u32];
        let mut local_incident = Vec::with_capacity(incident.len());
        for &v in &vertices {
            let v = v as usize;
            local_incident
                .extend_from_slice(&incident[offsets[v] as usize..offsets[v + 1] as usize]);
            local_offsets.push(local_incident.len() as u32);
        }
        let lanes = IncidenceLanes::new(&local_offsets, &local_incident, springs.len());
        LocalNumbering {
            a: springs.a.iter().map(|&v| place[v as usize]).collect(),
            b: springs.b.iter().map(|&v| place[v as usize]).collect(),
            vertices,
            place,
            offsets: local_offsets,
            incident: local_incident,
            lanes,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.vertices.capacity() + self.place.capacity()) * 4
            + (self.a.capacity() + self.b.capacity()) * 4
            + (self.offsets.capacity() + self.incident.capacity()) * 4
            + self.lanes.heap_bytes()
    }
}

/// For each vertex, the springs that touch it, in increasing order (CSR).
pub(super) fn incidence(n: usize, springs: &EdgeSprings) -> (Vec<u32>, Vec<u32>) {
    let mut count = vec![0u32; n + 1];
    for s in 0..springs.len() {
        count[springs.a[s] as usize + 1] += 1;
        count[springs.b[s] as usize + 1] += 1;
    }
    for v in 0..n {
        count[v + 1] += count[v];
    }
    let offsets = count.clone();
    let mut next = count;
    let mut incident = vec![0u32; 2 * springs.len()];
    for s in 0..springs.len() {
        for (end, v) in [(0, springs.a[s]), (1, springs.b[s])] {
            incident[next[v as usize] as usize] = (s as u32) << 1 | end;
            next[v as usize] += 1;
        }
    }
    (offsets, incident)
}

/// Sets `into[a][k]` to `from[a][index[k]]` for each array `a` and each `k` of `index`: the
/// state or the forces copied into a local numbering, or back from it. Checked once per array,
/// unchecked inside; a plain copy, so bitwise the same on every instruction set.
#[inline(always)]
pub fn gather_by<const N: usize>(into: [&mut [f32]; N], from: [&[f32]; N], index: &[u32]) {
    let top = index.iter().map(|&i| i as usize + 1).max().unwrap_or(0);
    for (into, from) in into.into_iter().zip(from) {
        assert!(
            top <= from.len() && index.len() <= into.len(),
            "a gather's index beyond its {} values",
            from.len()
        );
        for (k, &i) in index.iter().enumerate() {
            // SAFETY: `k` is below `into.len()` and every index below `from.len()`
            // (checked above).
            unsafe { *into.get_unchecked_mut(k) = *from.get_unchecked(i as usize) };
        }
    }
}
