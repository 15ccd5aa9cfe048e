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
//!      displacement strays from the common one. The repulsion and the cap look first at those
//!      of them that the substep's motion may bring within `(1 + HOT) thickness`, and at the
//!      others only where they have not shown that those cannot act (see `Cold`), so the list
//!      holds every pair closer than `(1 + HOT) thickness + 2 r`, searched for the rest when
//!      they are needed. It reaches `SKIN thickness` farther and is kept until the cloth has
//!      moved too far for it (a Verlet list); then the pairs of the vertices that moved most
//!      are searched for again, or, when they are many, all pairs. If the repulsion or the
//!      cap then moves a vertex more than `PUSH thickness` away, the substep is redone the
//!      second way.
//!    - *the swept search*, otherwise: every pair whose boxes, swept from `x0` to `x1` and
//!      grown by `thickness / 2`, overlap and whose distance at `x0` is below `thickness`
//!      plus how far its vertices may end from where they start (`|x1 - x0| + thickness / 2`
//!      each: see the capsule).
//!
//!    Either way the pairs looked at, and their order, are a function of the substep, so a
//!    restored state steps exactly as the one it was saved from.
//! 1. **Repulsion** (soft, what keeps the gap; `repulsion.rs`): Gauss-Seidel sweeps push every
//!    pair closer than `thickness` apart along the normal between their closest points at
//!    `x0`, then take away their approaching relative velocity, with Coulomb friction.
//! 2. **The cap** (hard, what makes the guarantee; `cap.rs`): scales the displacement of the
//!    vertices of every pair whose relative motion could close its distance at `x0` toward
//!    `x0`, until none can.
//!
//! **The capsule** (`capsule.rs`). Each vertex is also kept within `thickness / 2` of its
//! straight path from `x0` to `x1`, so the pairs neither way of finding them looks at stay
//! apart, and with no triangle pair in contact at the start none touches at any time of any
//! substep.
//!
//! A list build and a swept search allocate (per parallel task), and so do the parallel
//! filters of the repulsion and the cap when there are pairs; a substep with no pair on a kept
//! list does not. Everything parallel is a map in item order or an exact reduction (min, max); all
//! updates are sequential in pair order, so the result is bitwise the same for any thread
//! count.

mod bvh;
mod cap;
mod capsule;
mod geometry;
mod in_solve;
mod list;
mod pair;
mod parts;
mod repulsion;
mod search;
mod topology;

pub use in_solve::Apart;
pub use pair::Pair;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::model::Model;
use crate::soa::Vec3s;
use crate::state::Kinematics;
use bvh::Aabb;
use list::{PairList, Spread};
use search::{Broad, Looked, Order, Reuse};
use std::time::Instant;
use topology::Topology;

/// How far, as a fraction of `thickness`, the repulsion and the cap may move a vertex away from
/// the cloth's common motion within a substep before the substep is redone with the swept
/// search. Every pair that this much motion could bring within `thickness` is looked at; more
/// looks at more pairs in every substep, less redoes more substeps.
const PUSH: f64 = 0.25;

/// How much farther than a substep needs the pair list reaches, as a fraction of `thickness`:
/// the relative motion the cloth may make before some of its vertices are queried again. More
/// keeps the list longer, at more pairs found by each search and filtered in every substep
/// (chosen by the settling pile's cost at 64 x 64 and 128 x 128, docs/notes/contact.md,
/// "Before the scenes moved to display-frame steps").
const SKIN: f64 = 0.75;

/// The farthest, as a multiple of `thickness`, that a substep may need to look for the pair list
/// to be built for it. A list reaching farther holds many more pairs than the swept search
/// finds (their number grows with the square of the reach in a layered cloth), so a substep
/// whose motion needs more uses the swept search instead.
const LIST_LIMIT: f64 = 2.0;

/// When a vertex passes the bound the pair list allows it, the vertices past this fraction of
/// the bound are queried again, each from where it is, instead of the whole mesh: less queries
/// more vertices at once, and less often.
const REQUERY_AT: f64 = 0.5;

/// The largest share of the mesh's vertices queried again on their own; with more, the whole
/// list is built again, which then costs about as much (chosen by the pile's cost,
/// docs/notes/contact.md, "Before the scenes moved to display-frame steps").
const REQUERY_MOST: f64 = 0.1;

/// How near, beyond `thickness` and as a fraction of it, a pair must be able to come in a
/// substep on the pair list for the substep to give it its closest points and the repulsion and
/// the cap to look at it; the list holds only such pairs. The pairs left out cannot act unless
/// the repulsion moves a vertex more than half of this, or the cap acts at all; the substep
/// then looks at them too (and first lists them). More lists and looks at more pairs in every
/// substep, less looks at all of them more often (0.1 did so in every substep of the settling
/// 64 x 64 pile; chosen by the piles' and freefall's cost, docs/notes/contact.md, "2026-12-05:
/// the pile's substeps look only at the pairs their motion can bring near"). At most `2 PUSH`,
/// what the substep needs.
const HOT: f64 = 0.25;

/// What the pass did, summed since the simulation was built.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SelfCollisionStats {
    /// Substeps the pass ran.
    pub substeps: u64,
    /// Pairs looked at (given their closest points), summed over substeps. On the pair list,
    /// the listed pairs that can come within `thickness` and `HOT` of it, or all that can come
    /// within `thickness` in a substep where those others had to be looked at too (`widened`).
    pub pairs: u64,
    /// Substeps on the pair list that had to look at every pair within reach, the repulsion
    /// or the cap having shown that the pairs left out could act.
    pub widened: u64,
    /// Times the pair list was built, and times some of its vertices were queried again
    /// instead (`requeries`; `requeried` of them, summed).
    pub rebuilds: u64,
    pub requeries: u64,
    pub requeried: u64,
    /// Substeps that used the swept search: their motion needed more than the list reaches,
    /// or (`redone`) they were redone because the repulsion or the cap moved a vertex farther
    /// than the list allowed for.
    pub swept_substeps: u64,
    pub redone: u64,
    /// Swept searches run ahead of implicit Euler's solves (`in_solve.rs`): those the list of
    /// the pairs near enough to matter ahead did not hold every pair of, the steps whose pairs
    /// ahead that list gave instead (`ahead_from_list`; not counted: the steps it showed to
    /// have none), and the times it was built.
    pub ahead_searches: u64,
    pub ahead_from_list: u64,
    pub ahead_rebuilds: u64,
    /// Steps whose pairs ahead the list showed all too far apart for the solve to hold any,
    /// left out ([`Apart`]: no search, no closest points), and of those the steps whose solve
    /// then moved the cloth far enough to ask for them (the step is solved again with them).
    pub ahead_apart: u64,
    pub ahead_asked: u64,
    /// Solves given the last pairs ahead again, from the same start along the same paths ahead,
    /// bit for bit (a substep's passes run again, the solve holding what the pass moved): not
    /// searched or listed again.
    pub ahead_again: u64,
    /// Substeps whose pass after the solve took its pairs from the step's one search (the
    /// search ahead widened by each vertex's budget, `in_solve.rs`) instead of a search of its
    /// own, and the vertices it looked up on their own there, having ended outside their
    /// budget (summed).
    pub pass_from_ahead: u64,
    pub pass_outside: u64,
    /// Pairs closer than `thickness` after the integrator (the repulsion's first sweep).
    pub contacts: u64,
    /// Vertices whose displacement the cap shortened, summed over substeps.
    pub capped: u64,
    /// Of those, vertices the cap stopped altogether.
    pub stopped: u64,
    /// Most cap rounds one substep took.
    pub max_cap_rounds: u32,
    /// Substeps the pass ended with more energy than the cloth had at their start plus the
    /// work done on it, drawn back along their own paths until they did not
    /// (`Pipeline::keep_contact_passive`).
    pub drawn_back: u64,
    /// Smallest distance at the start of a substep between a vertex and a triangle without it,
    /// or two edges with no shared vertex, among the pairs looked at (m; infinite if none).
    pub min_distance: f64,
    /// The work the searches did and the time each stage took (flattened into the same
    /// dict in Python): a substep redone keeps its abandoned attempt's, not its counts.
    #[serde(flatten)]
    pub effort: SelfCollisionEffort,
}

/// The work the pass did and the time it took, summed over substeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SelfCollisionEffort {
    /// Boxes the searches tested (tree nodes and primitives), summed over searches.
    pub boxes_tested: u64,
    /// Pairs whose boxes overlapped in a search (the primitives' tight boxes then pass over
    /// those too far apart, the rest get their closest points).
    pub candidates: u64,
    /// Wall time of each stage, summed over substeps (s): finding the pairs (the searches,
    /// the list's upkeep and the pairs' closest points), the repulsion (with each touched
    /// vertex put back in its capsule), the cap, and the substeps redone with the swept search
    /// (all of their stages). Measured, so not the same from run to run.
    pub search_seconds: f64,
    pub repulsion_seconds: f64,
    pub cap_seconds: f64,
    pub redo_seconds: f64,
}

impl Default for SelfCollisionStats {
    fn default() -> Self {
        SelfCollisionStats {
            substeps: 0,
            pairs: 0,
            widened: 0,
            rebuilds: 0,
            requeries: 0,
            requeried: 0,
            swept_substeps: 0,
            redone: 0,
            ahead_searches: 0,
            ahead_from_list: 0,
            ahead_rebuilds: 0,
            ahead_apart: 0,
            ahead_asked: 0,
            ahead_again: 0,
            pass_from_ahead: 0,
            pass_outside: 0,
            contacts: 0,
            capped: 0,
            stopped: 0,
            max_cap_rounds: 0,
            drawn_back: 0,
            min_distance: f64::INFINITY,
            effort: SelfCollisionEffort::default(),
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
    /// The penalty implicit Euler's solve holds the pairs ahead of it apart with, as a multiple
    /// of a pair's effective mass over the step squared; 0 without the term (`in_solve.rs`).
    pub solve_stiffness: f32,
    /// The pairs ahead of the solve (`in_solve.rs`), and where the inertial motion takes each
    /// vertex.
    ahead_pairs: Vec<Pair>,
    ahead: Vec3s,
    /// Where the pairs ahead were found, while the search keeps its candidates (`ahead_kept`):
    /// a swept search from there, bit for bit, takes over their closest points.
    ahead_from: Vec3s,
    ahead_kept: bool,
    /// The start and the paths' ends of the last pairs ahead, while those pairs are what a
    /// search from them gives (`ahead_again`): not where they were left out as too far apart,
    /// whose solve may ask for them.
    again_from: Vec3s,
    again_ahead: Vec3s,
    ahead_again: bool,
    /// The step's one search (`in_solve.rs`, `search_wide`): each vertex's box and reach (m,
    /// by particle), wide enough for the search ahead and, for each vertex the solve ends within
    /// its budget, for the pass after it; the round-off margin it was found with, whether its
    /// candidates are those of this step's start (`ahead_from`), each vertex's move off its
    /// inertial path in the last step, and the vertices the solve took outside.
    wide_boxes: Vec<Aabb>,
    wide_side: Vec<f64>,
    wide_eps: f64,
    wide_ready: bool,
    /// Steps left that search ahead without widening, after a pass that could not use it.
    wide_rest: u32,
    off_inertia: Vec<Vec3>,
    outside: Vec<bool>,
    /// What shows that the search ahead of a solve would find nothing (`in_solve.rs`).
    ahead_list: in_solve::Quiet,
    /// Where the last step's pairs ahead were left out as too far apart to be held, what the
    /// solve is told of them, and whether it asked for them after all (`in_solve.rs`).
    ahead_apart: Option<Apart>,
    ahead_wanted: std::sync::atomic::AtomicBool,
    topology: Topology,
    /// Each vertex's grown swept box this substep.
    vertex_boxes: Vec<Aabb>,
    /// Each vertex's end of its path this substep, as the integrator left it (`x1`): with
    /// `x0` and `path_radius`, the capsule it is kept in.
    path_ends: Vec<Vec3>,
    /// The capsules' radius this substep (m): `thickness / 2` and a round-off margin.
    path_radius: f32,
    /// Each vertex's box for building the pair list, and the round-off margin (m) the list was
    /// built with.
    search_boxes: Vec<Aabb>,
    list_eps: f32,
    broad: Broad,
    list: PairList,
    pairs: Vec<Pair>,
    /// What the substep on the pair list left out of `pairs`, if it left out any.
    cold: Option<Cold>,
    /// Each particle's distance from the substep's common displacement (m; zero for a particle
    /// in no triangle), and how far the repulsion moved each vertex, summed over its
    /// corrections (m; zero outside the repulsion), and the most of that.
    moving: Vec<f64>,
    pushed: Vec<f64>,
    pushed_most: f64,
    /// The vertices of this substep's pairs as the integrator left them, to redo it from.
    saved: Vec<(u32, Vec3, Vec3)>,
    marked: Vec<bool>,
    /// Pairs the repulsion looks at, and whether each was in contact in some sweep.
    near: Vec<(u32, bool)>,
    /// The buffers of the repulsion's and the cap's ordered parallel filters, kept.
    near_parts: parts::Parts<(u32, bool)>,
    /// The pairs the cap's round finds too fast, with each one's factor.
    violations: Vec<(u32, f64)>,
    violation_parts: parts::Parts<(u32, f64)>,
    scale: Vec<f64>,
    scale_next: Vec<f64>,
    /// Whether the cap's last round changed each vertex's scale.
    rescaled: Vec<bool>,
    /// Each vertex's start and move over the substep in f64, for the cap's pair tests.
    cap_start: Vec<DVec3>,
    cap_move: Vec<DVec3>,
    /// Vertices the cap stopped altogether in the last substep (in its last run, where the
    /// substep ran the pass more than once): what tells a cascade (`stopped_last`).
    stopped_last: u64,
    stats: SelfCollisionStats,
    /// Look at every pair the substep needs in each substep on the list, as if none could be
    /// left out (what the tests compare with), and `HOT` in its place, if given.
    #[cfg(test)]
    look_at_all: bool,
    #[cfg(test)]
    hot: Option<f64>,
    /// Run the search ahead and the pass's search whole every step, as if there were no
    /// step's one search (what the tests compare with).
    #[cfg(test)]
    whole_searches: bool,
}

impl SelfCollision {
    pub const NAME: &'static str = "self_collision";

    pub fn new(thickness: f32, friction: f32, iterations: u32) -> SelfCollision {
        SelfCollision {
            thickness,
            friction,
            iterations,
            solve_stiffness: 0.0,
            ahead_pairs: Vec::new(),
            ahead: Vec3s::zeros(0),
            ahead_from: Vec3s::zeros(0),
            ahead_kept: false,
            again_from: Vec3s::zeros(0),
            again_ahead: Vec3s::zeros(0),
            ahead_again: false,
            wide_boxes: Vec::new(),
            wide_side: Vec::new(),
            wide_eps: 0.0,
            wide_ready: false,
            wide_rest: 0,
            off_inertia: Vec::new(),
            outside: Vec::new(),
            ahead_list: in_solve::Quiet::default(),
            ahead_apart: None,
            ahead_wanted: std::sync::atomic::AtomicBool::new(false),
            topology: Topology::default(),
            vertex_boxes: Vec::new(),
            path_ends: Vec::new(),
            path_radius: 0.0,
            search_boxes: Vec::new(),
            list_eps: 0.0,
            broad: Broad::default(),
            list: PairList::default(),
            pairs: Vec::new(),
            cold: None,
            moving: Vec::new(),
            pushed: Vec::new(),
            pushed_most: 0.0,
            saved: Vec::new(),
            marked: Vec::new(),
            near: Vec::new(),
            near_parts: Default::default(),
            violations: Vec::new(),
            violation_parts: Default::default(),
            scale: Vec::new(),
            scale_next: Vec::new(),
            rescaled: Vec::new(),
            cap_start: Vec::new(),
            cap_move: Vec::new(),
            stopped_last: 0,
            stats: SelfCollisionStats::default(),
            #[cfg(test)]
            look_at_all: false,
            #[cfg(test)]
            hot: None,
            #[cfg(test)]
            whole_searches: false,
        }
    }

    pub fn stats(&self) -> SelfCollisionStats {
        self.stats
    }

    /// Vertices the cap stopped altogether in the last run of the pass: many means the stop
    /// spread from pair to pair through a cluster of contacts moving together faster than the
    /// cap lets a pair close (`APPROACH` of its distance a substep), which holds the whole
    /// cluster at the substep's start while the cloth around it moves on.
    pub fn stopped_last(&self) -> u64 {
        self.stopped_last
    }

    /// Counts a substep drawn back for the energy it gained ([`SelfCollisionStats::drawn_back`]).
    pub fn count_drawn_back(&mut self) {
        self.stats.drawn_back += 1;
    }

    /// The live mesh's edges, each once, as of the last pass.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.topology.edges
    }

    /// Runs the pass on the substep from `start` to `next` (see the module's comment). Returns
    /// false, changing nothing, when `next` holds a non-finite position (the step then fails
    /// as any non-finite step does), and otherwise whether the velocities it wrote are finite.
    pub fn apply(&mut self, model: &Model, start: &Kinematics, next: &mut Kinematics) -> bool {
        self.follow_topology(model);
        self.stopped_last = 0;
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
        // What the list must hold: the pairs that may come within `(1 + HOT) thickness`.
        let hot_needed = (1.0 + self.hot()) * thickness + 2.0 * motion.radius() + eps;
        // Which pairs a substep looks at depends on the substep alone, never on when the list
        // was built, so a restored state steps exactly as the original.
        let clock = Instant::now();
        let finite = if needed <= LIST_LIMIT * thickness {
            let in_mesh = &self.topology.in_mesh;
            let strayed = survey.drift.and_then(|d| self.list.strayed(in_mesh, x0, d));
            if !self.list.covers(strayed, hot_needed, eps) {
                self.renew_list(x0, hot_needed, eps);
            }
            self.listed_pairs(x0, &next.pos, motion, (needed, hot_needed), eps);
            self.stats.effort.search_seconds += clock.elapsed().as_secs_f64();
            let inert = |c: &Cold| c.repulsion_safe(0.0, eps) && c.cap_safe(0.0, eps);
            let all = self.looks_at_all();
            if self.pairs.is_empty() && !all && self.cold.as_ref().is_none_or(inert) {
                return true;
            }
            self.sweep_boxes(x0, &next.pos, eps as f32);
            self.save_listed(next, false);
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
                let clock = Instant::now();
                let finite = self.redo_loose(x0, next, inv_mass, eps, before);
                self.stats.effort.redo_seconds += clock.elapsed().as_secs_f64();
                finite
            }
        } else {
            self.stats.swept_substeps += 1;
            self.sweep_boxes(x0, &next.pos, eps as f32);
            self.swept_pairs(x0, eps);
            self.stats.effort.search_seconds += clock.elapsed().as_secs_f64();
            self.resolve(x0, next, inv_mass, eps)
        };
        self.stats.pairs += self.pairs.len() as u64;
        if let Some(d) = self.pairs.iter().map(|p| p.d0).min_by(f64::total_cmp) {
            self.stats.min_distance = self.stats.min_distance.min(d);
        }
        finite
    }

    /// The mesh's surface as `model` has it now.
    fn follow_topology(&mut self, model: &Model) {
        if self.topology.version != Some(model.topology_version) {
            // The cut-aware surface: a triangle a cut or tear runs through is no surface.
            let triangles = model.triangles().collect();
            self.topology
                .rebuild(model.topology_version, model.grid.len(), triangles);
            self.topology.sew(model.sewn());
            self.list.clear();
            self.ahead_list.clear();
            self.broad.forget_kept();
            self.ahead_kept = false;
            self.wide_ready = false;
            self.ahead_again = false;
            self.off_inertia.clear();
            self.marked = vec![false; model.grid.len()];
        }
    }

    /// Makes the list cover a substep at `x0` that needs `needed`: the vertices past
    /// `REQUERY_AT` of the bound they may stray by are queried again, each from where it is,
    /// or, when there are more than `REQUERY_MOST` of the vertices or the list's reach falls
    /// short of `needed` itself, the whole list is built again.
    fn renew_list(&mut self, x0: &Vec3s, needed: f64, eps: f64) {
        let bound = self.list.bound(needed, eps);
        if self.list.anchor().is_some() && bound > 0.0 {
            let verts = &self.topology.vertices;
            let past = self.list.mark_past(verts, REQUERY_AT * bound);
            if past as f64 <= REQUERY_MOST * verts.len() as f64 {
                // A cloth carried farther from the origin rounds its coordinates coarser.
                self.list_eps = self.list_eps.max(eps as f32);
                self.requery_list(x0, past);
                let most = self.list.most_strayed();
                if self.list.covers(Some(most), needed, eps) {
                    return;
                }
            }
            self.list.unmark();
        }
        let reach = needed + SKIN * self.thickness as f64;
        self.list_eps = eps as f32;
        let mut boxes = std::mem::take(&mut self.search_boxes);
        list_boxes(&mut boxes, x0, reach, self.list_eps);
        let margin = 1e-3 * self.list_eps as f64;
        let looked = self
            .broad
            .search_near(&self.topology, &boxes, x0, reach, margin, None);
        self.count(looked);
        self.search_boxes = boxes;
        let found = self.broad.near_found(&self.topology);
        self.list.rebuild(x0, reach, found);
        self.stats.rebuilds += 1;
    }

    /// Moves the anchor of the `past` vertices the list marked to where they are at `x0` (less
    /// the cloth's common displacement), and lists again every pair through them: the pairs a
    /// search of the whole mesh at the new anchor would find, in its order.
    fn requery_list(&mut self, x0: &Vec3s, past: usize) {
        self.list.reanchor_marked(x0);
        let (anchor, moved) = (self.list.anchor(), self.list.marked());
        let anchor = anchor.expect("a list to query again");
        let reach = self.list.reach();
        let mut boxes = std::mem::take(&mut self.search_boxes);
        list_boxes(&mut boxes, anchor, reach, self.list_eps);
        let margin = 1e-3 * self.list_eps as f64;
        let looked =
            self.broad
                .search_near(&self.topology, &boxes, anchor, reach, margin, Some(moved));
        self.count(looked);
        self.search_boxes = boxes;
        self.list.merge(self.broad.near_found(&self.topology));
        self.stats.requeries += 1;
        self.stats.requeried += past as u64;
    }

    /// The pairs closer than `needed` at `x0` that the substep from `x0` to `x1` (`motion`,
    /// the box of its displacements) may bring within `thickness` and `HOT` of it, with their
    /// closest points at `x0`, ordered by their vertices (the list's order: the same whenever
    /// the list was built, so the result depends on the substep alone), from a list that
    /// holds every pair closer than `hot_needed`. A pair that was `d` apart at the anchor is
    /// at least `d` less its vertices' strays apart now ([`PairList::within`]; `eps` allows
    /// for round-off), so only the list's nearest need a look; of those, most are farther
    /// apart than the substep's own motion can close, and are left `cold` with the pairs the
    /// list does not hold (see [`Cold`]).
    fn listed_pairs(
        &mut self,
        x0: &Vec3s,
        x1: &Vec3s,
        motion: Spread,
        (needed, hot_needed): (f64, f64),
        eps: f64,
    ) {
        // Only for its side effect: the list's `near`, the pairs that may be closer than
        // `hot_needed`, which `PairList::hot` then filters by this substep's own motion.
        let _ = self.list.within(hot_needed, eps);
        let common = motion.centre();
        let moving_most = per_surface_vertex(&mut self.moving, &self.topology.in_mesh, |v| {
            (x1.get(v).as_dvec3() - x0.get(v).as_dvec3() - common).length()
        });
        let thickness = self.thickness as f64;
        let slack = self.hot() * thickness;
        let hot = self.list.hot(thickness + slack, eps, &self.moving);
        self.pairs.clear();
        self.pairs.par_extend(hot.map(|c| c.at(x0)));
        self.pairs.retain(|p| p.d0 < needed);
        self.cold = Some(Cold {
            needed,
            eps,
            thickness,
            slack,
            moving_most,
        });
    }

    /// Looks at every pair the substep needs, the ones [`SelfCollision::listed_pairs`] left
    /// cold too (in the list's order, the list first made to hold them), and keeps their
    /// vertices as `next` has them (as the integrator left them: only the pairs already
    /// looked at moved theirs) to redo the substep from.
    fn widen(&mut self, x0: &Vec3s, next: &Kinematics) {
        let Some(Cold { needed, eps, .. }) = self.cold.take() else {
            return;
        };
        self.stats.widened += 1;
        if !self
            .list
            .covers(Some(self.list.most_strayed()), needed, eps)
        {
            self.renew_list(x0, needed, eps);
        }
        let near = self.list.within(needed, eps);
        self.pairs.clear();
        self.pairs.par_extend(near.map(|c| c.at(x0)));
        self.pairs.retain(|p| p.d0 < needed);
        self.save_listed(next, true);
    }

    /// The swept search, for a substep whose motion the list does not cover: every pair whose
    /// swept boxes overlap and which the motion its vertices' capsules allow could bring
    /// within `thickness`. A vertex ends the substep in its capsule, so a pair at `d0` whose
    /// vertices' capsules reach at most `l_a` and `l_b` from where they start stays
    /// `d0 - l_a - l_b` apart.
    fn swept_pairs(&mut self, x0: &Vec3s, eps: f64) {
        self.cold = None;
        let mut pairs = std::mem::take(&mut self.pairs);
        // The step's own start: the search ahead of its solve looked at the pairs there, with
        // the same closest points.
        let same_start = self.ahead_kept && same_bits(&self.ahead_from, x0);
        let reuse = if same_start {
            Reuse::Take
        } else {
            Reuse::Nothing
        };
        let looked = match same_start && self.wide_ready {
            true => self.pass_from_wide(x0, eps, &mut pairs),
            false => None,
        };
        let looked =
            looked.unwrap_or_else(|| self.swept_search(x0, eps, (reuse, false), &mut pairs));
        self.pairs = pairs;
        self.count(looked);
    }

    /// The swept search of [`SelfCollision::swept_pairs`] into `out`, on the boxes and path
    /// ends of the last [`SelfCollision::sweep_boxes`]; with `listed`, its pairs among those
    /// the quiet list picked, which the caller vouches hold every pair it could find
    /// (`in_solve.rs`).
    fn swept_search(
        &mut self,
        x0: &Vec3s,
        eps: f64,
        (reuse, listed): (Reuse, bool),
        out: &mut Vec<Pair>,
    ) -> Looked {
        let (boxes, thickness) = (&self.vertex_boxes, self.thickness as f64);
        let reach = path_reach(&self.path_ends, x0, self.path_radius);
        // A pair is found closer than `thickness + side(a) + side(b) + eps`, a side's the most
        // any of its vertices may move.
        let (topo, limit, margin) = (&self.topology, (thickness, reach, eps), 1e-3 * eps);
        if listed {
            let picked = self.ahead_list.picked();
            let (order, broad) = (Order::Index, &mut self.broad);
            broad.search_listed(topo, boxes, x0, limit, margin, order, reuse, picked, out)
        } else {
            let order = Order::Index;
            self.broad
                .search(topo, boxes, x0, limit, margin, order, reuse, out)
        }
    }

    fn count(&mut self, looked: Looked) {
        self.stats.effort.boxes_tested += looked.boxes;
        self.stats.effort.candidates += looked.candidates;
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
        // The abandoned attempt's counts are forgotten, but not what it looked at or how long
        // it took; the redo's own time counts as `redo_seconds` alone.
        let tried = self.stats;
        self.stats = SelfCollisionStats {
            effort: tried.effort,
            ..before
        };
        self.stats.substeps += 1;
        self.stats.swept_substeps += 1;
        self.stats.redone += 1;
        self.swept_pairs(x0, eps);
        let finite = self.resolve(x0, next, inv_mass, eps);
        self.stats.effort.repulsion_seconds = tried.effort.repulsion_seconds;
        self.stats.effort.cap_seconds = tried.effort.cap_seconds;
        finite
    }

    /// Keeps the positions and velocities of the pairs' vertices, the only ones the pass
    /// changes, so that a substep can be redone; with `more`, adds those of the vertices not
    /// kept yet to those kept.
    fn save_listed(&mut self, next: &Kinematics, more: bool) {
        if !more {
            self.saved.clear();
        }
        for &(v, ..) in &self.saved {
            self.marked[v as usize] = true;
        }
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

    /// The repulsion, each touched vertex put back inside its box, and the cap. On pairs that
    /// left some `cold`, each stage looks at those too (from the integrator's positions again,
    /// for the repulsion) unless it has shown that they cannot act in it.
    fn resolve(&mut self, x0: &Vec3s, next: &mut Kinematics, inv_mass: &[f32], eps: f64) -> bool {
        let clock = Instant::now();
        if self.looks_at_all() {
            self.widen(x0, next);
        }
        let contacts = self.stats.contacts;
        let mut finite = self.repel(next, inv_mass, eps);
        if let Some(cold) = self.cold {
            if !cold.repulsion_safe(self.pushed_most, eps) {
                self.restore_listed(next);
                self.stats.contacts = contacts;
                self.widen(x0, next);
                finite = self.repel(next, inv_mass, eps);
            }
        }
        // Back inside each vertex's capsule, what the swept search allows for.
        for &(k, touched) in &self.near {
            if touched {
                for &v in &self.pairs[k as usize].verts {
                    let p = self.kept_on_path(v as usize, x0, next.pos.get(v as usize));
                    next.pos.set(v as usize, p);
                }
            }
        }
        let capping = Instant::now();
        self.stats.effort.repulsion_seconds += (capping - clock).as_secs_f64();
        if let Some(cold) = self.cold {
            if !cold.cap_safe(self.pushed_most, eps) {
                self.widen(x0, next);
            }
        }
        if !self.cap(x0, next, eps, self.cold.is_none()) {
            self.widen(x0, next);
            self.cap(x0, next, eps, true);
        }
        self.stats.effort.cap_seconds += capping.elapsed().as_secs_f64();
        finite
    }

    #[cfg(test)]
    fn looks_at_all(&self) -> bool {
        self.look_at_all
    }

    #[cfg(not(test))]
    fn looks_at_all(&self) -> bool {
        false
    }

    #[cfg(test)]
    fn hot(&self) -> f64 {
        self.hot.unwrap_or(HOT)
    }

    #[cfg(not(test))]
    fn hot(&self) -> f64 {
        HOT
    }

    pub fn heap_bytes(&self) -> usize {
        self.topology.heap_bytes()
            + (self.vertex_boxes.capacity() + self.search_boxes.capacity()) * size_of::<Aabb>()
            + self.path_ends.capacity() * size_of::<Vec3>()
            + self.broad.heap_bytes()
            + self.list.heap_bytes()
            + self.ahead_list.heap_bytes()
            + (self.pairs.capacity() + self.ahead_pairs.capacity()) * size_of::<Pair>()
            + self.ahead.heap_bytes()
            + self.ahead_from.heap_bytes()
            + self.again_from.heap_bytes()
            + self.again_ahead.heap_bytes()
            + self.wide_boxes.capacity() * size_of::<Aabb>()
            + self.wide_side.capacity() * 8
            + self.off_inertia.capacity() * size_of::<Vec3>()
            + self.outside.capacity()
            + (self.moving.capacity() + self.pushed.capacity()) * 8
            + self.saved.capacity() * size_of::<(u32, Vec3, Vec3)>()
            + self.marked.capacity()
            + self.near.capacity() * 8
            + (self.scale.capacity() + self.scale_next.capacity()) * 8
            + self.rescaled.capacity()
            + (self.cap_start.capacity() + self.cap_move.capacity()) * size_of::<DVec3>()
    }
}

/// Fills `out` with `of(v)` for each vertex `v` of the mesh's surface and zero for every other
/// particle, and returns the largest (zero if none is larger).
fn per_surface_vertex(
    out: &mut Vec<f64>,
    in_mesh: &[bool],
    of: impl Fn(usize) -> f64 + Sync,
) -> f64 {
    out.resize(in_mesh.len(), 0.0);
    out.par_iter_mut()
        .with_min_len(4096)
        .enumerate()
        .map(|(v, o)| {
            *o = if in_mesh[v] { of(v) } else { 0.0 };
            *o
        })
        .reduce(|| 0.0, f64::max)
}

/// How far each vertex may end from where it starts at `x0` (m, by particle): the length of its
/// path to its end in `ends` and the capsule's `radius` (m).
fn path_reach<'a>(ends: &'a [Vec3], x0: &'a Vec3s, radius: f32) -> impl Fn(u32) -> f64 + Sync + 'a {
    let radius = radius as f64;
    move |v: u32| {
        let v = v as usize;
        (ends[v] - x0.get(v)).as_dvec3().length() + radius
    }
}

/// Whether `a` and `b` hold the same positions, bit for bit.
fn same_bits(a: &Vec3s, b: &Vec3s) -> bool {
    let same = |p: &[f32], q: &[f32]| {
        p.len() == q.len() && p.iter().zip(q).all(|(u, v)| u.to_bits() == v.to_bits())
    };
    same(&a.x, &b.x) && same(&a.y, &b.y) && same(&a.z, &b.z)
}

/// Each vertex's box for a search for the pair list at `x` that reaches `reach` (m): a pair
/// closer than that has overlapping boxes.
fn list_boxes(boxes: &mut Vec<Aabb>, x: &Vec3s, reach: f64, eps: f32) {
    let grow = Vec3::splat(0.5 * reach as f32 + eps);
    boxes.clear();
    boxes.extend((0..x.len()).map(|v| {
        let p = x.get(v);
        Aabb {
            min: p - grow,
            max: p + grow,
        }
    }));
}

/// The pairs a substep on the pair list may leave out of what the repulsion and the cap look
/// at: each listed one was, at the anchor, farther than `thickness + slack` and the most any
/// vertex of each of its primitives strayed since then and strays in the substep (`moving`,
/// from the substep's common displacement `T`), and each one the list does not hold is farther
/// than `thickness + slack + 2 r` (`r` the most any vertex strays in the substep), so it is at
/// least `thickness + slack + m_a + m_b` apart at the substep's start (`m` the most a vertex
/// of that side strays in the substep). Its
/// gap along its normal at the start (what the repulsion measures) then changes by at most
/// `m_a + m_b` over the substep, since its closest points' weights are zero-sum, and by at
/// most `p_a + p_b` more through the repulsion (`p` what the repulsion moved a vertex, summed
/// over its corrections): below `slack` it stays at least `thickness`, and the pair is never
/// corrected, so the repulsion on the others alone ends exactly as on all. In the cap's first
/// round its relative motion is at most `m_a + m_b + 2 p`, within `APPROACH` of its distance
/// while `cap_safe`; the cap's later rounds look at the pairs of the vertices it rescaled,
/// which may be any, so when it acts it looks at every pair.
#[derive(Clone, Copy)]
struct Cold {
    /// What the substep needs (m): the pairs looked at in the end are those closer at `x0`;
    /// and the round-off margin it was found with (m).
    needed: f64,
    eps: f64,
    thickness: f64,
    /// How much farther than `thickness` the pairs left out are (m).
    slack: f64,
    /// The most any vertex strays from the substep's common displacement (m).
    moving_most: f64,
}

impl Cold {
    /// Whether no pair left out can be corrected by a repulsion that moved no vertex farther
    /// than `pushed` (m), summed over its corrections (`eps` allows for round-off).
    fn repulsion_safe(&self, pushed: f64, eps: f64) -> bool {
        2.0 * pushed + 4.0 * eps <= self.slack
    }

    /// Whether no pair left out is too fast for the cap's first round after such a
    /// repulsion: its relative motion `m_a + m_b + 2 pushed` (and round-off) within
    /// `APPROACH` of its distance `thickness + slack + m_a + m_b`, less `eps`.
    fn cap_safe(&self, pushed: f64, eps: f64) -> bool {
        let spare = cap::APPROACH * (self.thickness + self.slack);
        2.0 * (1.0 - cap::APPROACH) * self.moving_most + 2.0 * pushed + 3.0 * eps <= spare
    }
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
mod partial_rebuild_tests;

#[cfg(test)]
mod tests {
    use super::*;

    /// A pass that built its mesh from the live particles alone would keep the triangles a
    /// severed stroke runs through as a surface stretched across the gap, and push cloth off
    /// a surface nobody sees. It must keep apart exactly the drawn triangles.
    #[test]
    fn the_mesh_it_keeps_apart_is_the_drawn_one_after_a_cut() {
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
