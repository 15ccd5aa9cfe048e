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
    /// Each triangle's place among the triangles ordered by their vertices (for
    /// [`Order::Vertices`]).
    tri_rank: Vec<u32>,
    /// The topology version the trees were shaped for.
    shaped_for: Option<u64>,
}

/// How a search orders the vertex-triangle pairs it finds: by vertex, then by the triangle's
/// index (`Index`) or by the triangle's vertices (`Vertices`, the order of
/// [`crate::self_collision::pair::Candidate::key`], which the pair list keeps). The edge-edge
/// pairs come after them in the order of their edges, which is their vertices' order either way
/// (the edges are sorted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    Index,
    Vertices,
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
    /// Into `out`, in vertex then triangle (as `order` says) and edge then edge order (so the
    /// same for any thread count): every pair whose boxes overlap, given each vertex's box, and which is
    /// closer than `limit(verts, split)` at `x`, with its closest points there. A primitive's
    /// box is the union of its vertices'. `margin` (m) bounds the round-off of a distance at
    /// `x`: a pair whose primitives' tight boxes at `x` are farther apart than `limit` and
    /// `margin` is passed over without its closest points.
    // Each argument is a separate input of the one search both ways of finding pairs share.
    #[allow(clippy::too_many_arguments)]
    pub fn search(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        limit: impl Fn(&[u32; 4], usize) -> f64 + Sync,
        margin: f64,
        order: Order,
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
            let mut by_vertices: Vec<u32> = (0..topo.triangles.len() as u32).collect();
            by_vertices.sort_unstable_by_key(|&t| (topo.triangles[t as usize], t));
            self.tri_rank = vec![0; by_vertices.len()];
            for (rank, &t) in by_vertices.iter().enumerate() {
                self.tri_rank[t as usize] = rank as u32;
            }
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
        let tri_rank = &self.tri_rank;
        let vertex_triangle_pair = |k: u32, t: u32, out: &mut Vec<(u64, Pair)>| {
            let v = topo.vertices[k as usize];
            let [a, b, c] = topo.triangles[t as usize];
            if topo.joined(v, a) || topo.joined(v, b) || topo.joined(v, c) {
                return false;
            }
            let place = match order {
                Order::Index => t,
                Order::Vertices => tri_rank[t as usize],
            };
            let key = (v as u64) << 32 | place as u64;
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
            + self.tri_rank.capacity() * 4
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The pair list keeps its pairs in the order a substep looks at them and takes them with a
    /// filter, so a search for it must find them in that order, `Candidate::key`'s: by vertex,
    /// then by the triangle's vertices, which is not the triangles' index order here. Both
    /// orders must hold the same pairs.
    #[test]
    fn ordered_by_vertices_the_pairs_come_in_the_order_of_their_keys() {
        // Two layers of four triangles 1 mm apart, the second layer's triangles listed with
        // their vertices out of index order.
        let at = |k: usize| {
            let (layer, i, j) = (k / 9, k % 3, (k / 3) % 3);
            Vec3::new(0.01 * i as f32, 0.01 * j as f32, 0.001 * layer as f32)
        };
        let x = Vec3s::from_fn(18, at);
        let mut triangles = Vec::new();
        for layer in [9, 0] {
            for (i, j) in [(1, 1), (0, 0), (1, 0), (0, 1)] {
                let v = layer + 3 * j + i;
                triangles.push([v + 4, v, v + 1]);
                triangles.push([v + 3, v, v + 4]);
            }
        }
        let mut topo = Topology::default();
        topo.rebuild(0, 18, triangles);
        let boxes: Vec<Aabb> = (0..18)
            .map(|v| Aabb {
                min: x.get(v) - Vec3::splat(0.002),
                max: x.get(v) + Vec3::splat(0.002),
            })
            .collect();
        let mut broad = Broad::default();
        let key = |p: &Pair| p.candidate().key();
        let (mut by_index, mut by_vertices) = (Vec::new(), Vec::new());
        let limit = |_: &[u32; 4], _| 0.004;
        broad.search(&topo, &boxes, &x, limit, 0.0, Order::Index, &mut by_index);
        broad.search(
            &topo,
            &boxes,
            &x,
            limit,
            0.0,
            Order::Vertices,
            &mut by_vertices,
        );
        assert!(by_vertices.len() > 20, "{}", by_vertices.len());
        assert!(by_vertices.windows(2).all(|w| key(&w[0]) < key(&w[1])));
        assert!(by_index.windows(2).any(|w| key(&w[0]) > key(&w[1])));
        by_index.sort_unstable_by_key(key);
        assert!(by_index
            .iter()
            .zip(&by_vertices)
            .all(|(p, q)| key(p) == key(q)));
        assert_eq!(by_index.len(), by_vertices.len());
    }
}
