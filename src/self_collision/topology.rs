//! What self-collision needs of the mesh: its triangles, its edges and the vertices they use,
//! rebuilt only when the model's `topology_version` moves (a cut). Built from
//! the triangle list alone ([`crate::grid::Grid::triangles`]), never from grid cells, so a
//! mesh whose triangles come from elsewhere (cuts, tears) needs nothing new here.

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
}

impl Topology {
    /// Rebuilds everything from `triangles` over `n` particles.
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
        };
    }

    pub fn heap_bytes(&self) -> usize {
        self.triangles.capacity() * 12
            + self.edges.capacity() * 8
            + self.vertices.capacity() * 4
            + self.in_mesh.capacity()
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
    }
}
