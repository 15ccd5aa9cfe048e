//! The search for pairs: every vertex-triangle pair (the vertex not in the triangle) and
//! edge-edge pair (no shared vertex) whose boxes overlap, through trees over the vertices',
//! the triangles' and the edges' boxes (a primitive's box the union of its vertices'), shaped
//! once for the mesh and refitted at every search, walked two at a time.

use glam::Vec3;
use rayon::prelude::*;

use crate::self_collision::bvh::{Aabb, Bvh, WalkScratch};
use crate::self_collision::pair::{distance, edge_edge, vertex_triangle, Candidate, Pair};
use crate::self_collision::parts::Parts;
use crate::self_collision::per_surface_vertex;
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
    /// The candidate pairs of a swept search, each under its key with the most it may be
    /// apart to be found (m), and in key order: their closest points are taken after the walk,
    /// in that order, or taken over from the search they were kept from.
    candidate_vt: Vec<(u64, f64)>,
    candidate_ee: Vec<(u64, f64)>,
    sorted_candidates: Vec<(u64, f64)>,
    /// The candidates of the last [`Broad::search_wide`], under their keys (by index) with
    /// their tight boxes' distance (m, what a narrower search's tests compare), for
    /// [`Broad::search_among_wide`] to take the pairs of narrower searches from; and the
    /// candidates through the vertices outside it, found on their own.
    wide_vt: Vec<(u64, f64)>,
    wide_ee: Vec<(u64, f64)>,
    outside_vt: Vec<(u64, f64)>,
    outside_ee: Vec<(u64, f64)>,
    /// The candidates a search kept ([`Reuse::Keep`]) with their closest points, under their
    /// keys in `kept_for`'s order, the vertex-triangle pairs first (`kept_split` of them), and
    /// where each vertex's and edge's start among those of its kind.
    kept_for: Option<Order>,
    kept_keys: Vec<u64>,
    kept_pairs: Vec<Pair>,
    kept_split: usize,
    kept_starts: [Vec<u32>; 2],
    /// The pairs found for the pair list, each with what orders it and its distance (m): a
    /// sixth of a pair with its closest points, which a list rebuild finds by the hundred
    /// thousand.
    near_vertex_triangles: Vec<(u64, f64)>,
    near_edge_edges: Vec<(u64, f64)>,
    /// The pair list's pairs found, each under its key with its distance, in that order: the
    /// first `near_split` vertex-triangle pairs, then the edge-edge pairs.
    sorted_near: Vec<(u64, f64)>,
    near_split: usize,
    /// Where each key's first vertex or edge starts among the sorted pairs, and where its next
    /// pair goes.
    starts: Vec<u32>,
    cursor: Vec<u32>,
    /// Each triangle's place among the triangles ordered by their vertices (for
    /// [`Order::Vertices`]), and the triangle at each place.
    tri_rank: Vec<u32>,
    by_rank: Vec<u32>,
    /// The topology version the trees were shaped for.
    shaped_for: Option<u64>,
    /// Each triangle's and edge's tight box at the search's positions, and the most any vertex
    /// of each vertex, triangle and edge may move (m; a vertex's by particle), for a whole
    /// search: a primitive is in a few dozen candidate pairs, so its box and its reach are
    /// taken once, not once a pair.
    tight_tris: Vec<Aabb>,
    tight_edges: Vec<Aabb>,
    vert_side: Vec<f64>,
    tri_side: Vec<f64>,
    edge_side: Vec<f64>,
    /// The buffers the searches' parallel parts fill, kept from search to search (the walks of
    /// the vertex-triangle and the edge-edge trees, the filters of candidates and of pairs):
    /// the 128 x 128 twist finds megabytes of them a step, which, allocated afresh, the kernel
    /// zeroed page by page (8.8 % of its samples).
    walks: [WalkScratch<Keyed>; 2],
    keyed_parts: Parts<Keyed>,
    pair_parts: Parts<Pair>,
}

/// The keys of the pairs a [`Broad::search_near`] found, in the order of
/// [`Broad::near_found`]: the first `split` vertex-triangle pairs' (the vertex, then the
/// triangle's place among the triangles ordered by their vertices), then the edge-edge pairs'.
#[derive(Default)]
pub struct NearKeys {
    keys: Vec<u64>,
    split: usize,
}

impl NearKeys {
    pub fn clear(&mut self) {
        self.keys.clear();
        self.split = 0;
    }

    pub fn heap_bytes(&self) -> usize {
        self.keys.capacity() * 8
    }
}

/// A candidate pair of a swept search under its key, with the most it may be apart to be found
/// (m).
type Keyed = (u64, f64);

/// Whether a swept search keeps the closest points of its candidates for a later one to take
/// over, or takes them over from the last one that kept them.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Reuse {
    Nothing,
    Keep,
    /// The caller vouches that the search that kept them was at the same positions, bit for
    /// bit, with the same topology: a pair's closest points are a function of its vertices'
    /// positions alone, so a candidate found again is taken over whole, bitwise what it would
    /// be taken anew.
    Take,
}

/// How far apart a pair may be and still be found (m).
#[derive(Clone, Copy)]
enum Limit<'a> {
    /// The same for every pair.
    Fixed(f64),
    /// `base`, the most any vertex of each primitive may move (`vert`, `tri`, `edge`: by
    /// particle, triangle and edge), and `eps`, summed in that order.
    Sides {
        base: f64,
        vert: &'a [f64],
        tri: &'a [f64],
        edge: &'a [f64],
        eps: f64,
    },
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

impl Looked {
    fn and(self, other: Looked) -> Looked {
        Looked {
            boxes: self.boxes + other.boxes,
            candidates: self.candidates + other.candidates,
        }
    }
}

impl Broad {
    /// Into `out`, in vertex then triangle (as `order` says) and edge then edge order (so the
    /// same for any thread count): every pair whose boxes overlap, given each vertex's box, and
    /// which is closer than `limit` at `x`, with its closest points there: `(base, reach, eps)`,
    /// the limit `base + side(a) + side(b) + eps` (m), a primitive's side the most `reach` (m,
    /// by particle) of its vertices. A
    /// primitive's box is the union of its vertices'. `margin` (m) bounds the round-off of a
    /// distance at `x`: a pair whose primitives' tight boxes at `x` are farther apart than
    /// `limit` and `margin` is passed over without its closest points.
    // Each argument is a separate input of the one search both ways of finding pairs share.
    #[allow(clippy::too_many_arguments)]
    pub fn search(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        (base, reach, eps): (f64, impl Fn(u32) -> f64 + Sync, f64),
        margin: f64,
        order: Order,
        reuse: Reuse,
        out: &mut Vec<Pair>,
    ) -> Looked {
        let (mut vt, mut ee) = (
            std::mem::take(&mut self.candidate_vt),
            std::mem::take(&mut self.candidate_ee),
        );
        let limit = (base, reach, eps, margin);
        let looked = self.walk_trees(
            topo,
            (vertex_boxes, x),
            limit,
            order,
            false,
            (&mut vt, &mut ee),
        );
        self.take_found(topo, x, order, reuse, (&vt, &ee), out);
        (self.candidate_vt, self.candidate_ee) = (vt, ee);
        looked
    }

    /// The trees fitted to `vertex_boxes` (and the tight boxes and sides at `x`) and walked:
    /// into `vt` and `ee`, every pair whose boxes overlap and which the swept tests at `x`
    /// keep (`(base, reach, eps, margin)` and `order` as [`Broad::search`] takes them; with
    /// its tight boxes' distance where `keep_gap`). What [`Broad::search`] and
    /// [`Broad::search_wide`] share.
    fn walk_trees(
        &mut self,
        topo: &Topology,
        (vertex_boxes, x): (&[Aabb], &Vec3s),
        (base, reach, eps, margin): (f64, impl Fn(u32) -> f64 + Sync, f64, f64),
        order: Order,
        keep_gap: bool,
        (vt, ee): (&mut Vec<Keyed>, &mut Vec<Keyed>),
    ) -> Looked {
        self.fit(topo, vertex_boxes);
        self.fit_tight(topo, x);
        self.fit_sides(topo, reach);
        let mut walks = std::mem::take(&mut self.walks);
        let tests = self.swept_tests(topo, x, (base, eps, margin), order, (true, keep_gap));
        let looked = self.find(&tests, vt, ee, &mut walks);
        self.walks = walks;
        looked
    }

    /// Into `out`, in vertex then triangle (as `order` says) and edge then edge order: of the
    /// pairs `listed` (the keys of [`Broad::near_keys`], `picked` of them), those that
    /// [`Broad::search`] with the same arguments finds, with the same closest points, to the
    /// bit. Each is put through the search's own tests (its primitives' boxes overlap, as the
    /// trees' leaves test them, its tight boxes are near enough, its distance below its
    /// limit), so a pair the search would find is found here if it is among those picked, and
    /// nothing else is. The trees are not walked: the caller vouches that every pair the
    /// search could find is picked, and that the keys were found with this topology.
    #[allow(clippy::too_many_arguments)]
    pub fn search_listed(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        (base, reach, eps): (f64, impl Fn(u32) -> f64 + Sync, f64),
        margin: f64,
        order: Order,
        reuse: Reuse,
        (listed, picked): (&NearKeys, &[u32]),
        out: &mut Vec<Pair>,
    ) -> Looked {
        self.fit_sides(topo, reach);
        let (mut vt, mut ee) = (
            std::mem::take(&mut self.candidate_vt),
            std::mem::take(&mut self.candidate_ee),
        );
        let mut parts = std::mem::take(&mut self.keyed_parts);
        let tests = self.swept_tests(topo, x, (base, eps, margin), order, (false, false));
        let vb = vertex_boxes;
        let by_rank = &self.by_rank;
        let (of_vt, of_ee) =
            picked.split_at(picked.partition_point(|&k| (k as usize) < listed.split));
        let vertex_triangle = |&k: &u32| {
            let key = listed.keys[k as usize];
            let (v, rank) = ((key >> 32) as u32, key as u32);
            let t = by_rank[rank as usize];
            let tri = topo.triangles[t as usize];
            if !overlap(&vb[v as usize], &union(vb, &tri)) {
                return None;
            }
            let [a, b, c] = tri;
            let place = match order {
                Order::Index => t,
                Order::Vertices => rank,
            };
            let key = (v as u64) << 32 | place as u64;
            tests.close([v, a, b, c], 1, (v, t)).map(|most| (key, most))
        };
        vt.clear();
        parts.filter_map_into(of_vt, 1024, |_, k| vertex_triangle(k), &mut vt);
        let edge_edge = |&k: &u32| {
            let key = listed.keys[k as usize];
            let (e, f) = ((key >> 32) as u32, key as u32);
            let ([a, b], [c, d]) = (topo.edges[e as usize], topo.edges[f as usize]);
            if !overlap(&union(vb, &[a, b]), &union(vb, &[c, d])) {
                return None;
            }
            tests.close([a, b, c, d], 2, (e, f)).map(|most| (key, most))
        };
        ee.clear();
        parts.filter_map_into(of_ee, 1024, |_, k| edge_edge(k), &mut ee);
        self.keyed_parts = parts;
        let looked = Looked {
            boxes: 0,
            candidates: (vt.len() + ee.len()) as u64,
        };
        self.take_found(topo, x, order, reuse, (&vt, &ee), out);
        (self.candidate_vt, self.candidate_ee) = (vt, ee);
        looked
    }

    /// The candidates of a swept search at `x` on boxes and reaches at least as wide as those
    /// of each narrower search that [`Broad::search_among_wide`] is to answer from them: every
    /// pair whose boxes overlap and whose tight boxes at `x` are within its limit
    /// (`(base, reach, eps)` and `margin` as [`Broad::search`] takes them), by key, with the
    /// distance of its tight boxes (the same for every search at `x`), without closest points.
    pub fn search_wide(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        (base, reach, eps): (f64, impl Fn(u32) -> f64 + Sync, f64),
        margin: f64,
    ) -> Looked {
        let (mut vt, mut ee) = (
            std::mem::take(&mut self.wide_vt),
            std::mem::take(&mut self.wide_ee),
        );
        vt.clear();
        ee.clear();
        let limit = (base, reach, eps, margin);
        let looked = self.walk_trees(
            topo,
            (vertex_boxes, x),
            limit,
            Order::Index,
            true,
            (&mut vt, &mut ee),
        );
        (self.wide_vt, self.wide_ee) = (vt, ee);
        looked
    }

    /// What [`Broad::search`] finds at `x` (in [`Order::Index`]) with these arguments, to the
    /// bit, taken from the candidates of the last [`Broad::search_wide`] at `x`. The caller
    /// vouches that that search was at the same `x`, bit for bit, with this topology, and that
    /// each vertex's box and reach here lie inside the ones it searched with, except those of
    /// the vertices `outside` (by particle): then each pair the search finds here whose
    /// vertices are all inside was among its candidates (its boxes overlapped there too, and
    /// its tight boxes were within a limit at least this one), and goes through this search's
    /// own tests; the pairs through a vertex outside are looked up in the trees, refitted to
    /// these boxes, as a partial requery looks them up. The pairs are then those of a whole
    /// search, in its order.
    #[allow(clippy::too_many_arguments)]
    pub fn search_among_wide(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        (base, reach, eps): (f64, impl Fn(u32) -> f64 + Sync, f64),
        margin: f64,
        reuse: Reuse,
        outside: Option<&[bool]>,
        out: &mut Vec<Pair>,
    ) -> Looked {
        let outside = outside.filter(|o| o.iter().any(|&o| o));
        // Each primitive's box once, not once a candidate: the trees too where vertices outside
        // are to be looked up in them.
        if outside.is_some() {
            self.fit(topo, vertex_boxes);
        } else {
            let boxes = |vs: &[u32]| union(vertex_boxes, vs);
            per_primitive(topo, &mut self.tri_boxes, &mut self.edge_boxes, boxes);
        }
        self.fit_sides(topo, reach);
        let (mut vt, mut ee) = (
            std::mem::take(&mut self.candidate_vt),
            std::mem::take(&mut self.candidate_ee),
        );
        let (mut more_vt, mut more_ee) = (
            std::mem::take(&mut self.outside_vt),
            std::mem::take(&mut self.outside_ee),
        );
        let mut parts = std::mem::take(&mut self.keyed_parts);
        let tests = self.swept_tests(topo, x, (base, eps, margin), Order::Index, (true, false));
        let (vb, tri_boxes, edge_boxes) = (vertex_boxes, &self.tri_boxes, &self.edge_boxes);
        let inside =
            |verts: &[u32; 4]| outside.is_none_or(|o| !verts.iter().any(|&v| o[v as usize]));
        // A widened candidate `key` (two primitives' indices) of `kind`, over `verts`, whose
        // tight boxes `overlap`: kept where no vertex is outside its budget and the pair can
        // come within reach, with the gap the widened walk stored.
        let keep = |kind, verts: [u32; 4], overlap: bool, (key, gap): (u64, f64)| {
            if !inside(&verts) || !overlap {
                return None;
            }
            let ids = ((key >> 32) as u32, key as u32);
            tests
                .close_at(verts, kind, ids, gap)
                .map(|most| (key, most))
        };
        let vertex_triangle = |&(key, gap): &(u64, f64)| {
            let (v, t) = ((key >> 32) as usize, key as u32 as usize);
            let [a, b, c] = topo.triangles[t];
            let verts = [v as u32, a, b, c];
            keep(1, verts, overlap(&vb[v], &tri_boxes[t]), (key, gap))
        };
        let edge_edge = |&(key, gap): &(u64, f64)| {
            let (e, f) = ((key >> 32) as usize, key as u32 as usize);
            let ([a, b], [c, d]) = (topo.edges[e], topo.edges[f]);
            keep(
                2,
                [a, b, c, d],
                overlap(&edge_boxes[e], &edge_boxes[f]),
                (key, gap),
            )
        };
        for (out, wide, filter) in [
            (
                &mut vt,
                &self.wide_vt,
                &vertex_triangle as &(dyn Fn(&(u64, f64)) -> _ + Sync),
            ),
            (&mut ee, &self.wide_ee, &edge_edge),
        ] {
            out.clear();
            parts.filter_map_into(wide, 1024, |_, c| filter(c), out);
        }
        let mut looked = Looked {
            boxes: 0,
            candidates: (vt.len() + ee.len()) as u64,
        };
        if let Some(outside) = outside {
            looked = looked.and(self.find_touching(&tests, outside, &mut more_vt, &mut more_ee));
            vt.extend_from_slice(&more_vt);
            ee.extend_from_slice(&more_ee);
        }
        self.keyed_parts = parts;
        self.take_found(topo, x, Order::Index, reuse, (&vt, &ee), out);
        (self.candidate_vt, self.candidate_ee) = (vt, ee);
        (self.outside_vt, self.outside_ee) = (more_vt, more_ee);
        looked
    }

    /// The tests of a swept search at `x` ([`Broad::search`]'s `base`, `eps`, `margin` and
    /// `order`) on the sides of the last [`Broad::fit_sides`], and, when `tight`, the tight
    /// boxes of the last [`Broad::fit_tight`] (else each pair's own, the same to the bit).
    fn swept_tests<'a>(
        &'a self,
        topo: &'a Topology,
        x: &'a Vec3s,
        (base, eps, margin): (f64, f64, f64),
        order: Order,
        (tight, keep_gap): (bool, bool),
    ) -> PairTests<'a, impl Fn([u32; 4], usize, f64, f64) -> Option<f64> + Sync> {
        PairTests {
            topo,
            x,
            limit: Limit::Sides {
                base,
                vert: &self.vert_side,
                tri: &self.tri_side,
                edge: &self.edge_side,
                eps,
            },
            margin,
            order,
            tri_rank: &self.tri_rank,
            tight: tight.then_some((&self.tight_tris[..], &self.tight_edges[..])),
            measure: move |_: [u32; 4], _: usize, most: f64, gap: f64| {
                Some(if keep_gap { gap } else { most })
            },
        }
    }

    /// Each vertex's side for a search, the most `reach` of it (m, by particle; zero for a
    /// particle in no triangle), and each triangle's and edge's, the most of its vertices'.
    fn fit_sides(&mut self, topo: &Topology, reach: impl Fn(u32) -> f64 + Sync) {
        per_surface_vertex(&mut self.vert_side, &topo.in_mesh, |v| {
            0.0f64.max(reach(v as u32))
        });
        let vb = &self.vert_side;
        let side = |vs: &[u32]| vs.iter().map(|&v| vb[v as usize]).fold(0.0, f64::max);
        per_primitive(topo, &mut self.tri_side, &mut self.edge_side, side);
    }

    /// Into `out`, in key order, the pairs of `found` (the vertex-triangle and the edge-edge
    /// candidates, each under its key with its limit) closer than their limit at `x`, with
    /// their closest points there, kept or taken over as `reuse` says.
    fn take_found(
        &mut self,
        topo: &Topology,
        x: &Vec3s,
        order: Order,
        reuse: Reuse,
        (vt, ee): (&[Keyed], &[Keyed]),
        out: &mut Vec<Pair>,
    ) {
        out.clear();
        let keep = matches!(reuse, Reuse::Keep);
        let take = matches!(reuse, Reuse::Take) && self.kept_for == Some(order);
        // What this search keeps; what was kept stays where it is to be taken over.
        let mut keeping = Vec::new();
        if keep {
            self.kept_keys.clear();
            keeping = std::mem::take(&mut self.kept_pairs);
            keeping.clear();
            self.kept_for = Some(order);
        }
        let mut sorted = std::mem::take(&mut self.sorted_candidates);
        let mut parts = std::mem::take(&mut self.pair_parts);
        for (split, found, buckets) in [(1, vt, topo.same.len()), (2, ee, topo.edges.len())] {
            sorted.clear();
            let (starts, cursor) = (&mut self.starts, &mut self.cursor);
            in_key_order(found.iter().copied(), buckets, starts, cursor, &mut sorted);
            let by_rank = &self.by_rank;
            let (kept, kept_pairs) = (&self.kept_keys, &self.kept_pairs);
            let (kept_split, kept_starts) = (self.kept_split, &self.kept_starts[split - 1]);
            let taken_over = |key: u64| -> Option<Pair> {
                if !take {
                    return None;
                }
                let first = (key >> 32) as usize;
                let offset = if split == 1 { 0 } else { kept_split };
                let range = offset + *kept_starts.get(first)? as usize
                    ..offset + *kept_starts.get(first + 1)? as usize;
                let k = kept[range.clone()].binary_search(&key).ok()?;
                Some(kept_pairs[range.start + k])
            };
            let closest = |&(key, _): &(u64, f64)| {
                taken_over(key).unwrap_or_else(|| {
                    let (first, second) = ((key >> 32) as usize, key as u32 as usize);
                    if split == 1 {
                        let t = match order {
                            Order::Index => second,
                            Order::Vertices => by_rank[second] as usize,
                        };
                        let [a, b, c] = topo.triangles[t];
                        vertex_triangle(x, [first as u32, a, b, c])
                    } else {
                        let ([a, b], [c, d]) = (topo.edges[first], topo.edges[second]);
                        edge_edge(x, [a, b, c, d])
                    }
                })
            };
            if keep {
                // Every candidate's closest points are kept, the pairs found and the ones too
                // far apart alike: a later search with other boxes and limits finds many of
                // the latter.
                let before = keeping.len();
                keeping.par_extend(sorted.par_iter().with_min_len(256).map(closest));
                self.kept_keys.extend(sorted.iter().map(|&(key, _)| key));
                let near = keeping[before..].iter().zip(&sorted);
                out.extend(near.filter(|(p, c)| p.d0 < c.1).map(|(p, _)| *p));
                // Where each vertex's or edge's kept pairs start.
                let starts = &mut self.kept_starts[split - 1];
                starts.clear();
                starts.resize(buckets + 1, 0);
                for &(key, _) in sorted.iter() {
                    starts[(key >> 32) as usize + 1] += 1;
                }
                for b in 0..buckets {
                    starts[b + 1] += starts[b];
                }
                if split == 1 {
                    self.kept_split = self.kept_keys.len();
                }
            } else {
                let near = |c: &(u64, f64)| Some(closest(c)).filter(|p| p.d0 < c.1);
                parts.filter_map_into(&sorted, 256, |_, c| near(c), out);
            }
        }
        if keep {
            self.kept_pairs = keeping;
        }
        self.sorted_candidates = sorted;
        self.pair_parts = parts;
    }

    /// Forgets the candidates a search kept: they are not to be taken over.
    pub fn forget_kept(&mut self) {
        self.kept_for = None;
        self.kept_keys.clear();
        self.kept_pairs.clear();
        self.kept_split = 0;
        self.kept_starts.iter_mut().for_each(Vec::clear);
    }

    /// For the pair list: every pair whose boxes overlap and which is closer than `reach` at
    /// `x`, as [`Broad::search`] with [`Order::Vertices`] finds them, but with its distance
    /// alone; [`Broad::near_found`] then gives them in that order. With `moved` (one flag a
    /// particle), only those of them with a moved vertex: each primitive through a moved vertex
    /// is looked up in the other tree alone, so the cost is that of the moved vertices'
    /// neighbourhoods, not of the mesh.
    pub fn search_near(
        &mut self,
        topo: &Topology,
        vertex_boxes: &[Aabb],
        x: &Vec3s,
        reach: f64,
        margin: f64,
        moved: Option<&[bool]>,
    ) -> Looked {
        self.fit(topo, vertex_boxes);
        // A query of a few vertices looks at their neighbourhoods alone: the boxes of the whole
        // mesh would cost more than they save.
        if moved.is_none() {
            self.fit_tight(topo, x);
        }
        let measure = |verts: [u32; 4], split: usize, most: f64, _gap: f64| {
            let d = distance(x, verts, split);
            (d < most).then_some(d)
        };
        let (mut vt, mut ee) = (
            std::mem::take(&mut self.near_vertex_triangles),
            std::mem::take(&mut self.near_edge_edges),
        );
        let tests = PairTests {
            topo,
            x,
            limit: Limit::Fixed(reach),
            margin,
            order: Order::Vertices,
            tri_rank: &self.tri_rank,
            tight: moved
                .is_none()
                .then_some((&self.tight_tris[..], &self.tight_edges[..])),
            measure,
        };
        let mut walks = std::mem::take(&mut self.walks);
        let looked = match moved {
            None => self.find(&tests, &mut vt, &mut ee, &mut walks),
            Some(moved) => self.find_touching(&tests, moved, &mut vt, &mut ee),
        };
        self.walks = walks;
        // Sorted with their distances, as small as where each is, so that the list reads them
        // in order.
        let (starts, cursor, sorted) = (&mut self.starts, &mut self.cursor, &mut self.sorted_near);
        sorted.clear();
        in_key_order(vt.iter().copied(), topo.same.len(), starts, cursor, sorted);
        in_key_order(ee.iter().copied(), topo.edges.len(), starts, cursor, sorted);
        self.near_split = vt.len();
        (self.near_vertex_triangles, self.near_edge_edges) = (vt, ee);
        looked
    }

    /// The pairs the last [`Broad::search_near`] found, each with its distance, in the order of
    /// their keys ([`Candidate::key`]): the vertex-triangle pairs, then the edge-edge pairs.
    pub fn near_found<'a>(
        &'a self,
        topo: &'a Topology,
    ) -> impl Iterator<Item = (Candidate, f64)> + 'a {
        let (split, by_rank) = (self.near_split, &self.by_rank);
        self.sorted_near
            .iter()
            .enumerate()
            .map(move |(i, &(key, d))| {
                let (first, second) = ((key >> 32) as usize, key as u32 as usize);
                if i < split {
                    let [a, b, c] = topo.triangles[by_rank[second] as usize];
                    let verts = [first as u32, a, b, c];
                    (Candidate { verts, split: 1 }, d)
                } else {
                    let ([a, b], [c, d_]) = (topo.edges[first], topo.edges[second]);
                    let verts = [a, b, c, d_];
                    (Candidate { verts, split: 2 }, d)
                }
            })
    }

    /// Into `into`, the keys of the pairs the last [`Broad::search_near`] found, for
    /// [`Broad::search_listed`].
    pub fn near_keys(&self, into: &mut NearKeys) {
        into.keys.clear();
        into.keys
            .extend(self.sorted_near.iter().map(|&(key, _)| key));
        into.split = self.near_split;
    }

    /// Refits the trees to `vertex_boxes` (each vertex's box), shaping them first for a new
    /// topology.
    fn fit(&mut self, topo: &Topology, vertex_boxes: &[Aabb]) {
        let vb = vertex_boxes;
        let boxes = |vs: &[u32]| union(vb, vs);
        per_primitive(topo, &mut self.tri_boxes, &mut self.edge_boxes, boxes);
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
            self.by_rank = by_vertices;
            self.shaped_for = topo.version;
        } else {
            self.vert_tree.refit(&self.vert_boxes);
            self.tri_tree.refit(&self.tri_boxes);
            self.edge_tree.refit(&self.edge_boxes);
        }
    }

    /// Each triangle's and edge's tight box at `x`.
    pub fn fit_tight(&mut self, topo: &Topology, x: &Vec3s) {
        let tight = |vs: &[u32]| {
            let (lo, hi) = bounds(x, vs);
            Aabb { min: lo, max: hi }
        };
        per_primitive(topo, &mut self.tight_tris, &mut self.tight_edges, tight);
    }

    /// Into `vt` and `ee`, in an order fixed by the trees: every vertex-triangle and edge-edge
    /// pair whose boxes overlap and which passes `tests`.
    fn find(
        &self,
        tests: &PairTests<impl Fn([u32; 4], usize, f64, f64) -> Option<f64> + Sync>,
        vt: &mut Vec<Keyed>,
        ee: &mut Vec<Keyed>,
        [walk_vt, walk_ee]: &mut [WalkScratch<Keyed>; 2],
    ) -> Looked {
        let vertex_triangle_pair = |k, t, out: &mut _| tests.vertex_triangle(k, t, out);
        let tri_tree = Some(&self.tri_tree);
        let (boxes, candidates) =
            self.vert_tree
                .overlapping_pairs(tri_tree, vertex_triangle_pair, vt, walk_vt);
        let edge_edge_pair = |e, f, out: &mut _| tests.edge_edge(e, f, out);
        let more = self
            .edge_tree
            .overlapping_pairs(None, edge_edge_pair, ee, walk_ee);
        Looked { boxes, candidates }.and(Looked {
            boxes: more.0,
            candidates: more.1,
        })
    }

    /// What [`Broad::find`] finds with `tests`, of the pairs with a vertex `moved`, each once:
    /// a moved vertex against the triangles, a triangle through a moved vertex against the
    /// vertices not moved (the moved ones found it already), and an edge through a moved
    /// vertex against the edges, a pair of two such edges taken from its first. Each lookup is
    /// the walk's own box test, so the pairs are the walk's; their order is the trees', and the
    /// caller sorts them by key.
    fn find_touching<R: Send>(
        &self,
        tests: &PairTests<impl Fn([u32; 4], usize, f64, f64) -> Option<R> + Sync>,
        moved: &[bool],
        vt: &mut Vec<(u64, R)>,
        ee: &mut Vec<(u64, R)>,
    ) -> Looked {
        let topo = tests.topo;
        let touches = |verts: &[u32]| verts.iter().any(|&v| moved[v as usize]);
        let mut looked = Looked::default();
        vt.clear();
        ee.clear();
        for (k, &v) in topo.vertices.iter().enumerate() {
            if moved[v as usize] {
                let mut found = 0;
                looked.boxes += self.tri_tree.overlapping(&self.vert_boxes[k], |t| {
                    found += tests.vertex_triangle(k as u32, t, vt) as u64;
                });
                looked.candidates += found;
            }
        }
        for (t, tri) in topo.triangles.iter().enumerate() {
            if touches(tri) {
                let mut found = 0;
                looked.boxes += self.vert_tree.overlapping(&self.tri_boxes[t], |k| {
                    if !moved[topo.vertices[k as usize] as usize] {
                        found += tests.vertex_triangle(k, t as u32, vt) as u64;
                    }
                });
                looked.candidates += found;
            }
        }
        for (e, edge) in topo.edges.iter().enumerate() {
            if touches(edge) {
                let e = e as u32;
                let mut found = 0;
                looked.boxes += self
                    .edge_tree
                    .overlapping(&self.edge_boxes[e as usize], |f| {
                        let first = f > e || !touches(&topo.edges[f as usize]);
                        if f != e && first {
                            found += tests.edge_edge(e, f, ee) as u64;
                        }
                    });
                looked.candidates += found;
            }
        }
        looked
    }

    pub fn heap_bytes(&self) -> usize {
        (self.tri_boxes.capacity() + self.edge_boxes.capacity()) * size_of::<Aabb>()
            + self.vert_boxes.capacity() * size_of::<Aabb>()
            + (self.candidate_vt.capacity() + self.candidate_ee.capacity()) * 16
            + self.sorted_candidates.capacity() * 16
            + (self.wide_vt.capacity() + self.wide_ee.capacity()) * 16
            + (self.outside_vt.capacity() + self.outside_ee.capacity()) * 16
            + self.kept_keys.capacity() * 8
            + self.kept_pairs.capacity() * size_of::<Pair>()
            + (self.kept_starts[0].capacity() + self.kept_starts[1].capacity()) * 4
            + (self.near_vertex_triangles.capacity() + self.near_edge_edges.capacity()) * 16
            + self.sorted_near.capacity() * 16
            + (self.starts.capacity() + self.cursor.capacity()) * 4
            + (self.tri_rank.capacity() + self.by_rank.capacity()) * 4
            + self.vert_tree.heap_bytes()
            + self.tri_tree.heap_bytes()
            + self.edge_tree.heap_bytes()
            + self
                .walks
                .iter()
                .map(WalkScratch::heap_bytes)
                .sum::<usize>()
            + self.keyed_parts.heap_bytes()
            + self.pair_parts.heap_bytes()
            + (self.tight_tris.capacity() + self.tight_edges.capacity()) * size_of::<Aabb>()
            + (self.vert_side.capacity() + self.tri_side.capacity() + self.edge_side.capacity()) * 8
    }
}

/// What makes a pair whose boxes overlap one a search finds: neither primitive through the
/// other's vertices (or a vertex sewn to one), and its `measure` (its distance at `x` and what
/// is kept of it) below its `limit`. A pair's tight boxes at `x` pass over it first when they
/// are farther apart than `limit` and `margin`. Each found pair goes under its key (as `order`
/// says for the vertex-triangle pairs).
struct PairTests<'a, M> {
    topo: &'a Topology,
    x: &'a Vec3s,
    limit: Limit<'a>,
    margin: f64,
    order: Order,
    tri_rank: &'a [u32],
    /// The triangles' and edges' tight boxes at `x`, where the search took them.
    tight: Option<(&'a [Aabb], &'a [Aabb])>,
    measure: M,
}

impl<M, R> PairTests<'_, M>
where
    M: Fn([u32; 4], usize, f64, f64) -> Option<R> + Sync,
{
    /// The pair `verts` split at `split`, of primitives `first` and `second` (a vertex, by
    /// particle, and a triangle, or two edges), kept under `key` when close enough.
    #[inline]
    fn keep_close(
        &self,
        verts: [u32; 4],
        split: usize,
        primitives: (u32, u32),
        key: u64,
        out: &mut Vec<(u64, R)>,
    ) {
        if let Some(kept) = self.close(verts, split, primitives) {
            out.push((key, kept));
        }
    }

    /// What is kept of the pair of [`PairTests::keep_close`] when it is close enough.
    #[inline]
    fn close(&self, verts: [u32; 4], split: usize, primitives: (u32, u32)) -> Option<R> {
        self.close_at(verts, split, primitives, self.gap(verts, split, primitives))
    }

    /// [`PairTests::close`] given the pair's `gap`, the distance of its tight boxes at `x` (as
    /// [`PairTests::gap`] takes it).
    #[inline]
    fn close_at(
        &self,
        verts: [u32; 4],
        split: usize,
        (first, second): (u32, u32),
        gap: f64,
    ) -> Option<R> {
        let most = match self.limit {
            Limit::Fixed(most) => most,
            Limit::Sides {
                base,
                vert,
                tri,
                edge,
                eps,
            } => {
                let (a, b) = match split {
                    1 => (vert[first as usize], tri[second as usize]),
                    _ => (edge[first as usize], edge[second as usize]),
                };
                base + a + b + eps
            }
        };
        if gap <= most + self.margin {
            (self.measure)(verts, split, most, gap)
        } else {
            None
        }
    }

    /// The distance between the pair's primitives' tight boxes at `x` (m).
    #[inline]
    fn gap(&self, verts: [u32; 4], split: usize, (first, second): (u32, u32)) -> f64 {
        match self.tight {
            Some((tris, edges)) => {
                let (a, b) = match split {
                    1 => {
                        let p = self.x.get(first as usize);
                        let t = &tris[second as usize];
                        ((p, p), (t.min, t.max))
                    }
                    _ => {
                        let (e, f) = (&edges[first as usize], &edges[second as usize]);
                        ((e.min, e.max), (f.min, f.max))
                    }
                };
                boxes_apart(a, b)
            }
            None => apart(self.x, &verts, split),
        }
    }

    /// The mesh's `k`-th vertex against triangle `t`; false if they are neighbours.
    #[inline(always)]
    fn vertex_triangle(&self, k: u32, t: u32, out: &mut Vec<(u64, R)>) -> bool {
        let topo = self.topo;
        let v = topo.vertices[k as usize];
        let [a, b, c] = topo.triangles[t as usize];
        if topo.joined(v, a) || topo.joined(v, b) || topo.joined(v, c) {
            return false;
        }
        let place = match self.order {
            Order::Index => t,
            Order::Vertices => self.tri_rank[t as usize],
        };
        let key = (v as u64) << 32 | place as u64;
        self.keep_close([v, a, b, c], 1, (v, t), key, out);
        true
    }

    /// Edges `e` and `f` (either order); false if they are neighbours.
    #[inline(always)]
    fn edge_edge(&self, e: u32, f: u32, out: &mut Vec<(u64, R)>) -> bool {
        let topo = self.topo;
        let (e, f) = (e.min(f), e.max(f));
        let ([a, b], [c, d]) = (topo.edges[e as usize], topo.edges[f as usize]);
        let joined = |p: u32| topo.joined(p, c) || topo.joined(p, d);
        if joined(a) || joined(b) {
            return false;
        }
        let key = (e as u64) << 32 | f as u64;
        self.keep_close([a, b, c, d], 2, (e, f), key, out);
        true
    }
}

/// Appends `items`, each under its key, to `out` in key order: an order of the pairs alone,
/// whatever the trees' shape or the thread count. A counting sort by the key's first vertex or
/// edge (one of `buckets`, counted in `starts` and placed by `cursor`), then each bucket sorted:
/// the keys are distinct, so the order is exact, and a bucket holds a vertex's or an edge's few
/// dozen pairs.
fn in_key_order<T: Copy + Default + Send>(
    items: impl Iterator<Item = (u64, T)> + Clone,
    buckets: usize,
    starts: &mut Vec<u32>,
    cursor: &mut Vec<u32>,
    out: &mut Vec<(u64, T)>,
) {
    let bucket = |key: u64| (key >> 32) as usize;
    starts.clear();
    starts.resize(buckets + 1, 0);
    for (key, _) in items.clone() {
        starts[bucket(key) + 1] += 1;
    }
    for b in 0..buckets {
        starts[b + 1] += starts[b];
    }
    cursor.clear();
    cursor.extend_from_slice(&starts[..buckets]);
    let first = out.len();
    out.resize(first + starts[buckets] as usize, Default::default());
    let placed = &mut out[first..];
    for item in items {
        let at = &mut cursor[bucket(item.0)];
        placed[*at as usize] = item;
        *at += 1;
    }
    placed
        .par_chunk_by_mut(|p, q| bucket(p.0) == bucket(q.0))
        .for_each(|b| b.sort_unstable_by_key(|p| p.0));
}

/// The distance between the boxes of `verts[..split]` and `verts[split..]` at `x` (m), a lower
/// bound of the distance between the primitives, each inside its box: cheaper than their
/// closest points, and enough to pass over the neighbours a box test lets through in a flat
/// cloth (two parallel edges a grid spacing apart).
#[inline]
fn apart(x: &Vec3s, verts: &[u32; 4], split: usize) -> f64 {
    boxes_apart(bounds(x, &verts[..split]), bounds(x, &verts[split..]))
}

/// The tight box of `vertices` at `x`.
#[inline]
fn bounds(x: &Vec3s, vertices: &[u32]) -> (Vec3, Vec3) {
    let first = x.get(vertices[0] as usize);
    vertices[1..].iter().fold((first, first), |(lo, hi), &v| {
        let p = x.get(v as usize);
        (lo.min(p), hi.max(p))
    })
}

/// The distance between the boxes `(lo_a, hi_a)` and `(lo_b, hi_b)` (m).
#[inline]
fn boxes_apart((lo_a, hi_a): (Vec3, Vec3), (lo_b, hi_b): (Vec3, Vec3)) -> f64 {
    // Per axis, the gap between the two intervals (zero where they overlap), exact in f64.
    let gap = (lo_b.as_dvec3() - hi_a.as_dvec3())
        .max(lo_a.as_dvec3() - hi_b.as_dvec3())
        .max(glam::DVec3::ZERO);
    gap.length()
}

/// Into `tris` and `edges`, in order: `per` of each triangle's and each edge's vertices.
fn per_primitive<T: Send>(
    topo: &Topology,
    tris: &mut Vec<T>,
    edges: &mut Vec<T>,
    per: impl Fn(&[u32]) -> T + Sync,
) {
    tris.clear();
    tris.par_extend(topo.triangles.par_iter().map(|t| per(t)));
    edges.clear();
    edges.par_extend(topo.edges.par_iter().map(|e| per(e)));
}

/// Whether the closed boxes `a` and `b` overlap, as the trees' leaves test them (touching
/// counts).
#[inline]
fn overlap(a: &Aabb, b: &Aabb) -> bool {
    a.min.cmple(b.max).all() && a.max.cmpge(b.min).all()
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
    /// orders must hold the same pairs, and so must the list's own search, which keeps less of
    /// each.
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
        let limit = (0.004, |_| 0.0, 0.0);
        for (order, out) in [
            (Order::Index, &mut by_index),
            (Order::Vertices, &mut by_vertices),
        ] {
            broad.search(&topo, &boxes, &x, limit, 0.0, order, Reuse::Nothing, out);
        }
        assert!(by_vertices.len() > 20, "{}", by_vertices.len());
        assert!(by_vertices.windows(2).all(|w| key(&w[0]) < key(&w[1])));
        assert!(by_index.windows(2).any(|w| key(&w[0]) > key(&w[1])));
        by_index.sort_unstable_by_key(key);
        assert!(by_index
            .iter()
            .zip(&by_vertices)
            .all(|(p, q)| key(p) == key(q)));
        assert_eq!(by_index.len(), by_vertices.len());
        // The pair list's search keeps a pair's distance alone, and must find the same pairs,
        // in the same order, with the same distances to the bit.
        let mut near = Broad::default();
        near.search_near(&topo, &boxes, &x, 0.004, 0.0, None);
        let found: Vec<(Candidate, f64)> = near.near_found(&topo).collect();
        assert_eq!(found.len(), by_vertices.len());
        for ((c, d), p) in found.iter().zip(&by_vertices) {
            assert_eq!(*c, p.candidate());
            assert_eq!(d.to_bits(), p.d0.to_bits());
        }
        assert!(
            found.iter().any(|(c, _)| c.split == 2),
            "no edge-edge pair to test"
        );
    }

    /// The pass after an implicit solve searches from the step's start, where the search ahead
    /// of the solve looked at its candidates with other boxes, and takes over the closest
    /// points of the candidates both look at. It must find the same pairs, in the same order,
    /// with the same closest points to the bit, as a search that takes over nothing.
    #[test]
    fn a_search_taking_over_anothers_pairs_finds_what_it_finds_alone_to_the_bit() {
        // Two crumpled layers of a 6 x 6 grid 1.5 mm apart.
        let at = |k: usize| {
            let (layer, i, j) = (k / 36, k % 6, (k / 6) % 6);
            let wave = 0.0007 * ((i * 7 + j * 3 + layer) as f32).sin();
            Vec3::new(
                0.01 * i as f32,
                0.01 * j as f32,
                0.0015 * layer as f32 + wave,
            )
        };
        let x = Vec3s::from_fn(72, at);
        let mut triangles = Vec::new();
        for layer in [0, 36] {
            for j in 0..5 {
                for i in 0..5 {
                    let v = layer + 6 * j + i;
                    triangles.push([v, v + 1, v + 7]);
                    triangles.push([v, v + 7, v + 6]);
                }
            }
        }
        let mut topo = Topology::default();
        topo.rebuild(0, 72, triangles);
        // Each vertex moves its own way, differently in the two searches.
        let boxes = |turn: f32| -> Vec<Aabb> {
            (0..72)
                .map(|v| {
                    let p = x.get(v);
                    let q = p + 0.002 * Vec3::new((v as f32 + turn).sin(), turn.cos(), 0.3);
                    Aabb {
                        min: p.min(q) - Vec3::splat(0.001),
                        max: p.max(q) + Vec3::splat(0.001),
                    }
                })
                .collect()
        };
        let reach = |turn: f32| move |v: u32| 0.001 + 0.002 * (v as f64 + turn as f64).cos().abs();
        let (ahead_boxes, pass_boxes) = (boxes(0.0), boxes(1.3));
        let (mut broad, mut fresh) = (Broad::default(), Broad::default());
        let (mut ahead, mut taken, mut alone) = (Vec::new(), Vec::new(), Vec::new());
        let search = |broad: &mut Broad, boxes: &[Aabb], turn, reuse, out: &mut Vec<Pair>| {
            let limit = (0.002, reach(turn), 1e-9);
            broad.search(&topo, boxes, &x, limit, 1e-12, Order::Index, reuse, out);
        };
        search(&mut broad, &ahead_boxes, 0.0, Reuse::Keep, &mut ahead);
        search(&mut broad, &pass_boxes, 1.3, Reuse::Take, &mut taken);
        search(&mut fresh, &pass_boxes, 1.3, Reuse::Nothing, &mut alone);
        let bits = |p: &Pair| {
            let (c, n) = (p.c.map(f64::to_bits), p.n.to_array().map(f64::to_bits));
            (p.verts, p.split, c, n, p.d0.to_bits())
        };
        assert_eq!(taken.len(), alone.len());
        assert!(taken.iter().zip(&alone).all(|(p, q)| bits(p) == bits(q)));
        // Both kinds of pair are taken over, and some pairs are new to the second search.
        let before: Vec<_> = ahead.iter().map(|p| p.candidate().key()).collect();
        let shared = |split: usize| {
            alone
                .iter()
                .filter(|p| p.split == split && before.contains(&p.candidate().key()))
                .count()
        };
        assert!(
            shared(1) > 5 && shared(2) > 5,
            "{} {}",
            shared(1),
            shared(2)
        );
        assert!(
            alone.len() > shared(1) + shared(2),
            "no pair new to the second search"
        );
    }
}
