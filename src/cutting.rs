//! Cuts that sever springs: a mouse stroke (a sequence of rays) sweeps a surface, and every live
//! spring whose segment crosses it is severed. No particle is removed, so mass is conserved to
//! the bit; the pieces fall apart because nothing joins them any more. Also here: which of the
//! mesh's triangles a severed cell still draws, and how many pieces the cloth is in. A mesh
//! cloth's springs are swept the same way ([`StrokeCutter::mesh_crossings`]); what a severed
//! mesh spring takes with it is [`crate::mesh_cloth::topology`]'s.
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

use crate::grid::{cell_triangle, triangle_alive, Grid, SpringKind, SpringSlot};
use crate::mesh_cloth::{EdgeKind, EdgeSprings};
use crate::ray::Ray;
use crate::soa::Vec3s;
use crate::springs::Springs;

/// A severed spring and where the stroke crossed it: `t` in `[0, 1]` along its segment from
/// the anchor.
pub type Crossing = (SpringSlot, f32);

/// A severed spring of a mesh cloth (its index in the spring list) and where the stroke crossed
/// it: `t` in `[0, 1]` along its segment from its end `a`.
pub type MeshCrossing = (u32, f32);

/// The live springs whose segments cross the surface the rays sweep, each with where it
/// crosses, in order of (quad, triangle, kind, anchor); a spring crossing twice is listed
/// twice. Fewer than two rays sweep nothing; a quad of two equal rays (a mouse that did not
/// move) has no area and crosses nothing. [`StrokeCutter::crossings`] without keeping the
/// workspace.
pub fn springs_crossing_stroke(
    grid: Grid,
    springs: &Springs,
    alive: &[bool],
    pos: &Vec3s,
    rays: &[Ray],
) -> Vec<Crossing> {
    StrokeCutter::default()
        .crossings(grid, springs, alive, pos, rays, &mut || false)
        .map(<[Crossing]>::to_vec)
        .unwrap_or_default()
}

/// Quads of a stroke swept between two checks for an interrupt: each passes over every
/// particle, so at 64 a check comes every few milliseconds on a large cloth, and asking costs
/// next to nothing beside that.
const INTERRUPT_QUADS: usize = 64;

/// The workspace of the stroke test, kept between strokes so that a stroke segment allocates
/// nothing once the cloth has been cut once.
///
/// Per triangle of the swept surface, one branch-free pass over the particles gives each a
/// code of five bits, in float32 with a margin that makes it conservative: strictly above or
/// below the triangle's plane, and strictly outside each of its three edges (the half-space
/// beyond the plane through the edge along the normal). A segment whose two ends share a bit
/// lies wholly on one side of that plane, so it cannot meet the triangle: a spring is tested
/// exactly (in f64) only if `code[a] & code[b] == 0`, which one byte-wise pass per spring kind
/// finds, 64 anchors at a time. The exact tests are as many as the springs near the swept
/// triangle, not the springs along the whole line its plane cuts through the cloth.
#[derive(Default)]
pub struct StrokeCutter {
    code: Vec<u8>,
    out: Vec<Crossing>,
    mesh_out: Vec<MeshCrossing>,
}

/// Strictly above the plane.
const ABOVE: u8 = 1;
/// Strictly below the plane.
const BELOW: u8 = 2;
/// Strictly outside edge `e` of the triangle: `OUTSIDE << e`.
const OUTSIDE: u8 = 4;
/// A removed particle: shares a bit with every particle but one on the triangle.
const DEAD: u8 = 0xff;
/// Anchors whose codes are compared at once before looking for the spring that may cross.
const BLOCK: usize = 64;

/// A plane `n . x = c` in float32, and the margin beyond which the sign of `n . x - c`
/// computed in float32 is certain.
#[derive(Clone, Copy)]
struct Plane32 {
    n: [f32; 3],
    c: f32,
    margin: f32,
}

impl Plane32 {
    /// The plane through `point` with unit normal `n`, for points within `reach` of the origin
    /// (in each coordinate).
    fn new(n: DVec3, point: DVec3, reach: f64) -> Plane32 {
        let c = n.dot(point);
        // float32 rounding of n, of c and of each product and sum is a few 1e-7 relative to
        // the sizes involved; 1e-5 leaves a factor of ten or more.
        let margin = 1e-5 * (1.0 + c.abs() + 3.0 * reach);
        Plane32 {
            n: n.as_vec3().to_array(),
            c: c as f32,
            margin: margin as f32,
        }
    }

    #[inline(always)]
    fn distance(&self, x: f32, y: f32, z: f32) -> f32 {
        self.n[0] * x + self.n[1] * y + self.n[2] * z - self.c
    }
}

impl StrokeCutter {
    /// [`springs_crossing_stroke`], in this workspace.
    pub fn crossings(
        &mut self,
        grid: Grid,
        springs: &Springs,
        alive: &[bool],
        pos: &Vec3s,
        rays: &[Ray],
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Option<&[Crossing]> {
        self.out.clear();
        let out = &mut self.out;
        let test = |code: &[u8], tri| {
            grid_springs_crossing(code, out, (grid, springs), (pos, alive), tri);
        };
        sweep(&mut self.code, (pos, alive), rays, interrupted, test).then_some(&self.out)
    }

    /// The live springs of a mesh cloth (seams aside: two sewn vertices are one point) whose
    /// segments cross the surface the rays sweep, as indices into the spring list with where
    /// each crosses, in order of (quad, triangle, spring); a spring crossing twice is listed
    /// twice. The same sweep and
    /// the same conservative codes as [`StrokeCutter::crossings`], over the spring list: the
    /// codes of each block of springs are compared branch-free before any exact test.
    pub fn mesh_crossings(
        &mut self,
        springs: &EdgeSprings,
        (pos, alive): (&Vec3s, &[bool]),
        rays: &[Ray],
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Option<&[MeshCrossing]> {
        self.mesh_out.clear();
        let out = &mut self.mesh_out;
        let test = |code: &[u8], tri| mesh_springs_crossing(code, out, springs, pos, tri);
        sweep(&mut self.code, (pos, alive), rays, interrupted, test).then_some(&self.mesh_out)
    }

    pub fn heap_bytes(&self) -> usize {
        self.code.capacity()
            + self.out.capacity() * size_of::<Crossing>()
            + self.mesh_out.capacity() * size_of::<MeshCrossing>()
    }
}

/// Sweeps the stroke's quads, two triangles each: for each triangle, the particles' codes
/// against it ([`classify`]), then `test` on those codes and the triangle. False if
/// `interrupted` said stop.
fn sweep(
    code: &mut Vec<u8>,
    (pos, alive): (&Vec3s, &[bool]),
    rays: &[Ray],
    interrupted: &mut dyn FnMut() -> bool,
    mut test: impl FnMut(&[u8], [DVec3; 3]),
) -> bool {
    if rays.len() < 2 {
        return true;
    }
    let Some((lo, hi)) = live_bounds(pos, alive) else {
        return true; // nothing alive
    };
    let far = far_from_bounds(lo, hi, rays);
    let reach = lo.abs().max(hi.abs()).max_element();
    code.resize(pos.len(), 0);
    for (k, pair) in rays.windows(2).enumerate() {
        if k % INTERRUPT_QUADS == INTERRUPT_QUADS - 1 && interrupted() {
            return false;
        }
        let (o0, d0) = (pair[0].origin.as_dvec3(), pair[0].dir.as_dvec3());
        let (o1, d1) = (pair[1].origin.as_dvec3(), pair[1].dir.as_dvec3());
        let quad = [o0, o1, o1 + far * d1, o0 + far * d0];
        for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
            let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            if normal == DVec3::ZERO {
                continue; // a degenerate triangle: no surface
            }
            let n = normal.normalize();
            let plane = Plane32::new(n, tri[0], reach.max(far));
            let edges: [Plane32; 3] = std::array::from_fn(|e| {
                let (p, q) = (tri[e], tri[(e + 1) % 3]);
                Plane32::new((q - p).cross(n).normalize(), p, reach.max(far))
            });
            classify(code, pos, alive, plane, edges);
            test(code, tri);
        }
    }
    true
}

/// Appends the springs whose ends' codes share no bit and that cross `tri` exactly.
fn grid_springs_crossing(
    code: &[u8],
    out: &mut Vec<Crossing>,
    (grid, springs): (Grid, &Springs),
    (pos, alive): (&Vec3s, &[bool]),
    tri: [DVec3; 3],
) {
    for kind in SpringKind::ALL {
        let (k, o) = (kind.index(), grid.offset(kind));
        let n = grid.len().saturating_sub(o);
        let (ca, cb) = (&code[..n], &code[o..o + n]);
        for start in (0..n).step_by(BLOCK) {
            let end = (start + BLOCK).min(n);
            // Branch-free over the block (it vectorises): the smallest shared bit set.
            let shared = ca[start..end]
                .iter()
                .zip(&cb[start..end])
                .fold(u8::MAX, |m, (&x, &y)| m.min(x & y));
            if shared != 0 {
                continue;
            }
            for a in start..end {
                let b = a + o;
                if ca[a] & cb[a] != 0 || springs.active[k][a] == 0.0 || !(alive[a] && alive[b]) {
                    continue;
                }
                let (pa, pb) = (pos.get(a).as_dvec3(), pos.get(b).as_dvec3());
                // A spring on two quads or on both halves of one is listed twice;
                // severing it the second time finds it severed and counts nothing.
                if let Some(t) = segment_crossing(pa, pb, tri) {
                    out.push(((kind, a), t as f32));
                }
            }
        }
    }
}

/// Appends the live springs of a mesh cloth, seams aside, whose ends' codes share no bit and
/// that cross `tri` exactly, as indices into the spring list with where each crosses.
fn mesh_springs_crossing(
    code: &[u8],
    out: &mut Vec<MeshCrossing>,
    springs: &EdgeSprings,
    pos: &Vec3s,
    tri: [DVec3; 3],
) {
    for start in (0..springs.len()).step_by(BLOCK) {
        let block = start..(start + BLOCK).min(springs.len());
        let (a, b) = (&springs.a[block.clone()], &springs.b[block.clone()]);
        // Branch-free over the block (it vectorises): the smallest shared bit set.
        let shared = (a.iter().zip(b)).fold(u8::MAX, |m, (&x, &y)| {
            m.min(code[x as usize] & code[y as usize])
        });
        if shared != 0 {
            continue;
        }
        for e in block {
            let (a, b) = (springs.a[e] as usize, springs.b[e] as usize);
            if code[a] & code[b] != 0 || !springs.active[e] || springs.kind[e] == EdgeKind::Seam {
                continue;
            }
            let (pa, pb) = (pos.get(a).as_dvec3(), pos.get(b).as_dvec3());
            if let Some(t) = segment_crossing(pa, pb, tri) {
                out.push((e as u32, t as f32));
            }
        }
    }
}

/// Each particle's code against the triangle with the given plane and edge planes (see
/// [`StrokeCutter`]).
fn classify(code: &mut [u8], pos: &Vec3s, alive: &[bool], plane: Plane32, edges: [Plane32; 3]) {
    let n = code.len();
    let (xs, ys, zs, alive) = (&pos.x[..n], &pos.y[..n], &pos.z[..n], &alive[..n]);
    let [e0, e1, e2] = edges;
    for i in 0..n {
        let (x, y, z) = (xs[i], ys[i], zs[i]);
        let d = plane.distance(x, y, z);
        let c = (ABOVE * (d > plane.margin) as u8)
            | (BELOW * (d < -plane.margin) as u8)
            | (OUTSIDE * (e0.distance(x, y, z) > e0.margin) as u8)
            | ((OUTSIDE << 1) * (e1.distance(x, y, z) > e1.margin) as u8)
            | ((OUTSIDE << 2) * (e2.distance(x, y, z) > e2.margin) as u8);
        code[i] = if alive[i] { c } else { DEAD };
    }
}

/// The bounding box of the live particles, or `None` if none is alive. Eight lanes at a time,
/// so that it vectorises.
fn live_bounds(pos: &Vec3s, alive: &[bool]) -> Option<(DVec3, DVec3)> {
    const LANES: usize = 8;
    let n = alive.len();
    let bound = |values: &[f32]| {
        let (mut lo, mut hi) = ([f32::INFINITY; LANES], [f32::NEG_INFINITY; LANES]);
        let (values, alive) = (&values[..n], &alive[..n]);
        let chunks = values.chunks_exact(LANES).zip(alive.chunks_exact(LANES));
        for (v, a) in chunks {
            for l in 0..LANES {
                // Selects, not branches: the loop runs eight lanes at once.
                let low = if a[l] { v[l] } else { f32::INFINITY };
                let high = if a[l] { v[l] } else { f32::NEG_INFINITY };
                lo[l] = if low < lo[l] { low } else { lo[l] };
                hi[l] = if high > hi[l] { high } else { hi[l] };
            }
        }
        let tail = n - n % LANES;
        for (&v, _) in values[tail..]
            .iter()
            .zip(&alive[tail..])
            .filter(|(_, &a)| a)
        {
            (lo[0], hi[0]) = (lo[0].min(v), hi[0].max(v));
        }
        let lo = lo.into_iter().fold(f32::INFINITY, f32::min);
        let hi = hi.into_iter().fold(f32::NEG_INFINITY, f32::max);
        (lo as f64, hi as f64)
    };
    let (x, y, z) = (bound(&pos.x[..]), bound(&pos.y[..]), bound(&pos.z[..]));
    (x.0 <= x.1).then(|| (DVec3::new(x.0, y.0, z.0), DVec3::new(x.1, y.1, z.1)))
}

/// See [`far_distance`].
fn far_from_bounds(lo: DVec3, hi: DVec3, rays: &[Ray]) -> f64 {
    let far = rays
        .iter()
        .map(|r| {
            let o = r.origin.as_dvec3();
            (o - lo).abs().max((o - hi).abs()).length()
        })
        .fold(0.0, f64::max);
    far + 1.0
}

/// Distance along the rays that reaches every live particle from every ray origin: the
/// farthest corner of the live particles' bounding box, plus one metre so that a particle on
/// the box's corner is strictly inside the swept surface. `None` if no particle is alive.
pub fn far_distance(pos: &Vec3s, alive: &[bool], rays: &[Ray]) -> Option<f64> {
    live_bounds(pos, alive).map(|(lo, hi)| far_from_bounds(lo, hi, rays))
}

/// Whether the closed segment `p-q` meets the closed triangle `tri` (Moeller-Trumbore with the
/// segment's own parameter in `[0, 1]`). A segment lying in the triangle's plane never does:
/// it is parallel to the surface, not across it.
pub fn segment_crosses_triangle(p: DVec3, q: DVec3, tri: [DVec3; 3]) -> bool {
    segment_crossing(p, q, tri).is_some()
}

/// Where the closed segment `p-q` meets the closed triangle `tri`: the parameter `t` in
/// `[0, 1]` of the point `p + t (q - p)` (see [`segment_crosses_triangle`]).
pub fn segment_crossing(p: DVec3, q: DVec3, tri: [DVec3; 3]) -> Option<f64> {
    let dir = q - p;
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let h = dir.cross(e2);
    let det = e1.dot(h);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = p - tri[0];
    let u = inv * s.dot(h);
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = s.cross(e1);
    let v = inv * dir.dot(qv);
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = inv * e2.dot(qv);
    (0.0..=1.0).contains(&t).then_some(t)
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
    piece_labels_joined_by(grid, springs, alive, |_, _| true)
}

/// [`piece_labels`] as if only the live springs `joins(a, b)` accepts were left: the pieces a
/// cut of the others would leave.
pub fn piece_labels_joined_by(
    grid: Grid,
    springs: &Springs,
    alive: &[bool],
    joins: impl Fn(usize, usize) -> bool,
) -> Vec<u32> {
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
            if alive[a] && alive[b] && joins(a, b) {
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
