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
    sorted: Vec<(u64, u32)>,
    /// The topology version the trees were shaped for.
    shaped_for: Option<u64>,
}

/// What a search looked at.
#[derive(Clone, Copy, Debug, Default)]
pub struct Looked {
    /// Boxes tested against each other (the trees' nodes and items).
    pub boxes: u64,
    /// Pairs whose boxes overlapped: each is passed over by its tight boxes or given its
    /// closest points.
    pub candidates: u64,
}

impl Broad {
    /// Into `out`, in vertex then triangle and edge then edge order (so the same for any
    /// thread count): every pair whose boxes overlap, given each vertex's box, and which is
    /// closer than `limit(verts, split)` at `x`, with its closest points there. A primitive's
    /// box is the union of its vertices'. `margin` (m) bounds the round-off of a distance at
    /// `x`: a pair whose primitives' tight boxes at `x` are farther apart than `limit` and
    /// `margin` is passed over without its closest points.
    pub fn search(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        limit: impl Fn(&[u32; 4], usize) -> f64 + Sync,
        margin: f64,
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
        // A candidate's closest points, kept under `key` when closer than its limit; its tight
        // boxes pass over it first when they are already farther apart than that.
        let keep_close = |verts: [u32; 4],
                          split: usize,
                          key: u64,
                          closest: fn(&Vec3s, [u32; 4]) -> Pair,
                          out: &mut Vec<(u64, Pair)>| {
            let most = limit(&verts, split);
            if apart(x, &verts, split) <= most + margin {
                let pair = closest(x, verts);
                if pair.d0 < most {
                    out.push((key, pair));
                }
            }
        };
        let vertex_triangle_pair = |k: u32, t: u32, out: &mut Vec<(u64, Pair)>| {
            let v = topo.vertices[k as usize];
            let [a, b, c] = topo.triangles[t as usize];
            if topo.joined(v, a) || topo.joined(v, b) || topo.joined(v, c) {
                return false;
            }
            let key = (v as u64) << 32 | t as u64;
            keep_close([v, a, b, c], 1, key, vertex_triangle, out);
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
            let joined = |p: u32| topo.joined(p, c) || topo.joined(p, d);
            if joined(a) || joined(b) {
                return false;
            }
            let key = (e as u64) << 32 | f as u64;
            keep_close([a, b, c, d], 2, key, edge_edge, out);
            true
        };
        let more = self
            .edge_tree
            .overlapping_pairs(None, edge_edge_pair, &mut self.edge_edges);
        // Vertex then triangle, then edge then edge: an order of the pairs alone, whatever the
        // trees' shape or the thread count (the keys are distinct, so an unstable sort is
        // exact).
        // The keys are sorted with where each pair is, not with the pairs (ten times larger).
        out.clear();
        for found in [&self.vertex_triangles, &self.edge_edges] {
            self.sorted.clear();
            self.sorted
                .extend(found.iter().enumerate().map(|(k, p)| (p.0, k as u32)));
            self.sorted.par_sort_unstable();
            out.extend(self.sorted.iter().map(|&(_, k)| found[k as usize].1));
        }
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
            + self.sorted.capacity() * 16
            + self.vert_tree.heap_bytes()
            + self.tri_tree.heap_bytes()
            + self.edge_tree.heap_bytes()
    }
}

/// The distance between the boxes of `verts[..split]` and `verts[split..]` at `x` (m), a lower
/// bound of the distance between the primitives, each inside its box: cheaper than their
/// closest points, and enough to pass over the neighbours a box test lets through in a flat
/// cloth (two parallel edges a grid spacing apart).
#[inline]
fn apart(x: &Vec3s, verts: &[u32; 4], split: usize) -> f64 {
    let bounds = |s: &[u32]| {
        let first = x.get(s[0] as usize);
        s[1..].iter().fold((first, first), |(lo, hi), &v| {
            let p = x.get(v as usize);
            (lo.min(p), hi.max(p))
        })
    };
    let ((lo_a, hi_a), (lo_b, hi_b)) = (bounds(&verts[..split]), bounds(&verts[split..]));
    // Per axis, the gap between the two intervals (zero where they overlap), exact in f64.
    let gap = (lo_b.as_dvec3() - hi_a.as_dvec3())
        .max(lo_a.as_dvec3() - hi_b.as_dvec3())
        .max(glam::DVec3::ZERO);
    gap.length()
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
