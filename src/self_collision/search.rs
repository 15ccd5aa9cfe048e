//! The search for pairs: every vertex-triangle pair (the vertex not in the triangle) and
//! edge-edge pair (no shared vertex) whose boxes overlap, through a spatial hash of the
//! triangles' and the edges' boxes, each the union of its vertices' boxes.

use glam::Vec3;
use rayon::prelude::*;

use crate::self_collision::hash::{Aabb, HashGrid};
use crate::self_collision::pair::{edge_edge, vertex_triangle, Pair};
use crate::self_collision::topology::Topology;
use crate::soa::Vec3s;

/// Vertices (or edges) a parallel task searches for; each task keeps its own scratch, so a
/// search allocates per task, not per vertex.
const CHUNK: usize = 256;

/// The search's workspace.
#[derive(Default)]
pub struct Broad {
    tri_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    tri_grid: HashGrid,
    edge_grid: HashGrid,
}

impl Broad {
    /// Into `out`, in vertex then triangle and edge then edge order (so the same for any
    /// thread count): every pair whose boxes overlap, given each vertex's box, that `keep`
    /// keeps, with its closest points at `x`. A primitive's box is the union of its vertices'.
    pub fn search(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        keep: impl Fn(&Pair) -> bool + Sync,
        out: &mut Vec<Pair>,
    ) {
        let vb = vertex_boxes;
        self.tri_boxes.clear();
        self.tri_boxes
            .par_extend(topo.triangles.par_iter().map(|t| union(vb, t)));
        self.edge_boxes.clear();
        self.edge_boxes
            .par_extend(topo.edges.par_iter().map(|e| union(vb, e)));
        self.tri_grid.build(&self.tri_boxes);
        self.edge_grid.build(&self.edge_boxes);
        let eb = &self.edge_boxes;
        let (tri_grid, edge_grid) = (&self.tri_grid, &self.edge_grid);
        let vertex_triangles = topo.vertices.par_chunks(CHUNK).map(|chunk| {
            let (mut found, mut pairs) = (Vec::new(), Vec::new());
            for &v in chunk {
                let b = vb[v as usize];
                found.clear();
                tri_grid.query(&b, |t| {
                    if !topo.triangles[t as usize].contains(&v) {
                        found.push(t);
                    }
                });
                found.sort_unstable();
                found.dedup();
                let near = found.iter().map(|&t| {
                    let [a, b, c] = topo.triangles[t as usize];
                    vertex_triangle(x, [v, a, b, c])
                });
                pairs.extend(near.filter(&keep));
            }
            pairs
        });
        let edge_edges = topo.edges.par_chunks(CHUNK).enumerate().map(|(k, chunk)| {
            let (mut found, mut pairs) = (Vec::new(), Vec::new());
            for (e, &[a, b]) in (k * CHUNK..).zip(chunk) {
                let bx = eb[e];
                found.clear();
                edge_grid.query(&bx, |f| {
                    if (f as usize) > e {
                        let [c, d] = topo.edges[f as usize];
                        if a != c && a != d && b != c && b != d {
                            found.push(f);
                        }
                    }
                });
                found.sort_unstable();
                found.dedup();
                let near = found.iter().map(|&f| {
                    let [c, d] = topo.edges[f as usize];
                    edge_edge(x, [a, b, c, d])
                });
                pairs.extend(near.filter(&keep));
            }
            pairs
        });
        let found: Vec<Vec<Pair>> = vertex_triangles.chain(edge_edges).collect();
        out.clear();
        out.extend(found.into_iter().flatten());
    }

    pub fn heap_bytes(&self) -> usize {
        (self.tri_boxes.capacity() + self.edge_boxes.capacity()) * size_of::<Aabb>()
            + self.tri_grid.heap_bytes()
            + self.edge_grid.heap_bytes()
    }
}

/// The union of `vertices`' boxes.
fn union(vertex_boxes: &[Aabb], vertices: &[u32]) -> Aabb {
    let (mut min, mut max) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &v in vertices {
        let b = &vertex_boxes[v as usize];
        (min, max) = (min.min(b.min), max.max(b.max));
    }
    Aabb { min, max }
}
