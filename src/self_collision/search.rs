//! The search for pairs: every vertex-triangle pair (the vertex not in the triangle) and
//! edge-edge pair (no shared vertex) whose boxes overlap, through trees over the vertices',
//! the triangles' and the edges' boxes (a primitive's box the union of its vertices'), shaped
//! once for the mesh and refitted at every search, walked two at a time.

use glam::Vec3;
use rayon::prelude::*;

use crate::self_collision::bvh::{Aabb, Bvh};
use crate::self_collision::pair::{edge_edge, vertex_triangle, Pair};
use crate::self_collision::topology::Topology;
use crate::soa::Vec3s;

/// The search's workspace.
#[derive(Default)]
pub struct Broad {
    tri_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    /// The mesh's vertices' boxes, in `Topology::vertices` order.
    vert_boxes: Vec<Aabb>,
    vert_tree: Bvh,
    tri_tree: Bvh,
    edge_tree: Bvh,
    /// The pairs found, each with what orders it.
    vertex_triangles: Vec<(u64, Pair)>,
    edge_edges: Vec<(u64, Pair)>,
    /// The topology version the trees were shaped for.
    shaped_for: Option<u64>,
}

/// What a search looked at.
#[derive(Clone, Copy, Debug, Default)]
pub struct Looked {
    /// Boxes tested against each other (the trees' nodes and items).
    pub boxes: u64,
    /// Pairs whose boxes overlapped, and so whose closest points were computed.
    pub candidates: u64,
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
    ) -> Looked {
        let vb = vertex_boxes;
        self.tri_boxes.clear();
        self.tri_boxes
            .par_extend(topo.triangles.par_iter().map(|t| union(vb, t)));
        self.edge_boxes.clear();
        self.edge_boxes
            .par_extend(topo.edges.par_iter().map(|e| union(vb, e)));
        self.vert_boxes.clear();
        self.vert_boxes
            .extend(topo.vertices.iter().map(|&v| vb[v as usize]));
        if self.shaped_for != topo.version
            || !self.vert_tree.is_built_for(self.vert_boxes.len())
            || !self.tri_tree.is_built_for(self.tri_boxes.len())
            || !self.edge_tree.is_built_for(self.edge_boxes.len())
        {
            self.vert_tree.build(&self.vert_boxes);
            self.tri_tree.build(&self.tri_boxes);
            self.edge_tree.build(&self.edge_boxes);
            self.shaped_for = topo.version;
        } else {
            self.vert_tree.refit(&self.vert_boxes);
            self.tri_tree.refit(&self.tri_boxes);
            self.edge_tree.refit(&self.edge_boxes);
        }
        let vertex_triangle_pair = |k: u32, t: u32, out: &mut Vec<(u64, Pair)>| {
            let v = topo.vertices[k as usize];
            let [a, b, c] = topo.triangles[t as usize];
            if v == a || v == b || v == c {
                return false;
            }
            let pair = vertex_triangle(x, [v, a, b, c]);
            if keep(&pair) {
                out.push(((v as u64) << 32 | t as u64, pair));
            }
            true
        };
        let (boxes, candidates) = self.vert_tree.overlapping_pairs(
            Some(&self.tri_tree),
            vertex_triangle_pair,
            &mut self.vertex_triangles,
        );
        let edge_edge_pair = |e: u32, f: u32, out: &mut Vec<(u64, Pair)>| {
            let (e, f) = (e.min(f), e.max(f));
            let ([a, b], [c, d]) = (topo.edges[e as usize], topo.edges[f as usize]);
            if a == c || a == d || b == c || b == d {
                return false;
            }
            let pair = edge_edge(x, [a, b, c, d]);
            if keep(&pair) {
                out.push(((e as u64) << 32 | f as u64, pair));
            }
            true
        };
        let more = self
            .edge_tree
            .overlapping_pairs(None, edge_edge_pair, &mut self.edge_edges);
        // Vertex then triangle, then edge then edge: an order of the pairs alone, whatever the
        // trees' shape or the thread count (the keys are distinct, so an unstable sort is
        // exact).
        self.vertex_triangles.par_sort_unstable_by_key(|p| p.0);
        self.edge_edges.par_sort_unstable_by_key(|p| p.0);
        out.clear();
        out.extend(self.vertex_triangles.iter().map(|p| p.1));
        out.extend(self.edge_edges.iter().map(|p| p.1));
        Looked {
            boxes: boxes + more.0,
            candidates: candidates + more.1,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.tri_boxes.capacity() + self.edge_boxes.capacity()) * size_of::<Aabb>()
            + self.vert_boxes.capacity() * size_of::<Aabb>()
            + (self.vertex_triangles.capacity() + self.edge_edges.capacity())
                * size_of::<(u64, Pair)>()
            + self.vert_tree.heap_bytes()
            + self.tri_tree.heap_bytes()
            + self.edge_tree.heap_bytes()
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
