//! Cuts that sever springs: a mouse stroke (a sequence of rays) sweeps a surface, and every live
//! spring whose segment crosses it is severed. No particle is removed, so mass is conserved to
//! the bit; the pieces fall apart because nothing joins them any more. Also here: which of the
//! mesh's triangles a severed cell still draws, and how many pieces the cloth is in.
//!
//! **Representation.** Physics stays on the grid: a severed spring is a slot whose `active`
//! flag is 0, which every pass already reads (forces, implicit solvers, strain limiting, the
//! watchdog), so a cut costs the step nothing and the particle count never changes (no spare
//! capacity, no reallocation, no renumbering of the BVH leaves). The mesh is derived per cell:
//! a triangle of a cell is drawn only while its three corners are joined within that cell by
//! live springs ([`triangle_drawn`]), so no drawn triangle spans a cut. The price: triangles
//! have particles as vertices, so the rendered edge runs along the particles next to the cut
//! (up to one grid spacing from the stroke), not through the cut point itself.
//!
//! The swept surface between rays `k` and `k + 1` is the quad `o_k, o_{k+1}, o_{k+1} + F d_{k+1},
//! o_k + F d_k`, split into two triangles, with `F` the distance from the farthest ray origin to
//! the farthest corner of the live cloth's bounding box: the surface reaches through the whole
//! cloth and no farther. Everything is in f64.

use glam::DVec3;

use crate::grid::{cell_triangle, triangle_alive, Grid, SpringKind};
use crate::picking::ray::Ray;
use crate::soa::Vec3s;
use crate::springs::Springs;

/// A severed spring: its kind and its anchor particle (the slot it is stored in).
pub type SpringSlot = (SpringKind, usize);

/// The live springs whose segments cross the surface the rays sweep, in order of (quad,
/// triangle, row, kind, anchor); a spring crossing twice is listed twice. Fewer than two rays sweep nothing; a quad of two equal rays (a mouse
/// that did not move) has no area and crosses nothing.
pub fn springs_crossing_stroke(
    grid: Grid,
    springs: &Springs,
    alive: &[bool],
    pos: &Vec3s,
    rays: &[Ray],
) -> Vec<SpringSlot> {
    let mut out = Vec::new();
    if rays.len() < 2 {
        return out;
    }
    let Some(far) = far_distance(pos, alive, rays) else {
        return out; // nothing alive
    };
    let nx = grid.nx;
    let mut side = vec![0i8; grid.len()];
    // Per row, where its sides change: see `RowSides`.
    let mut rows = vec![RowSides::default(); grid.ny];
    for pair in rays.windows(2) {
        let (o0, d0) = (pair[0].origin.as_dvec3(), pair[0].dir.as_dvec3());
        let (o1, d1) = (pair[1].origin.as_dvec3(), pair[1].dir.as_dvec3());
        let quad = [o0, o1, o1 + far * d1, o0 + far * d0];
        for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
            let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            if normal == DVec3::ZERO {
                continue; // a degenerate triangle: no surface
            }
            // Which side of the triangle's plane each particle is on: a spring can only cross
            // the triangle if its ends are on different sides (or one lies on the plane), which
            // leaves the exact test for the few springs near the plane.
            for (j, row) in rows.iter_mut().enumerate() {
                *row = RowSides::measure(&mut side[j * nx..(j + 1) * nx], |i| {
                    let p = j * nx + i;
                    let x = DVec3::new(pos.x[p] as f64, pos.y[p] as f64, pos.z[p] as f64);
                    normal.dot(x - tri[0])
                });
            }
            for j in 0..grid.ny {
                let Some(columns) = anchor_columns(&rows[j..=(j + 2).min(grid.ny - 1)], nx) else {
                    continue;
                };
                for kind in SpringKind::ALL {
                    let k = kind.index();
                    let o = grid.offset(kind);
                    let row = j * nx + columns.start..j * nx + columns.end;
                    let anchors = row.start..row.end.min(grid.len().saturating_sub(o));
                    for a in anchors {
                        let b = a + o;
                        if side[a] * side[b] > 0 || springs.active[k][a] == 0.0 {
                            continue;
                        }
                        if !(alive[a] && alive[b]) {
                            continue;
                        }
                        let (pa, pb) = (pos.get(a).as_dvec3(), pos.get(b).as_dvec3());
                        // A spring on two quads or on both halves of one is listed twice;
                        // severing it the second time finds it severed and counts nothing.
                        if segment_crosses_triangle(pa, pb, tri) {
                            out.push((kind, a));
                        }
                    }
                }
            }
        }
    }
    out
}

/// Where the sides of one row's particles change: outside columns `lo..=hi` every particle is
/// strictly on the side `left` (columns below `lo`) or `right` (above `hi`); inside, a particle
/// is on the plane or differs from a neighbour. A row wholly on one side has `lo > hi`.
#[derive(Clone, Copy, Debug, Default)]
struct RowSides {
    left: i8,
    right: i8,
    lo: usize,
    hi: usize,
}

impl RowSides {
    /// Fills `side` with the sign of `distance(i)` for each column `i` and says where it
    /// changes, in one pass.
    fn measure(side: &mut [i8], distance: impl Fn(usize) -> f64) -> RowSides {
        let n = side.len();
        let (mut lo, mut hi, mut prev) = (n, 0, 0i8);
        for (i, out) in side.iter_mut().enumerate() {
            let d = distance(i);
            let s = (d > 0.0) as i8 - (d < 0.0) as i8;
            *out = s;
            if s == 0 {
                (lo, hi) = (lo.min(i), hi.max(i));
            } else if i > 0 && s != prev {
                (lo, hi) = (lo.min(i - 1), hi.max(i));
            }
            prev = s;
        }
        RowSides {
            left: side[0],
            right: side[n - 1],
            lo,
            hi,
        }
    }
}

/// The columns of row `rows[0]` whose springs (reaching up to two rows on, one column back
/// and two on) may join particles on different sides; `None` if none can. Left of every row's
/// `lo` by more than two columns, all the rows are on one side if their `left`s agree, and so
/// on the right.
fn anchor_columns(rows: &[RowSides], nx: usize) -> Option<std::ops::Range<usize>> {
    let uniform = |s: &dyn Fn(&RowSides) -> i8| {
        let first = s(&rows[0]);
        first != 0 && rows.iter().all(|r| s(r) == first)
    };
    let (left_ok, right_ok) = (uniform(&|r| r.left), uniform(&|r| r.right));
    let lo = rows.iter().map(|r| r.lo).min().expect("one row at least");
    let hi = rows.iter().filter(|r| r.lo <= r.hi).map(|r| r.hi).max();
    let start = if left_ok { lo.saturating_sub(2) } else { 0 };
    let end = match (right_ok, hi) {
        (false, _) => nx,
        (true, Some(hi)) => (hi + 3).min(nx),
        (true, None) if left_ok => return None, // every row wholly on the same side
        (true, None) => nx,
    };
    (start < end).then_some(start..end)
}

/// Distance along the rays that reaches every live particle from every ray origin: the
/// farthest corner of the live particles' bounding box, plus one metre so that a particle on
/// the box's corner is strictly inside the swept surface. `None` if no particle is alive.
pub fn far_distance(pos: &Vec3s, alive: &[bool], rays: &[Ray]) -> Option<f64> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in (0..pos.len()).filter(|&p| alive[p]) {
        let x = pos.get(p).as_dvec3();
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if lo.x > hi.x {
        return None;
    }
    let far = rays
        .iter()
        .map(|r| {
            let o = r.origin.as_dvec3();
            (o - lo).abs().max((o - hi).abs()).length()
        })
        .fold(0.0, f64::max);
    Some(far + 1.0)
}

/// Whether the closed segment `p-q` meets the closed triangle `tri` (Moeller-Trumbore with the
/// segment's own parameter in `[0, 1]`). A segment lying in the triangle's plane never does:
/// it is parallel to the surface, not across it.
pub fn segment_crosses_triangle(p: DVec3, q: DVec3, tri: [DVec3; 3]) -> bool {
    let dir = q - p;
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let h = dir.cross(e2);
    let det = e1.dot(h);
    if det == 0.0 {
        return false;
    }
    let inv = 1.0 / det;
    let s = p - tri[0];
    let u = inv * s.dot(h);
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = s.cross(e1);
    let v = inv * dir.dot(qv);
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = inv * e2.dot(qv);
    (0.0..=1.0).contains(&t)
}

/// Whether triangle `id` ([`cell_triangle`]) is drawn: its three corners are alive and joined
/// within their cell by live springs (the cell's four edges and two diagonals). On a cloth
/// that was never severed this is "all three corners alive", as before cuts severed springs;
/// after a cut through the cell, the corners on the two sides are not joined, so no drawn
/// triangle spans the cut.
pub fn triangle_drawn(grid: Grid, springs: &Springs, alive: &[bool], id: usize) -> bool {
    if !triangle_alive(grid, alive, id) {
        return false;
    }
    // Corners 0..4 = a (i, j), b (i+1, j), c (i, j+1), d (i+1, j+1).
    let a = cell_triangle(grid, id & !1)[0];
    let (b, c) = (a + 1, a + grid.nx);
    let live = |kind: SpringKind, anchor: usize| springs.active[kind.index()][anchor] != 0.0;
    let edges = [
        (0, 1, live(SpringKind::StructuralI, a)),
        (2, 3, live(SpringKind::StructuralI, c)),
        (0, 2, live(SpringKind::StructuralJ, a)),
        (1, 3, live(SpringKind::StructuralJ, b)),
        (0, 3, live(SpringKind::ShearDiagonal, a)),
        (1, 2, live(SpringKind::ShearAntiDiagonal, b)),
    ];
    // The common case, a cell no cut went through: no components to find (the mesh's normals
    // ask this six times per particle per frame).
    if edges.iter().all(|e| e.2) {
        return true;
    }
    // Connected components of four nodes: relax the labels until nothing changes (at most
    // three rounds for a path of four).
    let mut label = [0usize, 1, 2, 3];
    for _ in 0..3 {
        for &(x, y, on) in &edges {
            if on {
                let m = label[x].min(label[y]);
                label[x] = m;
                label[y] = m;
            }
        }
    }
    let corner = |q: usize| match q - a {
        0 => 0,
        1 => 1,
        o if o == grid.nx => 2,
        _ => 3,
    };
    let [x, y, z] = cell_triangle(grid, id).map(corner);
    label[x] == label[y] && label[y] == label[z]
}

/// The number of pieces the cloth is in: connected components of the live particles joined by
/// live springs (of any family, whatever its stiffness). A particle with no live spring is a
/// piece of its own.
pub fn pieces(grid: Grid, springs: &Springs, alive: &[bool]) -> usize {
    let labels = piece_labels(grid, springs, alive);
    (0..grid.len())
        .filter(|&p| alive[p] && labels[p] == p as u32)
        .count()
}

/// The piece each live particle belongs to, named by the smallest particle index in it
/// (`u32::MAX` for a removed particle). Union-find over the live springs, `O(n)`.
pub fn piece_labels(grid: Grid, springs: &Springs, alive: &[bool]) -> Vec<u32> {
    let n = grid.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up; // path halving
            x = up;
        }
        x
    }
    for kind in SpringKind::ALL {
        springs.for_each(grid, kind, |a, b, _| {
            if alive[a] && alive[b] {
                let (ra, rb) = (root(&mut parent, a as u32), root(&mut parent, b as u32));
                // The smaller index stays the root, so a root is its piece's smallest index.
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        });
    }
    (0..n)
        .map(|p| {
            if alive[p] {
                root(&mut parent, p as u32)
            } else {
                u32::MAX
            }
        })
        .collect()
}
