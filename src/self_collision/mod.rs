//! Self-collision: the cloth never passes through itself, and layers in contact are kept
//! about `thickness` apart, with Coulomb friction. The last pass of a substep (after the
//! colliders), present only when the scene has `[self_collision]`.
//!
//! Two stages on the substep's motion from `x0` (its start, assumed free of intersections) to
//! `x1` (what the integrator, pins and colliders made of it):
//!
//! 1. **Repulsion** (soft, what keeps the gap). The broad phase (`hash.rs`) finds every
//!    vertex-triangle pair (the vertex not in the triangle) and edge-edge pair (no shared
//!    vertex) whose boxes, swept from `x0` to `x1` and grown by `thickness`, overlap. For each,
//!    the closest points at `x0` (`geometry.rs`) give weights `c_i` with `sum c_i = 0` and a
//!    unit normal `n`, and the gap `g = (sum c_i x_i) . n`. `iterations` Gauss-Seidel sweeps
//!    in pair order push every pair with `g < thickness` apart along `n`, shared by inverse
//!    mass, `dx_i = w_i c_i (thickness - g) n / sum_j w_j c_j^2`. Then, in as many sweeps, each
//!    such pair loses its approaching normal velocity (an inelastic impulse of the same shape)
//!    and, in the first sweep, by Coulomb friction up to `friction` times that of its
//!    tangential relative velocity. Every correction is applied to both sides with weights
//!    summing to zero, so momentum is conserved.
//!
//! 2. **The cap** (hard, what makes the guarantee). The distance between a vertex and a
//!    triangle, or between two edges, is 1-Lipschitz in the relative position of the two
//!    primitives: along the straight motion `x0 + t dx`, `t` in `[0, 1]`, it is at least
//!    `d0 - t m` with `d0` its value at `x0` and `m = max |dx_i - dx_j|` over vertices `i` of one
//!    primitive and `j` of the other. So a pair with `m < d0` cannot touch during the substep.
//!    Sliding and separating motion count in `m` too, so a second bound is used beside it: the
//!    plane through the closest points at `x0`, normal `n`, separates the two primitives
//!    (both are convex), `(x_i - x_j) . n >= d0` for all such `i, j`; each of these is linear
//!    in `t`, so if all are positive at the end of the substep the plane separates them all
//!    along. A pair is safe when `m <= APPROACH d0 - eps` or every
//!    `(x_i - x_j) . n >= (1 - APPROACH) d0 + eps` at the end.
//!    The cap scales the displacement of the vertices of every pair safe by neither bound
//!    toward `x0` (`dx_i -> s_i dx_i`), for a few rounds in proportion,
//!    then by stopping them (`s = 0`), until no pair is left: it ends because each round stops
//!    at least one more vertex, and a pair whose vertices all stand still has `m = 0`. Each
//!    vertex is also kept inside its own grown swept box, so a pair the broad phase did not
//!    find (boxes apart) stays apart. Capped vertices get their velocity scaled by `s` too.
//!    With no triangle pair in contact at the start, none touches at any time of any substep:
//!    two triangles sharing no vertex can only start to intersect through a vertex touching a
//!    face or an edge touching an edge.
//!
//! The candidate lists are collected afresh each substep (this pass allocates; the others do
//! not). Everything parallel is a map in item order; all updates are sequential in pair order, so the
//! result is bitwise the same for any thread count.

mod geometry;
mod hash;
mod topology;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::model::Model;
use crate::soa::Vec3s;
use crate::state::Kinematics;
use hash::{Aabb, HashGrid};
use topology::Topology;

/// Fraction of a pair's distance at the start of a substep that its relative motion may close
/// within it. Close to 1 so that the cap seldom acts (the repulsion keeps pairs at
/// `thickness`, and only a relative motion of 0.9 `thickness` per substep reaches the cap);
/// below 1 so that a pair keeps a tenth of its distance, far above float32 round-off.
const APPROACH: f64 = 0.9;

/// Rounds of proportional scaling before the cap stops the vertices of the pairs still too
/// fast. More rounds keep more motion in a tangle of contacts, at one pass over the pairs each.
const SCALE_ROUNDS: u32 = 8;

/// What the pass did, summed since the simulation was built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfCollisionStats {
    /// Substeps the pass ran.
    pub substeps: u64,
    /// Candidate pairs from the broad phase, summed over substeps.
    pub pairs: u64,
    /// Pairs closer than `thickness` after the integrator (the repulsion's first sweep).
    pub contacts: u64,
    /// Vertices whose displacement the cap shortened, summed over substeps.
    pub capped: u64,
    /// Of those, vertices the cap stopped altogether.
    pub stopped: u64,
    /// Most cap rounds one substep took.
    pub max_cap_rounds: u32,
    /// Smallest distance at the start of a substep between a vertex and a triangle without it,
    /// or two edges with no shared vertex, among the broad phase's pairs (m; infinite if none).
    pub min_distance: f64,
}

impl Default for SelfCollisionStats {
    fn default() -> Self {
        SelfCollisionStats {
            substeps: 0,
            pairs: 0,
            contacts: 0,
            capped: 0,
            stopped: 0,
            max_cap_rounds: 0,
            min_distance: f64::INFINITY,
        }
    }
}

/// A candidate pair: a vertex and a triangle without it (`split = 1`: `verts[0]` against
/// `verts[1..]`) or two edges with no shared vertex (`split = 2`).
#[derive(Clone, Copy, Debug)]
struct Pair {
    verts: [u32; 4],
    split: usize,
    /// Weights of the closest points at the start: the gap vector is `sum c_i x_i`.
    c: [f64; 4],
    /// Unit normal at the start, from the second primitive to the first (zero if degenerate).
    n: DVec3,
    /// Distance at the start, in m.
    d0: f64,
}

impl Pair {
    fn gap(&self, x: &Vec3s) -> f64 {
        let mut g = DVec3::ZERO;
        for k in 0..4 {
            g += self.c[k] * x.get(self.verts[k] as usize).as_dvec3();
        }
        g.dot(self.n)
    }
}

/// The self-collision pass and its workspace.
pub struct SelfCollision {
    /// Gap kept between layers, in m.
    pub thickness: f32,
    /// Coulomb friction between layers.
    pub friction: f32,
    /// Repulsion sweeps per substep.
    pub iterations: u32,
    topology: Topology,
    vertex_boxes: Vec<Aabb>,
    tri_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    tri_grid: HashGrid,
    edge_grid: HashGrid,
    pairs: Vec<Pair>,
    /// Pairs the repulsion looks at, and whether each was in contact in some sweep.
    near: Vec<(u32, bool)>,
    scale: Vec<f64>,
    scale_next: Vec<f64>,
    stats: SelfCollisionStats,
}

impl SelfCollision {
    pub const NAME: &'static str = "self_collision";

    pub fn new(thickness: f32, friction: f32, iterations: u32) -> SelfCollision {
        SelfCollision {
            thickness,
            friction,
            iterations,
            topology: Topology::default(),
            vertex_boxes: Vec::new(),
            tri_boxes: Vec::new(),
            edge_boxes: Vec::new(),
            tri_grid: HashGrid::default(),
            edge_grid: HashGrid::default(),
            pairs: Vec::new(),
            near: Vec::new(),
            scale: Vec::new(),
            scale_next: Vec::new(),
            stats: SelfCollisionStats::default(),
        }
    }

    pub fn stats(&self) -> SelfCollisionStats {
        self.stats
    }

    /// Runs the pass on the substep from `start` to `next` (see the module's comment). Returns
    /// false, changing nothing, when `next` holds a non-finite position (the step then fails
    /// as any non-finite step does), and otherwise whether the velocities it wrote are finite.
    pub fn apply(&mut self, model: &Model, start: &Kinematics, next: &mut Kinematics) -> bool {
        if self.topology.version != Some(model.topology_version) {
            // The cut-aware surface: a triangle a cut or tear runs through is no surface.
            let triangles = model.triangles().collect();
            self.topology
                .rebuild(model.topology_version, model.grid.len(), triangles);
        }
        let n = model.grid.len();
        let (x0, inv_mass) = (&start.pos, &model.particles.inv_mass);
        let mut reach = 0.0f32;
        for &v in &self.topology.vertices {
            let (a, b) = (x0.get(v as usize), next.pos.get(v as usize));
            if !(a.is_finite() && b.is_finite()) {
                return false;
            }
            reach = reach.max(a.abs().max_element()).max(b.abs().max_element());
        }
        // A margin above float32 round-off of coordinates up to `reach` (8 ulps and more).
        let eps = 1e-6 * (1.0 + reach as f64);
        self.stats.substeps += 1;
        self.broad_phase(x0, &next.pos, n, eps as f32);
        self.narrow_phase(x0);
        self.stats.pairs += self.pairs.len() as u64;
        if let Some(d) = self.pairs.iter().map(|p| p.d0).min_by(f64::total_cmp) {
            self.stats.min_distance = self.stats.min_distance.min(d);
        }
        let h_finite = self.repel(next, inv_mass);
        // Back inside each vertex's grown swept box, where the broad phase looked.
        for &(k, touched) in &self.near {
            if touched {
                for &v in &self.pairs[k as usize].verts {
                    let b = &self.vertex_boxes[v as usize];
                    let p = next.pos.get(v as usize).clamp(b.min, b.max);
                    next.pos.set(v as usize, p);
                }
            }
        }
        self.cap(x0, next, eps);
        h_finite
    }

    /// Candidate pairs: boxes swept from `x0` to `x1`, each vertex's grown by `thickness / 2 +
    /// eps`, a primitive's the union of its vertices'.
    fn broad_phase(&mut self, x0: &Vec3s, x1: &Vec3s, n: usize, eps: f32) {
        let grow = Vec3::splat(0.5 * self.thickness + eps);
        self.vertex_boxes.resize(n, Aabb::EMPTY);
        self.vertex_boxes
            .par_iter_mut()
            .enumerate()
            .for_each(|(v, b)| {
                let (a, c) = (x0.get(v), x1.get(v));
                *b = Aabb {
                    min: a.min(c) - grow,
                    max: a.max(c) + grow,
                };
            });
        let (topo, vb) = (&self.topology, &self.vertex_boxes);
        self.tri_boxes.clear();
        self.tri_boxes
            .par_extend(topo.triangles.par_iter().map(|t| {
                vb[t[0] as usize]
                    .union(vb[t[1] as usize])
                    .union(vb[t[2] as usize])
            }));
        self.edge_boxes.clear();
        self.edge_boxes.par_extend(
            topo.edges
                .par_iter()
                .map(|e| vb[e[0] as usize].union(vb[e[1] as usize])),
        );
        self.tri_grid.build(&self.tri_boxes);
        self.edge_grid.build(&self.edge_boxes);
    }

    /// The closest points at `x0` of every candidate pair, in the broad phase's order.
    fn narrow_phase(&mut self, x0: &Vec3s) {
        let (topo, vb, tb, eb) = (
            &self.topology,
            &self.vertex_boxes,
            &self.tri_boxes,
            &self.edge_boxes,
        );
        let (tri_grid, edge_grid) = (&self.tri_grid, &self.edge_grid);
        self.pairs.clear();
        self.pairs
            .par_extend(topo.vertices.par_iter().flat_map_iter(|&v| {
                let b = vb[v as usize];
                let mut found = Vec::new();
                tri_grid.query(&b, |t| {
                    let tri = topo.triangles[t as usize];
                    if !tri.contains(&v) && tb[t as usize].overlaps(&b) {
                        found.push(t);
                    }
                });
                found.sort_unstable();
                found.dedup();
                found.into_iter().map(move |t| {
                    let [a, b, c] = topo.triangles[t as usize];
                    vertex_triangle(x0, [v, a, b, c])
                })
            }));
        self.pairs.par_extend(
            topo.edges
                .par_iter()
                .enumerate()
                .flat_map_iter(|(e, &[a, b])| {
                    let bx = eb[e];
                    let mut found = Vec::new();
                    edge_grid.query(&bx, |f| {
                        let [c, d] = topo.edges[f as usize];
                        if (f as usize) > e
                            && a != c
                            && a != d
                            && b != c
                            && b != d
                            && eb[f as usize].overlaps(&bx)
                        {
                            found.push(f);
                        }
                    });
                    found.sort_unstable();
                    found.dedup();
                    found.into_iter().map(move |f| {
                        let [c, d] = topo.edges[f as usize];
                        edge_edge(x0, [a, b, c, d])
                    })
                }),
        );
    }

    /// The repulsion sweeps and the inelastic, frictional velocity impulses; returns whether
    /// the velocities it wrote are finite.
    ///
    /// Gauss-Seidel in pair order: each pair is corrected with the positions its predecessors
    /// left, so a vertex in many contacts is not under-corrected as a Jacobi average would (a
    /// vertex lying on a layer touches a dozen triangles and edges). Sequential, so the same for
    /// any thread count; each correction keeps momentum on its own.
    fn repel(&mut self, next: &mut Kinematics, inv_mass: &[f32]) -> bool {
        let thickness = self.thickness as f64;
        self.near.clear();
        for (k, pair) in self.pairs.iter().enumerate() {
            // Pairs beyond twice the gap are out of the sweeps' reach (each moves a vertex by
            // at most the gap's shortfall).
            if pair.n != DVec3::ZERO && pair.gap(&next.pos) < 2.0 * thickness {
                self.near.push((k as u32, false));
            }
        }
        for sweep in 0..self.iterations {
            let mut any = false;
            for slot in &mut self.near {
                let pair = &self.pairs[slot.0 as usize];
                let g = pair.gap(&next.pos);
                if g >= thickness {
                    continue;
                }
                any = true;
                if sweep == 0 {
                    self.stats.contacts += 1;
                }
                slot.1 = true;
                if let Some(w) = inverse_mass(pair, inv_mass) {
                    let lambda = (thickness - g) / w;
                    for k in 0..4 {
                        let v = pair.verts[k] as usize;
                        let dx = inv_mass[v] as f64 * pair.c[k] * lambda * pair.n;
                        if dx != DVec3::ZERO {
                            next.pos.set(v, (next.pos.get(v).as_dvec3() + dx).as_vec3());
                        }
                    }
                }
            }
            if !any {
                break;
            }
        }
        let mut finite = true;
        let mu = self.friction as f64;
        for sweep in 0..self.iterations {
            for &(k, touched) in &self.near {
                if !touched {
                    continue;
                }
                let pair = &self.pairs[k as usize];
                let Some(w) = inverse_mass(pair, inv_mass) else {
                    continue;
                };
                let mut rel = DVec3::ZERO;
                for k in 0..4 {
                    rel += pair.c[k] * next.vel.get(pair.verts[k] as usize).as_dvec3();
                }
                let vn = rel.dot(pair.n);
                if vn >= 0.0 {
                    continue; // already separating
                }
                // Relative velocity change: -vn along n, and (in the first sweep) up to
                // mu |vn| against the sliding.
                let mut dv = -vn * pair.n;
                let tangential = rel - vn * pair.n;
                let speed = tangential.length();
                if sweep == 0 && speed > 0.0 {
                    dv -= tangential * (mu * -vn / speed).min(1.0);
                }
                for k in 0..4 {
                    let v = pair.verts[k] as usize;
                    let du = inv_mass[v] as f64 * pair.c[k] / w * dv;
                    if du != DVec3::ZERO {
                        let u = (next.vel.get(v).as_dvec3() + du).as_vec3();
                        next.vel.set(v, u);
                        finite &= u.is_finite();
                    }
                }
            }
        }
        finite
    }

    /// The cap (see the module's comment): scales displacements from `x0` until every pair's
    /// relative motion is below `APPROACH` of its distance at `x0`, less `eps`.
    fn cap(&mut self, x0: &Vec3s, next: &mut Kinematics, eps: f64) {
        let n = x0.len();
        self.scale.clear();
        self.scale.resize(n, 1.0);
        self.scale_next.clear();
        self.scale_next.resize(n, 1.0);
        let disp = |v: usize| next.pos.get(v).as_dvec3() - x0.get(v).as_dvec3();
        let start = |v: usize| x0.get(v).as_dvec3();
        let mut rounds = 0;
        loop {
            let mut violated = false;
            for pair in &self.pairs {
                let s = &self.scale;
                // The Lipschitz bound's relative motion `m`, and for the plane bound the least
                // gap along `n` at the end and the most approach along it.
                let (mut m, mut gap_end, mut approach) = (0.0f64, f64::INFINITY, 0.0f64);
                let mut slack_start = f64::INFINITY;
                for i in 0..pair.split {
                    let a = pair.verts[i] as usize;
                    let da = s[a] * disp(a);
                    for j in pair.split..4 {
                        let b = pair.verts[j] as usize;
                        let rel = da - s[b] * disp(b);
                        m = m.max(rel.length());
                        let base = (start(a) - start(b)).dot(pair.n);
                        gap_end = gap_end.min(base + rel.dot(pair.n));
                        approach = approach.max(-rel.dot(pair.n));
                        slack_start = slack_start.min(base);
                    }
                }
                let allowed = (APPROACH * pair.d0 - eps).max(0.0);
                let keep = (1.0 - APPROACH) * pair.d0 + eps;
                // Safe by either bound: relative motion below the distance, or the plane
                // through the closest points at the start separating the two at the end (and
                // so, by linearity, all along).
                if m > allowed && gap_end < keep {
                    violated = true;
                    let f = if rounds < SCALE_ROUNDS {
                        let lip = if m > 0.0 { allowed / m } else { 1.0 };
                        let plane = if approach > 0.0 {
                            ((slack_start - keep) / approach).max(0.0)
                        } else {
                            1.0
                        };
                        0.99 * lip.max(plane).min(1.0)
                    } else {
                        0.0
                    };
                    for &v in &pair.verts {
                        let v = v as usize;
                        self.scale_next[v] = self.scale_next[v].min(s[v] * f);
                    }
                }
            }
            if !violated {
                break;
            }
            rounds += 1;
            self.scale.copy_from_slice(&self.scale_next);
        }
        self.stats.max_cap_rounds = self.stats.max_cap_rounds.max(rounds);
        if rounds == 0 {
            return;
        }
        for &v in &self.topology.vertices {
            let v = v as usize;
            let s = self.scale[v];
            if s < 1.0 {
                let a = x0.get(v);
                let d = next.pos.get(v) - a;
                if d == Vec3::ZERO {
                    continue;
                }
                let b = &self.vertex_boxes[v];
                next.pos.set(v, (a + d * s as f32).clamp(b.min, b.max));
                next.vel.set(v, next.vel.get(v) * s as f32);
                self.stats.capped += 1;
                self.stats.stopped += (s == 0.0) as u64;
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.topology.heap_bytes()
            + (self.vertex_boxes.capacity()
                + self.tri_boxes.capacity()
                + self.edge_boxes.capacity())
                * size_of::<Aabb>()
            + self.tri_grid.heap_bytes()
            + self.edge_grid.heap_bytes()
            + self.pairs.capacity() * size_of::<Pair>()
            + self.near.capacity() * 8
            + (self.scale.capacity() + self.scale_next.capacity()) * 8
    }
}

/// `sum_i w_i c_i^2` of a pair, its inverse effective mass along the normal; None when no
/// vertex of it can move.
fn inverse_mass(pair: &Pair, inv_mass: &[f32]) -> Option<f64> {
    let w: f64 = (0..4)
        .map(|k| inv_mass[pair.verts[k] as usize] as f64 * pair.c[k] * pair.c[k])
        .sum();
    (w > 0.0).then_some(w)
}

/// Vertex `q[0]` against triangle `q[1..]` at positions `x`.
fn vertex_triangle(x: &Vec3s, q: [u32; 4]) -> Pair {
    let [p, a, b, c] = q.map(|v| x.get(v as usize).as_dvec3());
    let w = geometry::point_triangle(p, a, b, c);
    let gap = p - (w[0] * a + w[1] * b + w[2] * c);
    let fallback = || (b - a).cross(c - a).normalize_or_zero();
    finish(q, 1, [1.0, -w[0], -w[1], -w[2]], gap, fallback)
}

/// Edge `q[0..2]` against edge `q[2..]` at positions `x`.
fn edge_edge(x: &Vec3s, q: [u32; 4]) -> Pair {
    let [a, b, c, d] = q.map(|v| x.get(v as usize).as_dvec3());
    let (s, t) = geometry::segment_segment(a, b, c, d);
    let gap = (a + s * (b - a)) - (c + t * (d - c));
    let fallback = || (b - a).cross(d - c).normalize_or_zero();
    finish(q, 2, [1.0 - s, s, t - 1.0, -t], gap, fallback)
}

fn finish(
    verts: [u32; 4],
    split: usize,
    c: [f64; 4],
    gap: DVec3,
    fallback: impl Fn() -> DVec3,
) -> Pair {
    let d0 = gap.length();
    let n = if d0 > 0.0 { gap / d0 } else { fallback() };
    Pair {
        verts,
        split,
        c,
        n,
        d0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_weights_sum_to_zero_and_the_normal_points_from_the_triangle() {
        // Zero-sum weights are what make every correction keep momentum.
        let x0 = Vec3s::from_fn(4, |v| {
            [Vec3::new(0.2, 0.01, 0.2), Vec3::ZERO, Vec3::X, Vec3::Z][v]
        });
        let pair = vertex_triangle(&x0, [0, 1, 2, 3]);
        assert!((pair.d0 - 0.01).abs() < 1e-8, "{}", pair.d0);
        assert!((pair.n - DVec3::Y).length() < 1e-12);
        assert_eq!(pair.c.iter().sum::<f64>(), 0.0);
        let e = edge_edge(&x0, [0, 1, 2, 3]);
        assert!(e.c.iter().sum::<f64>().abs() < 1e-15);
    }

    /// Before the cutting and contact branches met, the pass rebuilt its mesh from the live
    /// particles alone, so the triangles a severed stroke runs through stayed in it as a
    /// surface stretched across the gap. It must keep apart exactly the drawn triangles.
    #[test]
    fn issue_15_the_mesh_it_keeps_apart_is_the_drawn_one_after_a_cut() {
        let scene = crate::Scene::builtin("hanging").unwrap();
        let (mut model, pos) = Model::new(scene).unwrap();
        let n = model.grid.len();
        let kin = Kinematics {
            pos,
            vel: Vec3s::zeros(n),
        };
        let mut next = Kinematics::zeros(n);
        next.copy_from(&kin);
        // Every spring between rows 3 and 4, as a stroke between them severs: the cells of rows
        // 3-4 lose their triangles.
        use crate::grid::SpringKind::{ShearAntiDiagonal, ShearDiagonal, StructuralJ};
        let (nx, grid) = (model.grid.nx, model.grid);
        let mut slots: Vec<_> = (0..nx).map(|i| (StructuralJ, grid.index(i, 3))).collect();
        for i in 0..nx - 1 {
            slots.push((ShearDiagonal, grid.index(i, 3)));
            slots.push((ShearAntiDiagonal, grid.index(i + 1, 3)));
        }
        assert!(model.sever(&slots) > 0);
        let drawn: Vec<[u32; 3]> = model.triangles().collect();
        assert!(drawn.len() < 2 * (nx - 1) * (model.grid.ny - 1));
        let mut pass = SelfCollision::new(1e-3, 0.0, 1);
        pass.apply(&model, &kin, &mut next);
        assert_eq!(pass.topology.triangles, drawn);
    }
}
