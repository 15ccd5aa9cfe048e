//! Which triangle corners meet at each vertex of a triangle list, as compressed rows: built once
//! for a topology, read by the passes that gather per vertex (the triangle membrane's forces)
//! or look up a vertex's triangles (a cut in the picking tree).

/// Each vertex's corners: `corners[offsets[v]..offsets[v + 1]]` holds `3 t + k` for every
/// triangle `t` whose corner `k` is `v`, in increasing order. `vertices` is at least one more
/// than the largest index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Corners {
    pub offsets: Vec<u32>,
    pub corners: Vec<u32>,
}

impl Corners {
    pub fn new(triangles: &[[u32; 3]], vertices: usize) -> Self {
        let mut offsets = vec![0u32; vertices + 1];
        for &v in triangles.iter().flatten() {
            offsets[v as usize + 1] += 1;
        }
        for v in 0..vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut next = offsets.clone();
        let mut corners = vec![0u32; 3 * triangles.len()];
        for (t, tri) in triangles.iter().enumerate() {
            for (k, &v) in tri.iter().enumerate() {
                corners[next[v as usize] as usize] = (3 * t + k) as u32;
                next[v as usize] += 1;
            }
        }
        Corners { offsets, corners }
    }

    /// Vertex `v`'s corners (`3 t + k`); none for a vertex beyond the list.
    pub fn at(&self, v: usize) -> &[u32] {
        match (self.offsets.get(v), self.offsets.get(v + 1)) {
            (Some(&lo), Some(&hi)) => &self.corners[lo as usize..hi as usize],
            _ => &[],
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.offsets.capacity() + self.corners.capacity()) * 4
    }
}
