//! Self-collision: the cloth never passes through itself, and layers in contact are kept
//! about `thickness` apart, with Coulomb friction. The last pass of a substep (after the
//! colliders), present only when the scene has `[self_collision]`.
//!
//! Three stages on the substep's motion from `x0` (its start, assumed free of intersections) to
//! `x1` (what the integrator, pins and colliders made of it):
//!
//! 0. **Pairs** (`list.rs`, `search.rs`). Only pairs that can come within `thickness` in the
//!    substep are looked at, found one of two ways, chosen by the substep's motion alone:
//!    - *the pair list*, when no vertex strays far from the cloth's common motion (a resting,
//!      falling or slowly moving cloth): every pair closer than
//!      `needed = thickness + 2 (r + PUSH thickness)` at `x0`, `r` the most any vertex's
//!      displacement strays from the common one. The list reaches `SKIN thickness` farther
//!      and is kept until the cloth has moved too far for it (a Verlet list). If the
//!      repulsion or the cap then moves a vertex more than `PUSH thickness` away, the
//!      substep is redone the second way.
//!    - *the swept search*, otherwise: every pair whose boxes, swept from `x0` to `x1` and
//!      grown by `thickness / 2`, overlap and whose distance at `x0` is below `thickness`
//!      plus how far its vertices may end from where they start (`|x1 - x0| + thickness / 2`
//!      each: see the cap).
//!
//!    Either way the pairs looked at, and their order, are a function of the substep, so a
//!    restored state steps exactly as the one it was saved from.
//! 1. **Repulsion** (soft, what keeps the gap). For each pair (a vertex and a triangle without
//!    it, or two edges with no shared vertex), the closest points at `x0` (`geometry.rs`) give weights `c_i` with `sum c_i = 0` and a
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
//!    vertex is also kept within `thickness / 2` of its straight path from `x0` to `x1` (a
//!    capsule, inside its grown swept box), so a pair the swept search did not look at stays
//!    apart: either their boxes are disjoint, or they were farther at `x0` than their
//!    capsules reach. A capsule rather than the box because its reach from `x0` is
//!    `|x1 - x0| + thickness / 2`, against `|x1 - x0| + sqrt(3) thickness / 2` to the box's
//!    corner: in a layered cloth the pairs within reach grow with its square, so the capsule
//!    looks at about half as many. A pair the list leaves out is farther than `needed` at `x0`, and
//!    no vertex strayed more than `r + PUSH thickness` (checked at the end), so it stays
//!    `thickness` apart. Capped vertices get their velocity scaled by `s` too.
//!    With no triangle pair in contact at the start, none touches at any time of any substep:
//!    two triangles sharing no vertex can only start to intersect through a vertex touching a
//!    face or an edge touching an edge.
//!
//! A list build and a swept search allocate (per parallel task), and so do the parallel
//! filters of the repulsion and the cap when there are pairs; a substep with no pair on a kept
//! list does not. Everything parallel is a map in item order or an exact reduction (min, max); all
//! updates are sequential in pair order, so the result is bitwise the same for any thread
//! count.

mod geometry;
mod hash;
mod list;
mod pair;
mod search;
mod topology;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::model::Model;
use crate::soa::Vec3s;
use crate::state::Kinematics;
use hash::Aabb;
use list::{PairList, Spread};
use pair::{inverse_mass, Pair};
use search::Broad;
use topology::Topology;

/// Fraction of a pair's distance at the start of a substep that its relative motion may close
/// within it. Close to 1 so that the cap seldom acts (the repulsion keeps pairs at
/// `thickness`, and only a relative motion of 0.9 `thickness` per substep reaches the cap);
/// below 1 so that a pair keeps a tenth of its distance, far above float32 round-off.
const APPROACH: f64 = 0.9;

/// Rounds of proportional scaling before the cap stops the vertices of the pairs still too
/// fast. More rounds keep more motion in a tangle of contacts, at one pass over the pairs each.
const SCALE_ROUNDS: u32 = 8;

/// How far, as a fraction of `thickness`, the repulsion and the cap may move a vertex away from
/// the cloth's common motion within a substep before the substep is redone with the swept
/// search. Every pair that this much motion could bring within `thickness` is looked at; more
/// looks at more pairs in every substep, less redoes more substeps.
const PUSH: f64 = 0.25;

/// How much farther than a substep needs the pair list reaches, as a fraction of `thickness`:
/// the relative motion the cloth may make before the list is built again. More keeps the list
/// longer, at more pairs looked at in every substep.
const SKIN: f64 = 1.0;

/// The farthest, as a multiple of `thickness`, that a substep may need to look for the pair list
/// to be built for it. A list reaching farther holds many more pairs than the swept search
/// finds (their number grows with the square of the reach in a layered cloth), so a substep
/// whose motion needs more uses the swept search instead.
const LIST_LIMIT: f64 = 2.0;

/// What the pass did, summed since the simulation was built.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SelfCollisionStats {
    /// Substeps the pass ran.
    pub substeps: u64,
    /// Pairs looked at, summed over substeps.
    pub pairs: u64,
    /// Times the pair list was built.
    pub rebuilds: u64,
    /// Substeps that used the swept search: their motion needed more than the list reaches,
    /// or (`redone`) they were redone because the repulsion or the cap moved a vertex farther
    /// than the list allowed for.
    pub swept_substeps: u64,
    pub redone: u64,
    /// Pairs closer than `thickness` after the integrator (the repulsion's first sweep).
    pub contacts: u64,
    /// Vertices whose displacement the cap shortened, summed over substeps.
    pub capped: u64,
    /// Of those, vertices the cap stopped altogether.
    pub stopped: u64,
    /// Most cap rounds one substep took.
    pub max_cap_rounds: u32,
    /// Smallest distance at the start of a substep between a vertex and a triangle without it,
    /// or two edges with no shared vertex, among the pairs looked at (m; infinite if none).
    pub min_distance: f64,
}

impl Default for SelfCollisionStats {
    fn default() -> Self {
        SelfCollisionStats {
            substeps: 0,
            pairs: 0,
            rebuilds: 0,
            swept_substeps: 0,
            redone: 0,
            contacts: 0,
            capped: 0,
            stopped: 0,
            max_cap_rounds: 0,
            min_distance: f64::INFINITY,
        }
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
    /// Each vertex's grown swept box this substep.
    vertex_boxes: Vec<Aabb>,
    /// Each vertex's end of its path this substep, as the integrator left it (`x1`): with
    /// `x0` and `path_radius`, the capsule it is kept in.
    path_ends: Vec<Vec3>,
    /// The capsules' radius this substep (m): `thickness / 2` and a round-off margin.
    path_radius: f32,
    /// Each vertex's box for building the pair list.
    search_boxes: Vec<Aabb>,
    broad: Broad,
    list: PairList,
    pairs: Vec<Pair>,
    /// The vertices of this substep's pairs as the integrator left them, to redo it from.
    saved: Vec<(u32, Vec3, Vec3)>,
    marked: Vec<bool>,
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
            path_ends: Vec::new(),
            path_radius: 0.0,
            search_boxes: Vec::new(),
            broad: Broad::default(),
            list: PairList::default(),
            pairs: Vec::new(),
            saved: Vec::new(),
            marked: Vec::new(),
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
            self.list.clear();
            self.marked = vec![false; model.grid.len()];
        }
        let (x0, inv_mass) = (&start.pos, &model.particles.inv_mass);
        let verts = &self.topology.vertices;
        let Some(survey) = Survey::of(verts, x0, &next.pos, self.list.anchor()) else {
            return false;
        };
        let (reach, motion) = (survey.reach, survey.motion);
        // A margin above float32 round-off of coordinates up to `reach` (8 ulps and more).
        let eps = 1e-6 * (1.0 + reach);
        let before = self.stats;
        self.stats.substeps += 1;
        // The pairs this substep looks at: those that can come closer than `thickness`. A pair
        // farther than `needed` at the start cannot, while no vertex strays more than
        // `allowed` from the cloth's common motion (twice that, the most any pair closes).
        let thickness = self.thickness as f64;
        let allowed = motion.radius() + PUSH * thickness;
        let needed = thickness + 2.0 * allowed + eps;
        // Which pairs a substep looks at depends on the substep alone, never on when the list
        // was built, so a restored state steps exactly as the original.
        let finite = if needed <= LIST_LIMIT * thickness {
            let mut drift = survey.drift.map_or(0.0, |d| d.radius()) + eps;
            if !self.list.covers(survey.drift, needed, eps) {
                self.rebuild_list(x0, needed + SKIN * thickness, eps as f32);
                drift = eps;
            }
            self.listed_pairs(x0, needed, drift);
            if self.pairs.is_empty() {
                return true;
            }
            self.sweep_boxes(x0, &next.pos, eps as f32);
            self.save_listed(next);
            let finite = self.resolve(x0, next, inv_mass, eps);
            // Only the pairs' vertices moved from where the integrator left them.
            let mut moved = motion;
            for &(v, ..) in &self.saved {
                let v = v as usize;
                moved.add(next.pos.get(v).as_dvec3() - x0.get(v).as_dvec3());
            }
            if moved.radius() <= allowed {
                finite
            } else {
                // The repulsion or the cap moved a vertex farther than the list allowed for.
                self.redo_loose(x0, next, inv_mass, eps, before)
            }
        } else {
            self.stats.swept_substeps += 1;
            self.sweep_boxes(x0, &next.pos, eps as f32);
            self.swept_pairs(x0, eps);
            self.resolve(x0, next, inv_mass, eps)
        };
        self.stats.pairs += self.pairs.len() as u64;
        if let Some(d) = self.pairs.iter().map(|p| p.d0).min_by(f64::total_cmp) {
            self.stats.min_distance = self.stats.min_distance.min(d);
        }
        finite
    }

    /// Each vertex's box, swept from `x0` to `x1` and grown by `thickness / 2 + eps`, what the
    /// swept search overlaps; and its path's end `x1`, for the capsule the pass keeps it in.
    fn sweep_boxes(&mut self, x0: &Vec3s, x1: &Vec3s, eps: f32) {
        self.path_radius = 0.5 * self.thickness + eps;
        let grow = Vec3::splat(self.path_radius);
        self.vertex_boxes.resize(x0.len(), Aabb::EMPTY);
        self.path_ends.resize(x0.len(), Vec3::ZERO);
        self.vertex_boxes
            .par_iter_mut()
            .zip(self.path_ends.par_iter_mut())
            .enumerate()
            .for_each(|(v, (b, end))| {
                let (a, c) = (x0.get(v), x1.get(v));
                *b = Aabb {
                    min: a.min(c) - grow,
                    max: a.max(c) + grow,
                };
                *end = c;
            });
    }

    /// `p` moved into vertex `v`'s capsule: the points within `path_radius` of its path from
    /// `x0` to `x1`, and (against round-off) inside its box.
    #[inline]
    fn kept_on_path(&self, v: usize, x0: &Vec3s, p: Vec3) -> Vec3 {
        let (a, d) = (x0.get(v), self.path_ends[v] - x0.get(v));
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - a).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let on_path = a + t * d;
        let off = p - on_path;
        let r = self.path_radius;
        let p = if off.length_squared() > r * r {
            on_path + off * (r / off.length())
        } else {
            p
        };
        let b = &self.vertex_boxes[v];
        p.clamp(b.min, b.max)
    }

    /// Lists every pair closer than `reach` at `x0`.
    fn rebuild_list(&mut self, x0: &Vec3s, reach: f64, eps: f32) {
        let grow = Vec3::splat(0.5 * reach as f32 + eps);
        let mut boxes = std::mem::take(&mut self.search_boxes);
        boxes.clear();
        boxes.extend((0..x0.len()).map(|v| {
            let p = x0.get(v);
            Aabb {
                min: p - grow,
                max: p + grow,
            }
        }));
        let keep = |p: &Pair| p.d0 < reach;
        self.broad
            .search(&self.topology, &boxes, x0, keep, &mut self.pairs);
        self.search_boxes = boxes;
        let found = self.pairs.iter().map(|p| (p.candidate(), p.d0)).collect();
        self.list.rebuild(x0, reach, found);
        self.stats.rebuilds += 1;
    }

    /// The listed pairs closer than `needed` at `x0`, with their closest points there, ordered
    /// by their vertices (the same whenever the list was built, so the result depends on the
    /// substep alone). A pair that was `d` apart at the anchor is at least `d - 2 drift` apart
    /// now, so only the list's nearest need a look.
    fn listed_pairs(&mut self, x0: &Vec3s, needed: f64, drift: f64) {
        let near = self.list.within(needed + 2.0 * drift);
        self.pairs.clear();
        self.pairs.par_extend(near.par_iter().map(|c| c.at(x0)));
        self.pairs.retain(|p| p.d0 < needed);
        self.pairs.sort_unstable_by_key(|p| p.candidate().key());
    }

    /// The swept search, for a substep whose motion the list does not cover: every pair whose
    /// swept boxes overlap and which the motion its vertices' capsules allow could bring
    /// within `thickness`. A vertex ends the substep in its capsule, so a pair at `d0` whose
    /// vertices' capsules reach at most `l_a` and `l_b` from where they start stays
    /// `d0 - l_a - l_b` apart.
    fn swept_pairs(&mut self, x0: &Vec3s, eps: f64) {
        let (boxes, thickness) = (&self.vertex_boxes, self.thickness as f64);
        let (ends, radius) = (&self.path_ends, self.path_radius as f64);
        let reach = |v: u32| {
            let v = v as usize;
            (ends[v] - x0.get(v)).as_dvec3().length() + radius
        };
        let keep = |pair: &Pair| {
            let (a, b) = pair.verts.split_at(pair.split);
            let side = |s: &[u32]| s.iter().map(|&v| reach(v)).fold(0.0, f64::max);
            pair.d0 < thickness + side(a) + side(b) + eps
        };
        self.broad
            .search(&self.topology, boxes, x0, keep, &mut self.pairs);
    }

    /// Redoes the substep from where the integrator left it with the swept search (`before`:
    /// the statistics to count it from).
    fn redo_loose(
        &mut self,
        x0: &Vec3s,
        next: &mut Kinematics,
        inv_mass: &[f32],
        eps: f64,
        before: SelfCollisionStats,
    ) -> bool {
        self.restore_listed(next);
        self.stats = before;
        self.stats.substeps += 1;
        self.stats.swept_substeps += 1;
        self.stats.redone += 1;
        self.swept_pairs(x0, eps);
        self.resolve(x0, next, inv_mass, eps)
    }

    /// Keeps the positions and velocities of the pairs' vertices, the only ones the pass
    /// changes, so that a substep can be redone.
    fn save_listed(&mut self, next: &Kinematics) {
        self.saved.clear();
        for pair in &self.pairs {
            for &v in &pair.verts {
                if !std::mem::replace(&mut self.marked[v as usize], true) {
                    let v = v as usize;
                    self.saved
                        .push((v as u32, next.pos.get(v), next.vel.get(v)));
                }
            }
        }
        for &(v, ..) in &self.saved {
            self.marked[v as usize] = false;
        }
    }

    fn restore_listed(&self, next: &mut Kinematics) {
        for &(v, x, u) in &self.saved {
            next.pos.set(v as usize, x);
            next.vel.set(v as usize, u);
        }
    }

    /// The repulsion, each touched vertex put back inside its box, and the cap.
    fn resolve(&mut self, x0: &Vec3s, next: &mut Kinematics, inv_mass: &[f32], eps: f64) -> bool {
        let finite = self.repel(next, inv_mass);
        // Back inside each vertex's capsule, what the swept search allows for.
        for &(k, touched) in &self.near {
            if touched {
                for &v in &self.pairs[k as usize].verts {
                    let p = self.kept_on_path(v as usize, x0, next.pos.get(v as usize));
                    next.pos.set(v as usize, p);
                }
            }
        }
        self.cap(x0, next, eps);
        finite
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
        // Pairs beyond twice the gap are out of the sweeps' reach (each moves a vertex by at
        // most the gap's shortfall). An ordered parallel filter: the same for any thread count.
        let pos = &next.pos;
        self.near.par_extend(
            self.pairs
                .par_iter()
                .enumerate()
                .with_min_len(1024)
                .filter(|(_, pair)| pair.n != DVec3::ZERO && pair.gap(pos) < 2.0 * thickness)
                .map(|(k, _)| (k as u32, false)),
        );
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
        let mut rounds = 0;
        loop {
            // Each pair's factor depends only on the scales of the round before (a Jacobi
            // round), so the pairs are checked in parallel; taking the least factor per vertex
            // is exact whatever the order.
            let (s, pos) = (&self.scale, &next.pos);
            let violations: Vec<(u32, f64)> = self
                .pairs
                .par_iter()
                .enumerate()
                .with_min_len(1024)
                .filter_map(|(k, pair)| {
                    cap_factor(pair, s, x0, pos, eps, rounds).map(|f| (k as u32, f))
                })
                .collect();
            let violated = !violations.is_empty();
            for (k, f) in violations {
                for &v in &self.pairs[k as usize].verts {
                    let v = v as usize;
                    self.scale_next[v] = self.scale_next[v].min(self.scale[v] * f);
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
                // Toward `x0` stays in the (convex) capsule; kept there against round-off.
                next.pos.set(v, self.kept_on_path(v, x0, a + d * s as f32));
                next.vel.set(v, next.vel.get(v) * s as f32);
                self.stats.capped += 1;
                self.stats.stopped += (s == 0.0) as u64;
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.topology.heap_bytes()
            + (self.vertex_boxes.capacity() + self.search_boxes.capacity()) * size_of::<Aabb>()
            + self.path_ends.capacity() * size_of::<Vec3>()
            + self.broad.heap_bytes()
            + self.list.heap_bytes()
            + self.pairs.capacity() * size_of::<Pair>()
            + self.saved.capacity() * size_of::<(u32, Vec3, Vec3)>()
            + self.marked.capacity()
            + self.near.capacity() * 8
            + (self.scale.capacity() + self.scale_next.capacity()) * 8
    }
}

/// The factor the cap scales a pair's vertices' displacements by in round `round`, given the
/// scales `s` so far, or None when the pair is safe by either bound (see the module's comment).
#[inline]
fn cap_factor(pair: &Pair, s: &[f64], x0: &Vec3s, x: &Vec3s, eps: f64, round: u32) -> Option<f64> {
    let disp = |v: usize| x.get(v).as_dvec3() - x0.get(v).as_dvec3();
    let start = |v: usize| x0.get(v).as_dvec3();
    // The Lipschitz bound's relative motion `m`, and for the plane bound the least gap along
    // `n` at the end and the most approach along it.
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
    // Safe by either bound: relative motion below the distance, or the plane through the
    // closest points at the start separating the two at the end (and so, by linearity, all
    // along).
    if m <= allowed || gap_end >= keep {
        return None;
    }
    Some(if round < SCALE_ROUNDS {
        let lip = if m > 0.0 { allowed / m } else { 1.0 };
        let plane = if approach > 0.0 {
            ((slack_start - keep) / approach).max(0.0)
        } else {
            1.0
        };
        0.99 * lip.max(plane).min(1.0)
    } else {
        0.0
    })
}

/// What one pass over the mesh's vertices finds of a substep.
#[derive(Clone, Copy)]
struct Survey {
    /// The largest coordinate at the start or the end, in m.
    reach: f64,
    /// The bounding box of the displacements `x1 - x0`.
    motion: Spread,
    /// The bounding box of the displacements from the pair list's anchor to `x0`, if it has one.
    drift: Option<Spread>,
}

impl Survey {
    /// None if a position at `x0` or `x1` is not finite.
    fn of(verts: &[u32], x0: &Vec3s, x1: &Vec3s, anchor: Option<&Vec3s>) -> Option<Survey> {
        let empty = Survey {
            reach: 0.0,
            motion: Spread::default(),
            drift: anchor.map(|_| Spread::default()),
        };
        verts
            .par_iter()
            .with_min_len(4096)
            .map(|&v| {
                let (a, b) = (x0.get(v as usize), x1.get(v as usize));
                (a.is_finite() && b.is_finite()).then(|| Survey {
                    reach: a.abs().max_element().max(b.abs().max_element()) as f64,
                    motion: Spread::of(b.as_dvec3() - a.as_dvec3()),
                    drift: anchor.map(|x| Spread::of(a.as_dvec3() - x.get(v as usize).as_dvec3())),
                })
            })
            .reduce(
                || Some(empty),
                |p, q| {
                    let (p, q) = (p?, q?);
                    Some(Survey {
                        reach: p.reach.max(q.reach),
                        motion: p.motion.union(q.motion),
                        drift: p.drift.zip(q.drift).map(|(a, b)| a.union(b)),
                    })
                },
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap alone on the motion from `x0` to `x1` of the mesh `triangles`, as `apply` runs
    /// it after the repulsion: the swept search's pairs, then `cap`. Returns where the vertices
    /// end and the pass's statistics. The repulsion is left out on purpose: it keeps pairs at
    /// `thickness` on its own and would hide what the cap guarantees.
    fn cap_only(
        triangles: Vec<[u32; 3]>,
        x0: &Vec3s,
        x1: &Vec3s,
        thickness: f32,
    ) -> (Vec3s, SelfCollisionStats) {
        let n = x0.len();
        let mut pass = SelfCollision::new(thickness, 0.0, 1);
        pass.topology.rebuild(0, n, triangles);
        // The round-off margin `apply` would use.
        let survey = Survey::of(&pass.topology.vertices, x0, x1, None).unwrap();
        let eps = 1e-6 * (1.0 + survey.reach);
        pass.sweep_boxes(x0, x1, eps as f32);
        pass.swept_pairs(x0, eps);
        assert!(!pass.pairs.is_empty(), "nothing for the cap to look at");
        let mut next = Kinematics {
            pos: Vec3s::from_fn(n, |v| x1.get(v)),
            vel: Vec3s::zeros(n),
        };
        pass.cap(x0, &mut next, eps);
        (next.pos, pass.stats)
    }

    /// A horizontal triangle of 1 cm legs at height `y` (m), its vertices `first..first + 3`.
    fn flat_triangle(first: u32, y: f32) -> ([u32; 3], [Vec3; 3]) {
        let corners = [
            Vec3::new(0.0, y, 0.0),
            Vec3::new(0.01, y, 0.0),
            Vec3::new(0.0, y, 0.01),
        ];
        ([first, first + 1, first + 2], corners)
    }

    /// A vertex 1 mm above a still triangle, moved 3 mm down within one substep, through it.
    /// The cap lets a pair close at most `APPROACH` of its starting distance, so the vertex
    /// must stop at least `(1 - APPROACH) 1 mm = 0.1 mm` above the triangle's plane (0.109 mm:
    /// the proportional round scales by 0.99 of the bound). A cap that let the pair close all
    /// of its distance would leave it a round-off margin from touching.
    #[test]
    fn the_cap_stops_a_vertex_a_tenth_of_its_distance_above_a_triangle() {
        let (below, corners) = flat_triangle(0, 0.0);
        // The vertex (3) is the corner of a triangle whose other corners stand still 5 cm up.
        let start = [
            corners[0],
            corners[1],
            corners[2],
            Vec3::new(0.002, 0.001, 0.002),
            Vec3::new(0.002, 0.05, 0.03),
            Vec3::new(0.03, 0.05, 0.002),
        ];
        let x0 = Vec3s::from_fn(6, |v| start[v]);
        let x1 = Vec3s::from_fn(6, |v| {
            start[v] - (v == 3) as u8 as f32 * Vec3::new(0.0, 0.003, 0.0)
        });
        let (end, stats) = cap_only(vec![below, [3, 4, 5]], &x0, &x1, 0.0005);
        let height = end.get(3).y;
        assert!(
            height >= 1e-4,
            "the vertex ended {height} m above the triangle: {stats:?}"
        );
        // It did move down, most of the way the bound allows (not stopped dead).
        assert!(
            height < 2e-4,
            "the vertex ended {height} m above the triangle"
        );
        assert_eq!((0..3).map(|v| end.get(v)).collect::<Vec<_>>(), corners);
    }

    /// 41 triangles stacked 1 mm apart, the bottom one still and the 40 above it all moved
    /// 10 mm down within one substep. Each pair may close at most 0.9 of its distance, and the
    /// proportional rounds, one Jacobi sweep each, settle the stack from the bottom up a few
    /// layers per round: `SCALE_ROUNDS` rounds are not enough, and the stopping round (`s = 0`
    /// for every vertex still in a fast pair) is what keeps the upper layers from passing
    /// through the ones the earlier rounds slowed. Every layer must end at least a tenth of
    /// their 1 mm above the one below.
    #[test]
    fn the_cap_keeps_every_layer_of_a_falling_stack_above_the_one_below() {
        let layers = 41;
        let (mut triangles, mut start) = (Vec::new(), Vec::new());
        for k in 0..layers {
            let (t, corners) = flat_triangle(3 * k, 0.001 * k as f32);
            triangles.push(t);
            start.extend(corners);
        }
        let x0 = Vec3s::from_fn(start.len(), |v| start[v]);
        let drop = Vec3::new(0.0, 0.01, 0.0);
        let x1 = Vec3s::from_fn(start.len(), |v| start[v] - (v >= 3) as u8 as f32 * drop);
        let (end, stats) = cap_only(triangles, &x0, &x1, 0.0005);
        for k in 1..layers as usize {
            for corner in 0..3 {
                let (v, below) = (3 * k + corner, 3 * (k - 1) + corner);
                let gap = end.get(v).y - end.get(below).y;
                assert!(gap >= 1e-4, "layer {k} ends {gap} m above layer {}", k - 1);
            }
        }
        // What the test is for: the proportional rounds were not enough.
        assert!(
            stats.max_cap_rounds > SCALE_ROUNDS && stats.stopped > 0,
            "the stack did not reach the stopping round: {stats:?}"
        );
    }

    /// The capsule a vertex is kept in: a point within `path_radius` of the straight path
    /// from `x0` to `x1` stays where it is; one farther is brought onto the capsule, so that
    /// it ends no farther from `x0` than `|x1 - x0| + path_radius`, the reach the swept
    /// search's filter counts on.
    #[test]
    fn a_vertex_is_kept_within_its_capsule_and_box() {
        let x0 = Vec3s::from_fn(1, |_| Vec3::new(1.0, 2.0, 3.0));
        let x1 = Vec3s::from_fn(1, |_| Vec3::new(1.01, 2.0, 3.0));
        let mut pass = SelfCollision::new(0.004, 0.0, 1);
        pass.sweep_boxes(&x0, &x1, 1e-7);
        let r = pass.path_radius;
        let (a, c) = (x0.get(0), x1.get(0));
        let inside = Vec3::new(1.005, 2.0015, 3.0);
        assert_eq!(pass.kept_on_path(0, &x0, inside), inside);
        // A box corner is inside the box but outside the capsule: sqrt(2) r off the path.
        let corner = Vec3::new(1.005, 2.0 + r, 3.0 + r);
        let kept = pass.kept_on_path(0, &x0, corner);
        // Up to round-off of coordinates near 3 (the pass's `eps` allows for 1e-6 per unit).
        let round_off = 1e-6;
        let off_path = (kept - Vec3::new(kept.x, 2.0, 3.0)).length();
        assert!(off_path <= r + round_off, "{off_path} > {r}");
        assert!((kept.x - 1.005).abs() < 1e-6);
        // Far beyond the end: onto the end's cap, at most |x1 - x0| + r from the start.
        for far in [Vec3::new(2.0, 2.5, 3.0), Vec3::new(0.0, 1.0, 4.0)] {
            let kept = pass.kept_on_path(0, &x0, far);
            let reach = (c - a).length() + r;
            assert!((kept - a).length() <= reach + round_off, "{kept}");
            let b = pass.vertex_boxes[0];
            assert_eq!(kept.clamp(b.min, b.max), kept);
        }
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
