//! What self-collision needs of the mesh: its triangles, its edges and the vertices they use,
//! rebuilt only when the model's `topology_version` moves (a cut). Built from
//! the triangle list alone ([`crate::grid::Grid::triangles`]), never from grid cells, so a
//! mesh whose triangles come from elsewhere (cuts, tears) needs nothing new here.
//!
//! Vertices sewn together (a garment's seams, [`crate::model::Model::sewn`]) are one point to
//! the search: a vertex and a triangle through its partner, or two edges through a sewn pair,
//! are neighbours, as primitives sharing a vertex are, and never a pair. Otherwise the
//! repulsion between the two panels' seam edges would hold every seam `thickness` open
//! against the seam springs pulling it shut.

/// The mesh of the live cloth, as the contact pass walks it.
#[derive(Default)]
pub struct Topology {
    /// The topology version this was built for.
    pub version: Option<u64>,
    pub triangles: Vec<[u32; 3]>,
    /// Each undirected edge once, `a < b`, sorted.
    pub edges: Vec<[u32; 2]>,
    /// The vertices some triangle uses, ascending (a vertex in no triangle cannot collide).
    pub vertices: Vec<u32>,
    /// Whether each particle is a vertex of some triangle.
    pub in_mesh: Vec<bool>,
    /// Each particle's stand-in as a neighbour: the lowest particle sewn to it, directly or
    /// through others, or itself.
    pub same: Vec<u32>,
}

impl Topology {
    /// Rebuilds everything from `triangles` over `n` particles, none sewn.
    pub fn rebuild(&mut self, version: u64, n: usize, triangles: Vec<[u32; 3]>) {
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let mut in_mesh = vec![false; n];
        for &q in triangles.iter().flatten() {
            in_mesh[q as usize] = true;
        }
        let vertices = (0..n as u32).filter(|&p| in_mesh[p as usize]).collect();
        *self = Topology {
            version: Some(version),
            triangles,
            edges,
            vertices,
            in_mesh,
            same: (0..n as u32).collect(),
        };
    }

    /// Makes each vertex pair of `sewn` one point, directly or through others (union-find):
    /// each vertex stands for the lowest it is joined to.
    pub fn sew(&mut self, sewn: impl IntoIterator<Item = [u32; 2]>) {
        fn root(same: &mut [u32], mut v: u32) -> u32 {
            while same[v as usize] != v {
                same[v as usize] = same[same[v as usize] as usize];
                v = same[v as usize];
            }
            v
        }
        let same = &mut self.same;
        for [a, b] in sewn {
            let (ra, rb) = (root(same, a), root(same, b));
            same[ra.max(rb) as usize] = ra.min(rb);
        }
        for v in 0..same.len() as u32 {
            same[v as usize] = root(same, v);
        }
    }

    /// Whether primitives through `a` and through `b` are neighbours: one vertex, or sewn.
    #[inline]
    pub fn joined(&self, a: u32, b: u32) -> bool {
        self.same[a as usize] == self.same[b as usize]
    }

    pub fn heap_bytes(&self) -> usize {
        self.triangles.capacity() * 12
            + self.edges.capacity() * 8
            + self.vertices.capacity() * 4
            + self.in_mesh.capacity()
            + self.same.capacity() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_share_one_edge() {
        let mut t = Topology::default();
        t.rebuild(3, 5, vec![[0, 1, 3], [0, 3, 2]]);
        assert_eq!(t.edges, vec![[0, 1], [0, 2], [0, 3], [1, 3], [2, 3]]);
        assert_eq!(t.vertices, vec![0, 1, 2, 3]);
        assert!(!t.in_mesh[4]);
        assert_eq!(t.version, Some(3));
        assert!(!t.joined(1, 2));
    }

    #[test]
    fn vertices_sewn_together_directly_or_through_others_are_one_point() {
        let mut t = Topology::default();
        t.rebuild(0, 6, vec![[0, 1, 2], [3, 4, 5]]);
        t.sew([[4, 1], [5, 4]]);
        assert_eq!(t.same, vec![0, 1, 2, 3, 1, 1]);
        assert!(t.joined(5, 1) && t.joined(4, 4) && !t.joined(0, 3));
    }
}
