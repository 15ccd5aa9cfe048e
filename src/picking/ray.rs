//! Ray queries against the cloth: particles (a small box around each) and triangles, each
//! through a parry3d [`Bvh`], each with a brute-force scan that gives the same answer.
//!
//! Both trees are keyed by stable ids (the particle index; for triangles `2 * cell + half`, see
//! [`cell_triangle`]), so a cut removes leaves instead of renumbering them, and a moved cloth
//! updates the leaf boxes and refits the tree (`O(n)`) instead of rebuilding it (`O(n log n)`).
//!
//! **Exactness.** The BVH answer is bit-for-bit the brute-force answer. Both use the same
//! leaf test and the same total order of hits (distance along the ray, then distance from the
//! ray to the particle, then index), and the traversal only prunes a node whose entry distance
//! is *strictly* greater than the best hit so far. The ray-box test ([`ray_aabb`]) is monotone
//! in the box bounds, so a node's entry distance is never greater than that of a leaf it
//! contains, in floating point as well as in exact arithmetic.
//!
//! For triangles the leaf test is Moeller-Trumbore, whose rounding can report a hit where the
//! ray does not pass (a ray from far away: it works with `origin - a`; a sliver triangle), so
//! [`ray_triangle`] accepts a hit only where the ray also enters the triangle's box, widened
//! for that rounding, no farther than the hit's *reach* (its distance plus a relative
//! allowance). Every box the searches test contains the widened boxes of its triangles, so a
//! box that starts beyond the best hit's reach holds no better hit, by construction rather
//! than by an estimate of the rounding. Without that rule a ray from 10 km away disagrees with
//! the brute force in a few percent of picks (tests/fuzz.rs checks it does not).

use std::cmp::Ordering;

use glam::Vec3;
use parry3d::partitioning::{Bvh, TraversalAction};

use crate::grid::{cell_triangle, triangle_alive, Grid};
pub use crate::ray::{ray_aabb, Ray};
use crate::soa::Vec3s;

/// A particle hit by a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleHit {
    pub index: usize,
    /// Distance along the ray to the particle's box, in m (0 if the ray starts inside it).
    pub distance: f32,
    /// Distance from the ray's line to the particle, in m: breaks ties in `distance`.
    pub offset: f32,
}

impl ParticleHit {
    /// The order in which hits win: nearer along the ray, then nearer to the ray, then the
    /// lower index. Total, so the winner does not depend on the order of the scan.
    pub fn cmp_key(&self, other: &ParticleHit) -> Ordering {
        self.distance
            .total_cmp(&other.distance)
            .then(self.offset.total_cmp(&other.offset))
            .then(self.index.cmp(&other.index))
    }
}

pub(super) fn particle_box(p: Vec3, radius: f32) -> (Vec3, Vec3) {
    (p - Vec3::splat(radius), p + Vec3::splat(radius))
}

/// The ray against particle `index` at `p`, a box of half-size `radius`.
#[inline]
pub fn hit_particle(ray: &Ray, index: usize, p: Vec3, radius: f32) -> Option<ParticleHit> {
    let (lo, hi) = particle_box(p, radius);
    let distance = ray_aabb(ray, lo, hi)?;
    Some(ParticleHit {
        index,
        distance,
        offset: (p - ray.origin).cross(ray.dir).length(),
    })
}

/// The winning particle by testing every live one, one at a time: the readable reference.
pub fn pick_particle_brute_force(
    ray: &Ray,
    pos: &Vec3s,
    alive: &[bool],
    radius: f32,
) -> Option<ParticleHit> {
    (0..pos.len())
        .filter(|&p| alive[p])
        .filter_map(|p| hit_particle(ray, p, pos.get(p), radius))
        .min_by(ParticleHit::cmp_key)
}

/// Particles per block of [`pick_particle_scan`]: consecutive indices, so a piece of a grid
/// row, close together on the cloth.
const SCAN_BLOCK: usize = 64;

/// [`pick_particle_brute_force`] without a tree, at about the cost of reading each position
/// once: one vectorised pass bounds each block of [`SCAN_BLOCK`] consecutive particles; blocks
/// are visited nearest first, testing their particles, until the next block starts farther
/// than the best hit. A block's box (its bounds widened by the radius) contains its particles'
/// boxes, and [`ray_aabb`] is monotone, so the answer is the brute force's, bit for bit. The
/// cheapest exact answer for one query on a cloth that has just moved: a refit reads every
/// position too, and then rewrites the tree.
pub fn pick_particle_scan(
    ray: &Ray,
    pos: &Vec3s,
    alive: &[bool],
    radius: f32,
) -> Option<ParticleHit> {
    let n = pos.len();
    let r = Vec3::splat(radius);
    let mut blocks: Vec<(f32, usize)> = (0..n.div_ceil(SCAN_BLOCK))
        .filter_map(|b| {
            let range = b * SCAN_BLOCK..((b + 1) * SCAN_BLOCK).min(n);
            let (x, y, z) = (
                min_max(&pos.x[range.clone()]),
                min_max(&pos.y[range.clone()]),
                min_max(&pos.z[range]),
            );
            let (lo, hi) = (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1));
            Some((ray_aabb(ray, lo - r, hi + r)?, b))
        })
        .collect();
    blocks.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut best: Option<ParticleHit> = None;
    for (enter, b) in blocks {
        if best.is_some_and(|h| enter > h.distance) {
            break;
        }
        let block = b * SCAN_BLOCK..((b + 1) * SCAN_BLOCK).min(n);
        for p in block.filter(|&p| alive[p]) {
            if let Some(hit) = hit_particle(ray, p, pos.get(p), radius) {
                if best.is_none_or(|h| hit.cmp_key(&h) == Ordering::Less) {
                    best = Some(hit);
                }
            }
        }
    }
    best
}

/// The ray against triangle `(a, b, c)` (Moeller-Trumbore, both sides): the distance along the
/// ray and the barycentric weights of `a`, `b`, `c` at the hit. A hit counts only if the ray
/// enters the triangle's [`triangle_bounds`], widened by [`triangle_query_margin`], no farther
/// than [`triangle_reach`] of its distance: what keeps the searches exact (module docs).
#[inline]
pub fn ray_triangle(ray: &Ray, a: Vec3, b: Vec3, c: Vec3) -> Option<(f32, [f32; 3])> {
    let (t, weights) = moller_trumbore(ray, a, b, c)?;
    let (lo, hi) = triangle_bounds(a, b, c);
    let widen = Vec3::splat(triangle_query_margin(ray));
    let enter = ray_aabb(ray, lo - widen, hi + widen)?;
    (enter <= triangle_reach(t)).then_some((t, weights))
}

#[inline]
fn moller_trumbore(ray: &Ray, a: Vec3, b: Vec3, c: Vec3) -> Option<(f32, [f32; 3])> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = ray.dir.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None; // the ray runs parallel to the triangle, or the triangle is degenerate
    }
    let inv = 1.0 / det;
    let tv = ray.origin - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = ray.dir.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t >= 0.0 && t.is_finite()).then_some((t, [1.0 - u - v, u, v]))
}

/// What the BVH search needs of a hit: how far along the ray a box may start and still hold a
/// hit that beats it (monotone in the distance), and a total order.
pub(super) trait Hit: Copy {
    fn reach(&self) -> f32;
    fn cmp_key(&self, other: &Self) -> Ordering;
}

impl Hit for ParticleHit {
    /// The distance itself: a particle's hit distance is its box's entry distance, and
    /// [`ray_aabb`] is monotone in the bounds.
    fn reach(&self) -> f32 {
        self.distance
    }

    fn cmp_key(&self, other: &Self) -> Ordering {
        ParticleHit::cmp_key(self, other)
    }
}

impl Hit for TriangleHit {
    fn reach(&self) -> f32 {
        triangle_reach(self.distance)
    }

    fn cmp_key(&self, other: &Self) -> Ordering {
        TriangleHit::cmp_key(self, other)
    }
}

/// The winning hit among the leaves `leaf_hit` reports, visiting only nodes whose box, widened
/// by `widen` on every side, the ray enters no farther than the best hit's reach.
pub(super) fn nearest_hit<H: Hit>(
    bvh: &Bvh,
    ray: &Ray,
    widen: f32,
    leaf_hit: impl Fn(u32) -> Option<H>,
) -> Option<H> {
    let widen = Vec3::splat(widen);
    let mut best: Option<H> = None;
    bvh.traverse(|node| {
        if let Some(leaf) = node.leaf_data() {
            if let Some(hit) = leaf_hit(leaf) {
                if best.is_none_or(|b| hit.cmp_key(&b) == Ordering::Less) {
                    best = Some(hit);
                }
            }
            return TraversalAction::Continue;
        }
        match ray_aabb(ray, node.mins() - widen, node.maxs() + widen) {
            Some(t) if best.is_none_or(|b| t <= b.reach()) => TraversalAction::Continue,
            _ => TraversalAction::Prune,
        }
    });
    best
}

/// A triangle hit by a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Position in the list of triangles searched (for the BVH: the stable id).
    pub index: usize,
    /// Distance along the ray, in m.
    pub distance: f32,
    /// Weights of the triangle's three vertices, in the triangle's order; they sum to 1.
    pub barycentric: [f32; 3],
}

/// Relative rounding allowed for in [`ray_triangle`]'s distances, far above float32's (6e-8).
const TRIANGLE_ROUNDING: f32 = 1e-5;

/// The farthest a ray may enter a triangle's widened box and still count a hit at distance
/// `t`: `t` plus [`TRIANGLE_ROUNDING`] of it. Monotone in `t`.
#[inline]
fn triangle_reach(t: f32) -> f32 {
    t + TRIANGLE_ROUNDING * (1.0 + t)
}

impl TriangleHit {
    fn cmp_key(&self, other: &TriangleHit) -> Ordering {
        self.distance
            .total_cmp(&other.distance)
            .then(self.index.cmp(&other.index))
    }
}

/// The nearest triangle of `triangles` by testing each: the reference for the triangle BVH.
pub fn pick_triangle_brute_force(
    ray: &Ray,
    pos: &Vec3s,
    triangles: &[[u32; 3]],
) -> Option<TriangleHit> {
    pick_triangle_brute_force_where(ray, pos, triangles, |_| true)
}

/// [`pick_triangle_brute_force`] over the triangles whose position in `triangles` passes
/// `drawn` (a mesh cloth's drawn triangles, by id), `index` being that position.
pub fn pick_triangle_brute_force_where(
    ray: &Ray,
    pos: &Vec3s,
    triangles: &[[u32; 3]],
    drawn: impl Fn(usize) -> bool,
) -> Option<TriangleHit> {
    triangles
        .iter()
        .enumerate()
        .filter(|&(index, _)| drawn(index))
        .filter_map(|(index, tri)| {
            let [a, b, c] = tri.map(|q| pos.get(q as usize));
            let (distance, barycentric) = ray_triangle(ray, a, b, c)?;
            Some(TriangleHit {
                index,
                distance,
                barycentric,
            })
        })
        .min_by(TriangleHit::cmp_key)
}

/// The nearest live triangle, with `index` its stable id ([`cell_triangle`]): the same
/// answer as [`crate::picking::bvh::TriangleBvh::cast`] and as testing every triangle, without
/// a tree.
///
/// One pass over the positions bounds each row of particles; the strip of cells between two
/// rows lies in the union of their bounds (widened like a triangle's box). Strips are visited
/// nearest first and their triangles tested until the next strip starts farther than the best
/// hit, so a ray across the cloth tests a few strips, not every triangle.
pub fn pick_triangle_scan(
    ray: &Ray,
    grid: Grid,
    pos: &Vec3s,
    alive: &[bool],
) -> Option<TriangleHit> {
    pick_triangle_scan_where(ray, grid, pos, |id| triangle_alive(grid, alive, id))
}

/// [`pick_triangle_scan`] over the triangles `drawn` says are there (by id), such as
/// [`crate::model::Model::triangle_drawn`] after cuts that severed springs.
pub fn pick_triangle_scan_where(
    ray: &Ray,
    grid: Grid,
    pos: &Vec3s,
    drawn: impl Fn(usize) -> bool,
) -> Option<TriangleHit> {
    let nx = grid.nx;
    let rows: Vec<(Vec3, Vec3)> = (0..grid.ny)
        .map(|j| {
            let r = j * nx..(j + 1) * nx;
            let (x, y, z) = (
                min_max(&pos.x[r.clone()]),
                min_max(&pos.y[r.clone()]),
                min_max(&pos.z[r]),
            );
            (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
        })
        .collect();
    let widen = Vec3::splat(triangle_query_margin(ray));
    let mut strips: Vec<(f32, usize)> = (0..grid.ny - 1)
        .filter_map(|j| {
            let lo = rows[j].0.min(rows[j + 1].0);
            let hi = rows[j].1.max(rows[j + 1].1);
            // Widened like `triangle_bounds`, then by the query margin: step by step, so
            // that the strip's box contains each of its triangles' in floating point too.
            let margin = Vec3::splat(box_margin(lo, hi));
            let t = ray_aabb(ray, lo - margin - widen, hi + margin + widen)?;
            Some((t, j))
        })
        .collect();
    strips.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut best: Option<TriangleHit> = None;
    for (enter, j) in strips {
        if best.is_some_and(|b| enter > triangle_reach(b.distance)) {
            break;
        }
        let first = 2 * j * (nx - 1);
        for id in first..first + 2 * (nx - 1) {
            if !drawn(id) {
                continue;
            }
            let tri = cell_triangle(grid, id);
            let [a, b, c] = tri.map(|q| pos.get(q));
            if let Some((distance, barycentric)) = ray_triangle(ray, a, b, c) {
                let hit = TriangleHit {
                    index: id,
                    distance,
                    barycentric,
                };
                if best.is_none_or(|b| hit.cmp_key(&b) == Ordering::Less) {
                    best = Some(hit);
                }
            }
        }
    }
    best
}

/// Smallest and largest of `xs` (finite), in eight lanes so that it vectorises.
fn min_max(xs: &[f32]) -> (f32, f32) {
    let mut lo = [f32::INFINITY; 8];
    let mut hi = [f32::NEG_INFINITY; 8];
    let chunks = xs.chunks_exact(8);
    let tail = chunks.remainder();
    for chunk in chunks {
        for k in 0..8 {
            lo[k] = lo[k].min(chunk[k]);
            hi[k] = hi[k].max(chunk[k]);
        }
    }
    let lo = tail.iter().chain(&lo).fold(f32::INFINITY, |a, &x| a.min(x));
    let hi = tail
        .iter()
        .chain(&hi)
        .fold(f32::NEG_INFINITY, |a, &x| a.max(x));
    (lo, hi)
}

/// How far a triangle's box (or a box around several) is widened: far above the rounding of
/// [`ray_triangle`] at these coordinates. Grows with the box, so a box that contains another
/// is widened at least as much.
pub(super) fn box_margin(lo: Vec3, hi: Vec3) -> f32 {
    1e-5 * (1.0 + lo.abs().max(hi.abs()).max_element())
}

/// How much a triangle query widens every box beyond [`box_margin`]: Moeller-Trumbore works
/// with `origin - a`, so its rounding grows with the ray origin's distance from the origin of
/// coordinates too. 5e-5 m for a camera 5 m out; from 1e6 m it is 10 m, and the searches
/// degrade towards testing every triangle (still with the same answer).
pub(super) fn triangle_query_margin(ray: &Ray) -> f32 {
    TRIANGLE_ROUNDING * ray.origin.abs().max_element()
}

/// The bounds of triangle `(a, b, c)` widened by [`box_margin`]: its leaf box in the tree.
#[inline]
pub(super) fn triangle_bounds(a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
    let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
    let margin = Vec3::splat(box_margin(lo, hi));
    (lo - margin, hi + margin)
}
