//! The independent intersection checker: a plain edge-through-triangle test (signed volumes,
//! f64) over every pair of triangles that share no particle, written apart from the solver
//! (which works with distances). Two triangles that share no particle and are not coplanar
//! intersect exactly when an edge of one crosses the other.

use glam::DVec3;
use rustcloth::soa::Vec3s;

/// Six times the signed volume of the tetrahedron `a b c d`, and a scale for its round-off
/// (the product of the three edge lengths from `a`).
pub fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> (f64, f64) {
    let (u, v, w) = (b - a, c - a, d - a);
    (u.cross(v).dot(w), u.length() * v.length() * w.length())
}

/// Whether segment `p q` properly crosses triangle `a b c`: `p` and `q` strictly on opposite
/// sides of its plane, and the line `p q` strictly on the same side of each of its edges
/// (signed volumes, Segura and Feito 1998). A sign within round-off of zero counts as not
/// crossing: such a touch (a segment in the triangle's plane, or through its boundary) is
/// within 1e-12 of the triangles' size of not intersecting at all.
pub fn segment_hits_triangle(p: DVec3, q: DVec3, a: DVec3, b: DVec3, c: DVec3) -> bool {
    let sign = |(v, scale): (f64, f64)| {
        if v.abs() <= 1e-12 * scale {
            0
        } else if v > 0.0 {
            1
        } else {
            -1
        }
    };
    let (sp, sq) = (sign(orient(a, b, c, p)), sign(orient(a, b, c, q)));
    if sp * sq >= 0 {
        return false;
    }
    let e = [
        sign(orient(p, q, a, b)),
        sign(orient(p, q, b, c)),
        sign(orient(p, q, c, a)),
    ];
    e[0] != 0 && e[0] == e[1] && e[1] == e[2]
}

pub fn triangles_intersect(t: [DVec3; 3], u: [DVec3; 3]) -> bool {
    let crosses = |s: [DVec3; 3], o: [DVec3; 3]| {
        (0..3).any(|k| segment_hits_triangle(s[k], s[(k + 1) % 3], o[0], o[1], o[2]))
    };
    crosses(t, u) || crosses(u, t)
}

/// The pairs of `triangles` at `pos` that intersect, by sort and sweep along x, skipping pairs
/// that share a particle once each particle is taken as `same(particle)` (a garment's sewn
/// vertices are one point).
pub fn intersecting_pairs(
    triangles: &[[u32; 3]],
    pos: &Vec3s,
    same: impl Fn(u32) -> u32,
) -> Vec<(usize, usize)> {
    let tris: Vec<[u32; 3]> = triangles.iter().map(|t| t.map(&same)).collect();
    let corners: Vec<[DVec3; 3]> = triangles
        .iter()
        .map(|t| t.map(|p| pos.get(p as usize).as_dvec3()))
        .collect();
    let boxes: Vec<(DVec3, DVec3)> = corners
        .iter()
        .map(|c| (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2])))
        .collect();
    let mut order: Vec<usize> = (0..tris.len()).collect();
    order.sort_by(|&a, &b| boxes[a].0.x.total_cmp(&boxes[b].0.x));
    let mut found = Vec::new();
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if boxes[b].0.x > boxes[a].1.x {
                break;
            }
            let (ba, bb) = (boxes[a], boxes[b]);
            if ba.0.cmpgt(bb.1).any() || bb.0.cmpgt(ba.1).any() {
                continue;
            }
            if tris[a].iter().any(|p| tris[b].contains(p)) {
                continue;
            }
            if triangles_intersect(corners[a], corners[b]) {
                found.push((a.min(b), a.max(b)));
            }
        }
    }
    found
}
