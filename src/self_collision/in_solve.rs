//! The pairs ahead of an implicit solve: those the step's inertial motion could bring within
//! `thickness`, found at the step's start by the swept search, for implicit Euler to hold
//! apart inside its linear solve (`src/integrators/self_contact.rs`). The pass after the solve
//! is unchanged: the solve only makes it rarely have to stop anything far.
//!
//! A cloth where nothing is close would pay for that search over the whole mesh before every
//! solve only to find pairs it could have known of. A pair list of its own ([`Quiet`],
//! `list.rs`), reaching as far as the search could look and a skin more, holds every pair the
//! search could find while the cloth has moved little from its anchor: then the search is not
//! run, and its pairs are taken from the list, through the search's own tests and in its
//! order, so they are the same to the bit (none, most often, on a cloth at rest). The list is
//! kept while it covers, so a cloth at rest builds it once.
//!
//! Where the search runs, it is the step's one search: the pass after the solve, which would
//! search again from the same start to where the solve ended each vertex, takes its pairs
//! from it. Each vertex's box and reach are widened beyond its path ahead (`x0` to
//! `x0 + h v`) by a budget `b` around `p`, where the last step's solve ended it off its
//! inertial path (`p = x0 + h v + o`, `o` that move): the box takes in `x0`, `x0 + h v` and `p`,
//! grown by the capsule's radius and `b`, and the reach is the longer of `|h v|` and
//! `|p - x0| + b`, and the capsule's radius. Every candidate of the widened search (boxes
//! overlapping, tight boxes within its limit) is kept, by key, without closest points.
//!
//! Why that covers both searches. A search finds a pair when the two primitives' boxes (the
//! union of their vertices') overlap and its distance at `x0` is below `thickness` plus the
//! longest reach of each primitive's vertices (the tight boxes only pass over, earlier, pairs
//! whose distance the boxes already bound above that limit). Each test is monotone: a vertex
//! box inside a larger one leaves overlapping boxes overlapping, and a longer reach raises the
//! limit. The pairs' distances are taken at the same `x0` by every search (the same positions,
//! bit for bit: `same_bits`), so a pair the narrower search finds, all of whose vertices' boxes
//! and reaches lie inside the widened ones, is a candidate of the widened search, and the
//! narrower search's own tests, run on it, keep it exactly when the narrower search would. The
//! search ahead always lies inside (its path is in the box, its reach at most the widened
//! one; checked, against round-off). A vertex the solve ends at `x1` lies inside when `x1` is
//! within `b` of `p`: distance is 1-Lipschitz in each point, so `|x1 - x0| <= |p - x0| + b`,
//! and its box (`x0` and `x1`, grown by the radius) lies in the widened one. That is checked
//! exactly after the solve on the boxes and reaches the pass searches with (`mark_outside`),
//! not proven from `b`; a vertex that fails it is outside, and every pair through a vertex
//! outside is looked up in the trees, refitted to the pass's boxes, one primitive at a time,
//! as the pair list's partial requery does (`Broad::find_touching`: the same box tests as the
//! walk's). The pairs through no vertex outside come from the widened candidates, those
//! through one from the lookups, each once; all go through the pass's own tests and into key
//! order, so the pass gets the pairs of a whole search, in its order, with the same closest
//! points (taken over from the search ahead where it computed them). Where more than one
//! vertex in `OUTSIDE_MOST` is outside, the lookups cost more than a walk and the pass
//! searches on its own.

use std::sync::atomic::Ordering::Relaxed;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::bvh::Aabb;
use super::list::PairList;
use super::pair::Pair;
use super::search::{Looked, NearKeys, Reuse};
use super::{list_boxes, path_reach, per_surface_vertex, SelfCollision, Survey, SKIN};
use crate::model::Model;
use crate::soa::Vec3s;
use crate::state::Kinematics;

impl SelfCollision {
    /// Whether implicit Euler's solve holds the pairs ahead of it apart.
    pub fn in_solve(&self) -> bool {
        self.solve_stiffness > 0.0
    }

    /// The pairs of the swept search from `from.pos` to `from.pos + h from.vel` (each vertex's
    /// inertial motion over a step of `h` s), with their closest points at `from.pos`, in
    /// vertex then triangle and edge then edge order (a function of `from` alone, so a restored
    /// state steps as the original). The pass's own search and its bounds: a pair left out
    /// cannot come within `thickness` along those straight paths.
    pub fn pairs_ahead(&mut self, model: &Model, from: &Kinematics, h: f32) -> &[Pair] {
        self.follow_topology(model);
        self.find_pairs_ahead(from, h);
        if self.ahead_apart.is_none() {
            // Kept for a solve from the same start along the same paths: its pairs are these.
            self.ahead_again = true;
            self.again_from.assign(&from.pos);
            self.again_ahead.assign(&self.ahead);
        }
        &self.ahead_pairs
    }

    /// [`SelfCollision::pairs_ahead`] into `ahead_pairs`. Where a search would run and the last
    /// pairs ahead were found from the same start along the same paths ahead, bit for bit (a
    /// substep's passes run again, holding what the pass moved), they are kept: the search
    /// would find the same pairs, and the pass after the solve takes its own from the same
    /// candidates. Whether the pairs are left out as too far apart, or the list shows there
    /// are none, is decided anew, as that decision reads the list as it is now.
    fn find_pairs_ahead(&mut self, from: &Kinematics, h: f32) {
        self.ahead_apart = None;
        self.ahead_wanted.store(false, Relaxed);
        let (x0, v) = (&from.pos, &from.vel);
        let n = x0.len();
        if self.ahead.len() != n {
            self.ahead = Vec3s::zeros(n);
        }
        self.ahead
            .par_chunks_mut(4096)
            .enumerate()
            .for_each(|(c, out)| {
                for i in 0..out.x.len() {
                    let p = c * 4096 + i;
                    let x = x0.get(p) + h * v.get(p);
                    (out.x[i], out.y[i], out.z[i]) = (x.x, x.y, x.z);
                }
            });
        let again = std::mem::take(&mut self.ahead_again)
            && self.gives_ahead_again()
            && super::same_bits(&self.again_from, x0)
            && super::same_bits(&self.again_ahead, &self.ahead);
        let kept = (self.ahead_kept, self.wide_ready);
        self.ahead_kept = false;
        self.wide_ready = false;
        // The round-off margin of `apply`, from the largest coordinate at either end; with a
        // non-finite position the step fails anyway, and nothing is held.
        let verts = &self.topology.vertices;
        let anchor = self.ahead_list.list.anchor();
        let Some(survey) = Survey::of(verts, x0, &self.ahead, anchor) else {
            self.ahead_pairs.clear();
            return;
        };
        let eps = 1e-6 * (1.0 + survey.reach);
        let listed = !self.ahead_always() && self.listed_ahead(x0, survey, eps, (v, h));
        if self.ahead_apart.is_some() {
            self.ahead_pairs.clear();
            self.stats.ahead_apart += 1;
            self.ahead_list.eps_ahead = eps;
            // Every pair the search would find is farther than `thickness`; whether it would
            // find any is not known, and only decides when the list is built.
            self.ahead_list.found_none = false;
            self.ahead_list.found_apart = true;
            return;
        }
        if listed && self.ahead_list.list.picked().is_empty() {
            self.ahead_pairs.clear();
            return;
        }
        if again {
            self.stats.ahead_again += 1;
            (self.ahead_kept, self.wide_ready) = kept;
            // The pass's own searches since may have taken the primitives' tight boxes
            // elsewhere (the pair list's, at its anchor); the widened candidates are read
            // with the ones at the step's start.
            if self.wide_ready {
                self.broad.fit_tight(&self.topology, x0);
            }
            return;
        }
        self.ahead_pairs.clear();
        self.find_ahead(x0, eps, listed);
    }

    /// The pairs the last [`SelfCollision::pairs_ahead`] gave.
    pub fn pairs_ahead_given(&self) -> &[Pair] {
        &self.ahead_pairs
    }

    /// Where the last [`SelfCollision::pairs_ahead`] left its pairs out, what the solve is told
    /// of them.
    pub fn ahead_apart(&self) -> Option<Apart> {
        self.ahead_apart
    }

    /// Marks the pairs left out of the last [`SelfCollision::pairs_ahead`] as needed after all
    /// (the solve moved a vertex farther than [`Apart`] allows for).
    pub fn ask_for_pairs_ahead(&self) {
        self.ahead_wanted.store(true, Relaxed);
    }

    /// Whether the solve asked for the pairs left out ([`SelfCollision::ask_for_pairs_ahead`]).
    pub fn pairs_ahead_asked(&self) -> bool {
        self.ahead_apart.is_some() && self.ahead_wanted.load(Relaxed)
    }

    /// The pairs the last [`SelfCollision::pairs_ahead`], from `from` (the same state), left
    /// out: those the search would have found, the same to the bit.
    pub fn give_pairs_ahead(&mut self, from: &Kinematics) -> &[Pair] {
        if self.ahead_apart.take().is_some() {
            self.stats.ahead_asked += 1;
            let eps = self.ahead_list.eps_ahead;
            self.pick_ahead(eps);
            self.find_ahead(&from.pos, eps, true);
        }
        self.ahead_wanted.store(false, Relaxed);
        &self.ahead_pairs
    }

    /// The swept search ahead from `x0` to `self.ahead` (`eps` its round-off margin) into
    /// `ahead_pairs`, among the pairs the list picked when `listed`.
    fn find_ahead(&mut self, x0: &Vec3s, eps: f64, listed: bool) {
        let ahead = std::mem::replace(&mut self.ahead, Vec3s::zeros(0));
        self.sweep_boxes(x0, &ahead, eps as f32);
        self.ahead = ahead;
        let mut pairs = std::mem::take(&mut self.ahead_pairs);
        pairs.clear();
        self.wide_ready = false;
        if listed {
            self.stats.ahead_from_list += 1;
            let looked = self.swept_search(x0, eps, (Reuse::Keep, true), &mut pairs);
            self.count(looked);
        } else {
            self.stats.ahead_searches += 1;
            // After a pass that could not take its pairs from the step's one search, the next
            // few steps search ahead as narrowly as they need: widening costs more than the
            // narrow search ahead, and where the solve's ends wander that far they would
            // likely miss again.
            let rest = self.wide_rest > 0;
            self.wide_rest = self.wide_rest.saturating_sub(1);
            self.wide_ready =
                !rest && !self.whole_searches() && self.search_wide(x0, eps, &mut pairs);
            if !self.wide_ready {
                self.swept_search(x0, eps, (Reuse::Keep, false), &mut pairs);
            }
        }
        let thickness = self.thickness as f64;
        self.ahead_list.found_none = pairs.is_empty();
        self.ahead_list.found_apart = pairs.iter().all(|p| p.d0 >= thickness);
        self.ahead_pairs = pairs;
        // The pass after the solve searches from the same start and takes over the closest
        // points this search took.
        self.ahead_from.assign(x0);
        self.ahead_kept = true;
    }

    /// The step's one search: the swept search from `x0` on each vertex's path ahead (the
    /// boxes and ends of the last `sweep_boxes`) and its budget beyond it, its candidates kept
    /// for the pass after the solve; into `pairs`, the search ahead's own pairs taken from
    /// them, the same to the bit. False, with nothing found, where a box or reach ahead is not
    /// inside the widened one (round-off).
    fn search_wide(&mut self, x0: &Vec3s, eps: f64, pairs: &mut Vec<Pair>) -> bool {
        let thickness = self.thickness as f64;
        // The pass's margin grows with the largest coordinate at the solve's end: twice the
        // search ahead's covers ends up to a metre and that coordinate farther out.
        let wide_eps = 2.0 * eps;
        let n = x0.len();
        let off = (self.off_inertia.len() == n).then_some(&self.off_inertia[..]);
        let radius = 0.5 * self.thickness + wide_eps as f32;
        let budget = BUDGET * self.thickness;
        self.wide_boxes.resize(n, Aabb::EMPTY);
        self.wide_side.resize(n, 0.0);
        let ends = &self.path_ends;
        self.wide_boxes
            .par_iter_mut()
            .zip(self.wide_side.par_iter_mut())
            .enumerate()
            .with_min_len(1024)
            .for_each(|(v, (bx, side))| {
                let (a, c) = (x0.get(v), ends[v]);
                let off = off.map_or(Vec3::ZERO, |o| o[v]);
                let b = budget + OFF_BUDGET * off.length();
                let p = c + off;
                let grow = Vec3::splat(radius + b);
                *bx = Aabb {
                    min: a.min(c).min(p) - grow,
                    max: a.max(c).max(p) + grow,
                };
                let (to_c, to_p) = ((c - a).as_dvec3().length(), (p - a).as_dvec3().length());
                *side = to_c.max(to_p + b as f64) + radius as f64;
            });
        let reach = path_reach(&self.path_ends, x0, self.path_radius);
        let verts = &self.topology.vertices;
        let wide = (&self.wide_boxes[..], &self.wide_side[..]);
        if mark_outside(&mut self.outside, verts, (&self.vertex_boxes, &reach), wide) > 0 {
            return false;
        }
        let (topo, wide_side) = (&self.topology, &self.wide_side);
        let wide_reach = |v: u32| wide_side[v as usize];
        let limit = (thickness, wide_reach, wide_eps);
        self.broad
            .search_wide(topo, &self.wide_boxes, x0, limit, 1e-3 * wide_eps);
        self.wide_eps = wide_eps;
        let (boxes, limit) = (&self.vertex_boxes, (thickness, reach, eps));
        self.broad
            .search_among_wide(topo, boxes, x0, limit, 1e-3 * eps, Reuse::Keep, None, pairs);
        true
    }

    /// The pass's swept search from `x0` (on the boxes and ends of its `sweep_boxes`, `eps` its
    /// margin) into `out`, taken from the step's one search when it was at `x0` and the solve
    /// took few enough vertices outside their budget (the rest looked up on their own): the
    /// same pairs, in the same order, to the bit. None, with nothing found, where it cannot.
    /// Keeps each vertex's move off its inertial path for the next step's budget.
    pub(super) fn pass_from_wide(
        &mut self,
        x0: &Vec3s,
        eps: f64,
        out: &mut Vec<Pair>,
    ) -> Option<Looked> {
        let n = x0.len();
        self.off_inertia.resize(n, Vec3::ZERO);
        let (ends, ahead) = (&self.path_ends, &self.ahead);
        self.off_inertia
            .par_iter_mut()
            .enumerate()
            .with_min_len(4096)
            .for_each(|(v, o)| *o = ends[v] - ahead.get(v));
        if eps > self.wide_eps {
            return None;
        }
        let reach = path_reach(&self.path_ends, x0, self.path_radius);
        let verts = &self.topology.vertices;
        let wide = (&self.wide_boxes[..], &self.wide_side[..]);
        let outside = mark_outside(&mut self.outside, verts, (&self.vertex_boxes, &reach), wide);
        if outside * OUTSIDE_MOST > verts.len() {
            self.wide_rest = MISSED_REST;
            return None;
        }
        self.stats.pass_from_ahead += 1;
        self.stats.pass_outside += outside as u64;
        let thickness = self.thickness as f64;
        let (topo, boxes) = (&self.topology, &self.vertex_boxes);
        let outside = (outside > 0).then_some(&self.outside[..]);
        Some(self.broad.search_among_wide(
            topo,
            boxes,
            x0,
            (thickness, reach, eps),
            1e-3 * eps,
            Reuse::Take,
            outside,
            out,
        ))
    }

    /// What the solve may be told instead of the pairs ahead, when the list (which covers the
    /// step: [`SelfCollision::listed_ahead`]) shows every pair it could give too far apart for
    /// the solve to hold ([`Apart`]): each pair is at least the least listed distance, less its
    /// primitives' strays since the anchor, apart at the step's start, and the inertial motion
    /// closes it by at most twice the most any vertex's path `h v` strays from a common
    /// displacement. Only when that motion uses at most half the room between that and
    /// `thickness`: the other half is left to the solve's own motion, which the solve checks
    /// ([`Apart::holds_none`]), asking for the pairs where it fails.
    fn apart_ahead(&self, vel: &Vec3s, h: f32, reach: f64, eps: f64) -> Option<Apart> {
        let quiet = &self.ahead_list;
        let eps = quiet.eps.max(eps);
        // The solve's gaps are taken in f32 (`self_contact.rs`): a few roundings of the
        // coordinates each, far below this.
        let round = ROUND * (1.0 + reach);
        let least = quiet.least - 2.0 * (quiet.list.most_strayed() + eps) - round;
        let room = least - self.thickness as f64;
        if room.is_nan() || room <= 0.0 {
            return None;
        }
        let h = h as f64;
        let path = |p: usize| h * vel.get(p).as_dvec3();
        let (common, most) = Apart::spread((0..vel.len()).map(path));
        (2.0 * most <= 0.5 * room).then_some(Apart { least, common })
    }
}

/// The pass takes its pairs from the step's one search while at most one vertex in this many
/// ended outside its budget; beyond, a search of its own costs less than the lookups.
const OUTSIDE_MOST: usize = 8;

/// Steps that search ahead without widening after a pass that had too many vertices outside
/// to take its pairs from the step's one search.
const MISSED_REST: u32 = 4;

/// Marks in `outside` (by particle) each vertex of `verts` whose box or reach (`boxes`,
/// `reach`) is not inside the wide one (`wide`), and returns how many.
fn mark_outside(
    outside: &mut Vec<bool>,
    verts: &[u32],
    (boxes, reach): (&[Aabb], &(impl Fn(u32) -> f64 + Sync)),
    (wide_boxes, wide_side): (&[Aabb], &[f64]),
) -> usize {
    outside.clear();
    outside.resize(boxes.len(), false);
    let mut count = 0;
    for &v in verts {
        let (b, w) = (&boxes[v as usize], &wide_boxes[v as usize]);
        let inside = w.min.cmple(b.min).all() && b.max.cmple(w.max).all();
        if !(inside && reach(v) <= wide_side[v as usize]) {
            outside[v as usize] = true;
            count += 1;
        }
    }
    count
}

/// Each vertex's budget beyond its path ahead, in the step's one search: `BUDGET` of
/// `thickness` and `OFF_BUDGET` of how far the last step's solve ended it off its inertial
/// path, around where that move would take it again (gravity's `h^2 g` and the springs' pull
/// change little from step to step). A larger budget widens the search every step; a smaller
/// one leaves more vertices outside to be looked up on their own after the solve. Chosen by
/// newton's 50 x 50 twist (docs/notes/contact.md, "2026-12-06: one swept search a step on the
/// twist"): 0.05 to 0.5 of `thickness` all within a tenth of each other, 0.2 the least work;
/// 28.6 vertices of 2 500 outside a step there.
const BUDGET: f32 = 0.2;
const OFF_BUDGET: f32 = 0.5;

/// Relative round-off allowed for the solve's f32 gaps, per m of the largest coordinate.
const ROUND: f64 = 1e-5;

/// What a solve is told of the pairs ahead of it when they were left out as all too far apart
/// to be held: every one of them is at least `least` (m) apart at the step's start (its gap
/// `n . sum c_i x_i`, `n` and `c` at the start), less the round-off of the solve's gaps. A
/// pair's weights sum to zero and to at most one on each primitive, so a motion `d_i` changes
/// its gap by at most twice the most any `|d_i - u|` is, for any common `u`: a solve whose
/// every vertex ends within `(least - thickness) / 2` of `u` (here the middle of the inertial
/// paths' box) brings no pair within `thickness`, and holds none, as with the pairs given.
#[derive(Clone, Copy, Debug)]
pub struct Apart {
    pub least: f64,
    pub common: DVec3,
}

impl Apart {
    /// The middle of the box of `d`, and the most any `d` is from it (m; an exact reduction,
    /// the same for any order).
    fn spread(d: impl Iterator<Item = DVec3> + Clone) -> (DVec3, f64) {
        let (lo, hi) = d
            .clone()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), d| {
                (lo.min(d), hi.max(d))
            });
        let common = if lo.is_finite() && hi.is_finite() {
            0.5 * (lo + hi)
        } else {
            DVec3::ZERO
        };
        let most = d.fold(0.0f64, |m, d| m.max((d - common).length()));
        (common, most)
    }

    /// Whether a step of `h` s from velocities `vel` with the change `dv` brings no pair
    /// within `thickness` (m): then the solve, given the pairs, would have held none.
    pub fn holds_none(&self, h: f32, thickness: f32, vel: &Vec3s, dv: &Vec3s) -> bool {
        #[cfg(test)]
        if tests::mode(thickness) == tests::Mode::Ask {
            return false;
        }
        let h = h as f64;
        let mut most = 0.0f64;
        for p in 0..vel.len() {
            let d = h * (vel.get(p).as_dvec3() + dv.get(p).as_dvec3());
            most = most.max((d - self.common).length());
        }
        // A motion that is not finite fails the step whatever the pairs.
        self.least - 2.0 * most * (1.0 + ROUND) >= thickness as f64
    }
}

/// The pairs that may matter to the search ahead of a solve, and when to build their list
/// again.
#[derive(Default)]
pub struct Quiet {
    /// Every pair closer than its reach at its anchor, their keys in the search's terms, and
    /// the round-off margin (m) it was built with.
    list: PairList,
    keys: NearKeys,
    eps: f64,
    /// The least listed distance at the anchor (m; infinite with none), and the round-off
    /// margin of the last step whose pairs were left out ([`Apart`]).
    least: f64,
    eps_ahead: f64,
    /// Whether the last search ahead found no pair, or none closer than `thickness`: the
    /// list is built only after the first, or the second on a cloth whose vertices move less
    /// than `SLOW thickness` in the step (there the list lasts many steps), so that a cloth in
    /// contact or moving fast, which soon moves past any list, never pays for it. Whether the
    /// list has spared a search since the step it was built in (a build costs about as much
    /// as the search it spares there: `fold`, falling fast past its lists, was no cheaper for
    /// a build in every step it could not cover). If not, how many more steps a failed cover
    /// waits before the next build (`wait`, doubled after each build that spared none, so a
    /// cloth moving fast pays for few builds), and how many of them are left. None of this
    /// changes which pairs a step finds, only what finding them costs.
    found_none: bool,
    found_apart: bool,
    spared: bool,
    wait: u32,
    left: u32,
    /// Each particle's side in the search (m): the length of its path and the capsule's
    /// radius (zero for a particle in no triangle).
    sides: Vec<f64>,
    /// Run the search whatever the list shows (what the tests compare with).
    #[cfg(test)]
    always: bool,
}

/// The most steps a failed cover waits before the list is built again.
const MOST_WAIT: u32 = 64;

/// The longest path a vertex may take in a step, as a fraction of `thickness`, for the list to
/// be built when the search ahead found pairs (none closer than `thickness`): the list allows
/// its vertices `SKIN / 2` of it, so at this speed it lasts a few steps at least. More builds
/// lists for cloths that move past them sooner (each build costs more than a search); less
/// leaves more slow cloths to the search.
const SLOW: f64 = 0.1;

impl Quiet {
    /// Forgets the list (the mesh changed).
    pub fn clear(&mut self) {
        self.list.clear();
        self.keys.clear();
        self.least = f64::INFINITY;
        self.found_none = false;
        self.found_apart = false;
        self.spared = false;
        self.wait = 0;
        self.left = 0;
    }

    /// The listed pairs' keys, and which of them the last [`PairList::unclear`] picked.
    pub fn picked(&self) -> (&NearKeys, &[u32]) {
        (&self.keys, self.list.picked())
    }

    pub fn heap_bytes(&self) -> usize {
        self.list.heap_bytes() + self.keys.heap_bytes() + self.sides.capacity() * 8
    }
}

impl SelfCollision {
    /// Whether the list holds every pair the swept search ahead of a solve from `x0` to
    /// `self.ahead` could find (`survey`, with the drift from the list's anchor; `eps` the
    /// search's round-off margin), building it first when it is due; if so, the listed pairs
    /// that may be among them are picked ([`PairList::picked`]). The search finds a pair closer
    /// than `thickness`, `eps` and its two primitives' sides, a side the most any of its
    /// vertices' paths is long (`|x1 - x0|`, as the search measures it) and the capsule's
    /// radius. So the list holds them all when it covers `thickness + 2 s + 2 eps` (`s` the
    /// longest side; one `eps` more than the search allows, for its own round-off) at `x0`,
    /// and only the listed pairs that may be closer than `thickness + 2 eps` and their own
    /// sides ([`PairList::unclear`]) can be among them. Exact either way: a pair the search
    /// would find is never left out, so the choice changes what a step costs, never what it
    /// finds.
    fn listed_ahead(
        &mut self,
        x0: &Vec3s,
        survey: Survey,
        eps: f64,
        (vel, h): (&Vec3s, f32),
    ) -> bool {
        if self.ahead_list.list.anchor().is_none() && !self.ahead_list.found_apart {
            return false;
        }
        let thickness = self.thickness as f64;
        // The search's capsule radius, rounded as `sweep_boxes` rounds it.
        let radius = (0.5 * self.thickness + eps as f32) as f64;
        let (ahead, in_mesh) = (&self.ahead, &self.topology.in_mesh);
        let quiet = &mut self.ahead_list;
        let side = per_surface_vertex(&mut quiet.sides, in_mesh, |v| {
            (ahead.get(v) - x0.get(v)).as_dvec3().length() + radius
        });
        // One `eps` for the search's own limit, one for its round-off.
        let base = thickness + 2.0 * eps;
        let needed = base + 2.0 * side;
        // A cloth carried farther from the origin rounds its coordinates coarser.
        let margin = quiet.eps.max(eps);
        let strayed = survey
            .drift
            .and_then(|d| quiet.list.strayed(in_mesh, x0, d));
        let built = !quiet.list.covers(strayed, needed, margin);
        if built {
            let slow = side - radius <= SLOW * thickness;
            if !(quiet.found_none || quiet.found_apart && slow) {
                return false;
            }
            if quiet.left > 0 {
                quiet.left -= 1;
                return false;
            }
            quiet.wait = match (quiet.list.anchor(), quiet.spared) {
                (Some(_), false) => (2 * quiet.wait).clamp(1, MOST_WAIT),
                _ => 0,
            };
            quiet.left = quiet.wait;
            quiet.spared = false;
            quiet.eps = eps;
            let reach = needed + SKIN * thickness;
            let mut boxes = std::mem::take(&mut self.search_boxes);
            list_boxes(&mut boxes, x0, reach, eps as f32);
            let looked =
                self.broad
                    .search_near(&self.topology, &boxes, x0, reach, 1e-3 * eps, None);
            self.count(looked);
            self.search_boxes = boxes;
            let quiet = &mut self.ahead_list;
            quiet
                .list
                .rebuild(x0, reach, self.broad.near_found(&self.topology));
            self.broad.near_keys(&mut quiet.keys);
            quiet.least = quiet.list.least_distance();
            self.stats.ahead_rebuilds += 1;
        }
        self.ahead_list.spared |= !built;
        if self.ahead_list.least.is_finite() {
            self.ahead_apart = self.apart_ahead(vel, h, survey.reach, eps);
            if self.ahead_apart.is_some() {
                return true;
            }
        }
        self.pick_ahead(eps);
        true
    }

    /// Picks the listed pairs that may be among those of the search ahead
    /// ([`PairList::unclear`]), from the sides [`SelfCollision::listed_ahead`] found (`eps`
    /// the search's round-off margin).
    fn pick_ahead(&mut self, eps: f64) {
        let base = self.thickness as f64 + 2.0 * eps;
        let quiet = &mut self.ahead_list;
        let least = quiet
            .sides
            .iter()
            .zip(&self.topology.in_mesh)
            .filter(|&(_, &m)| m)
            .fold(f64::INFINITY, |l, (&s, _)| l.min(s));
        let eps = quiet.eps.max(eps);
        quiet.list.unclear(base, (&quiet.sides, least), eps);
    }
}

impl SelfCollision {
    #[cfg(test)]
    fn ahead_always(&self) -> bool {
        self.ahead_list.always || tests::mode(self.thickness) == tests::Mode::Search
    }

    #[cfg(not(test))]
    fn ahead_always(&self) -> bool {
        false
    }

    #[cfg(test)]
    fn whole_searches(&self) -> bool {
        self.whole_searches
    }

    /// The searches the tests compare with search every time, and the tests that pin how a
    /// thickness's steps find their pairs ahead look at each step's own way of finding them
    /// (a cloth at rest to the bit is otherwise given its first step's pairs again).
    #[cfg(test)]
    fn gives_ahead_again(&self) -> bool {
        !self.ahead_list.always && !self.whole_searches && !tests::mode_pinned(self.thickness)
    }

    #[cfg(not(test))]
    fn gives_ahead_again(&self) -> bool {
        true
    }

    #[cfg(not(test))]
    fn whole_searches(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// How the steps of the passes of one `thickness` find their pairs ahead (the steps run on
    /// the thread pool, and other tests' passes step as shipped): as shipped, by the search
    /// every time (what the others are compared with), or with every solve given no pair
    /// asking for those left out.
    #[derive(Clone, Copy, PartialEq, Eq, Debug)]
    pub(super) enum Mode {
        Shipped,
        Search,
        Ask,
    }

    static MODE: Mutex<Option<(f32, Mode)>> = Mutex::new(None);

    pub(super) fn mode_pinned(thickness: f32) -> bool {
        matches!(*MODE.lock().unwrap(), Some((t, _)) if t.to_bits() == thickness.to_bits())
    }

    pub(super) fn mode(thickness: f32) -> Mode {
        match *MODE.lock().unwrap() {
            Some((t, mode)) if t.to_bits() == thickness.to_bits() => mode,
            _ => Mode::Shipped,
        }
    }

    /// The built-in twist's model and its particles' positions at rest.
    fn twist_at_rest() -> (Model, Vec3s) {
        Model::new(crate::Scene::builtin("twist").unwrap()).unwrap()
    }

    /// A pair to the bit: its vertices, split, closest-point weights, normal and distance.
    type PairBits = ([u32; 4], usize, [u64; 4], [u64; 3], u64);

    fn pair_bits(p: &Pair) -> PairBits {
        let (c, n) = (p.c.map(f64::to_bits), p.n.to_array().map(f64::to_bits));
        (p.verts, p.split, c, n, p.d0.to_bits())
    }

    /// Positions and velocities to the bit.
    fn state_bits(k: &Kinematics) -> [Vec<u32>; 6] {
        let c = [&k.pos.x, &k.pos.y, &k.pos.z, &k.vel.x, &k.vel.y, &k.vel.z];
        c.map(|c| c.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    }

    /// A solve given no pair ahead because all are too far apart to be held, which then moves
    /// the cloth farther than that allows for, asks for them, and the step is solved again
    /// with them: a cloth at rest whose list shows its pairs apart steps bitwise as with the
    /// search run ahead of every solve, whether its solves ask for the pairs or not.
    #[test]
    fn a_step_whose_solve_asks_for_the_pairs_left_out_steps_as_if_they_were_given() {
        // A thickness of this test's own.
        let thickness = 1.21e-2;
        let run = |mode| {
            *MODE.lock().unwrap() = Some((thickness, mode));
            let mut scene = crate::Scene::builtin("twist").unwrap();
            // 0.38 of the grid spacing, as the 128 x 128 cloth's 3 mm of its 7.9 mm: its grid
            // neighbours across a cell's short diagonal are pairs ahead, 0.7 spacings apart.
            scene.self_collision.as_mut().unwrap().thickness = thickness as f64;
            let mut sim = crate::Simulation::new(scene).unwrap();
            sim.step(60).unwrap();
            *MODE.lock().unwrap() = None;
            let bits = |v: &Vec3s| {
                let c = [&v.x, &v.y, &v.z];
                c.map(|c| c.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
            };
            let state = (bits(sim.positions()), bits(sim.velocities()));
            (state, sim.self_collision_stats().unwrap())
        };
        let (searched, s) = run(Mode::Search);
        let (shipped, a) = run(Mode::Shipped);
        let (asked, b) = run(Mode::Ask);
        assert!(s.ahead_apart == 0 && s.ahead_searches == 60, "{s:?}");
        assert!(a.ahead_apart > 40 && a.ahead_asked == 0, "{a:?}");
        assert!(
            b.ahead_asked == b.ahead_apart && b.ahead_asked > 40,
            "{b:?}"
        );
        assert!(shipped == searched, "the pairs left out changed the steps");
        assert!(
            asked == searched,
            "the steps asking for the pairs left out changed"
        );
    }

    /// The pass after a solve takes its pairs from the step's one search (the search ahead
    /// widened by each vertex's budget) and looks up on their own only the vertices the solve
    /// took outside it: it must end every step exactly as with two whole searches. A cloth
    /// given waves of velocity, its solve's ends off the inertial paths by a common drop and a
    /// wave whose amplitude grows from nothing to several budgets (so that first no vertex
    /// ends outside, then some, then too many for anything but a whole search): the pairs
    /// ahead, the pass's pairs (closest points to the bit) and the positions and velocities
    /// it ends with are the same in every step.
    #[test]
    fn the_pass_given_its_pairs_by_the_step_s_one_search_steps_as_with_its_own_search() {
        let thickness = 1.2e-2;
        let (model, pos) = twist_at_rest();
        let n = model.grid.len();
        let h = 1.0 / 240.0;
        let mut one = SelfCollision::new(thickness, 0.0, 2);
        let mut two = SelfCollision::new(thickness, 0.0, 2);
        two.whole_searches = true;
        let (bits, state) = (pair_bits, state_bits);
        let mut taken_with_outside = 0u64;
        for k in 0..40u32 {
            let speed = 1.0 + 0.05 * k as f32;
            let wave = |p: usize, t: f32| {
                let x = pos.get(p);
                let phase = 40.0 * x.x + 17.0 * x.y + t;
                glam::Vec3::new(phase.sin(), (1.3 * phase).cos(), (0.7 * phase).sin())
            };
            let vel = Vec3s::from_fn(n, |p| speed * wave(p, 0.3 * k as f32));
            let from = Kinematics {
                pos: pos.clone(),
                vel: vel.clone(),
            };
            let ahead = one.pairs_ahead(&model, &from, h).to_vec();
            let whole = two.pairs_ahead(&model, &from, h).to_vec();
            assert_eq!(ahead.len(), whole.len(), "step {k}");
            assert!(
                ahead.iter().zip(&whole).all(|(a, b)| bits(a) == bits(b)),
                "step {k}"
            );
            // The solve's end: off the inertial path by a drop and a wave of its own.
            let amplitude = thickness * (k as f32 / 20.0).powi(2);
            let drop = glam::Vec3::new(0.0, 0.0, -0.3 * thickness);
            let end = Vec3s::from_fn(n, |p| {
                let off = drop + amplitude * wave(p, 1.7 * k as f32);
                pos.get(p) + h * vel.get(p) + off
            });
            let next = Kinematics {
                vel: Vec3s::from_fn(n, |p| (end.get(p) - pos.get(p)) / h),
                pos: end,
            };
            let (mut a, mut b) = (next.clone(), next);
            let (taken, outside) = (one.stats.pass_from_ahead, one.stats.pass_outside);
            assert!(one.apply(&model, &from, &mut a), "step {k}");
            assert!(two.apply(&model, &from, &mut b), "step {k}");
            assert_eq!(one.pairs.len(), two.pairs.len(), "step {k}");
            assert!(
                one.pairs
                    .iter()
                    .zip(&two.pairs)
                    .all(|(a, b)| bits(a) == bits(b)),
                "step {k}"
            );
            assert!(state(&a) == state(&b), "step {k}");
            taken_with_outside +=
                u64::from(one.stats.pass_from_ahead > taken && one.stats.pass_outside > outside);
        }
        let (s, t) = (one.stats, two.stats);
        assert_eq!(t.pass_from_ahead, 0);
        // Some passes took their pairs with no vertex outside, some with a few looked up on
        // their own, and some had too many outside and searched on their own.
        assert!(s.pass_from_ahead > taken_with_outside, "{s:?}");
        assert!(taken_with_outside > 0, "{s:?}");
        assert!(s.swept_substeps > s.pass_from_ahead, "{s:?}");
    }

    /// A substep's passes run again (the solve holding what the pass moved) solve from the same
    /// start along the same paths ahead: the second solve is given the first's pairs ahead
    /// without a search, and its pass takes its pairs from what the first search kept. Both
    /// must be what searches of their own find, and the pass must end where theirs would. The
    /// cloth and waves of `the_pass_given_its_pairs_by_the_step_s_one_search_steps_as_with_its_own_search`,
    /// each step's passes run twice from one start (to two ends), against a fresh pass that
    /// searches on its own for each.
    #[test]
    fn a_substep_run_again_is_given_the_same_pairs_ahead_and_its_pass_the_same_pairs() {
        let thickness = 1.2e-2;
        let (model, pos) = twist_at_rest();
        let n = model.grid.len();
        let h = 1.0 / 240.0;
        let mut one = SelfCollision::new(thickness, 0.0, 2);
        let same = |a: &[Pair], b: &[Pair]| {
            a.len() == b.len() && a.iter().zip(b).all(|(a, b)| pair_bits(a) == pair_bits(b))
        };
        let state = state_bits;
        let (mut again_taken, mut found) = (0, 0);
        for k in 0..24u32 {
            let wave = |p: usize, t: f32| {
                let x = pos.get(p);
                let phase = 40.0 * x.x + 17.0 * x.y + t;
                glam::Vec3::new(phase.sin(), (1.3 * phase).cos(), (0.7 * phase).sin())
            };
            let speed = 1.0 + 0.05 * k as f32;
            let from = Kinematics {
                pos: pos.clone(),
                vel: Vec3s::from_fn(n, |p| speed * wave(p, 0.3 * k as f32)),
            };
            for round in 0..2u32 {
                let again = one.stats.ahead_again;
                let ahead = one.pairs_ahead(&model, &from, h).to_vec();
                assert_eq!(one.stats.ahead_again, again + u64::from(round), "step {k}");
                let mut fresh = SelfCollision::new(thickness, 0.0, 2);
                fresh.whole_searches = true;
                assert!(
                    same(&ahead, fresh.pairs_ahead(&model, &from, h)),
                    "step {k}"
                );
                found += u32::from(!ahead.is_empty());
                // The first round's end off the inertial path by a drop and a small wave, the
                // second's off the first's by a wave growing from nothing to beyond the budget.
                let drop = glam::Vec3::new(0.0, 0.0, -0.3 * thickness);
                let again = thickness * 0.15 * (k as f32 / 12.0).powi(2) * round as f32;
                let end = Vec3s::from_fn(n, |p| {
                    let off = drop + 0.05 * thickness * wave(p, 1.7 * k as f32);
                    let moved = again * wave(p, 2.9 * k as f32 + 1.0);
                    pos.get(p) + h * from.vel.get(p) + off + moved
                });
                let next = Kinematics {
                    vel: Vec3s::from_fn(n, |p| (end.get(p) - pos.get(p)) / h),
                    pos: end,
                };
                let (mut a, mut b) = (next.clone(), next);
                let taken = one.stats.pass_from_ahead;
                assert!(one.apply(&model, &from, &mut a), "step {k}");
                assert!(fresh.apply(&model, &from, &mut b), "step {k}");
                assert!(same(&one.pairs, &fresh.pairs), "step {k}, round {round}");
                assert!(state(&a) == state(&b), "step {k}, round {round}");
                again_taken += u32::from(round == 1 && one.stats.pass_from_ahead > taken);
            }
        }
        assert_eq!(one.stats.ahead_again, 24);
        assert!(
            found > 40 && again_taken > 4,
            "found {found}, {:?}",
            one.stats
        );
    }

    /// Skipping the search ahead never changes the pairs it finds: on a resting cloth given
    /// velocities from none to fast enough to bring its neighbours together within the step,
    /// the pairs ahead are those of the search run every time, in the same order, with the
    /// same closest points to the bit, whether the list shows there are none or gives them.
    /// At `thickness` 3 mm (a tenth of the grid spacing) nothing is near at rest; at 12 mm
    /// (0.38 of it, as the 128 x 128 cloth's 3 mm of its 7.9 mm) the search finds grid
    /// neighbours farther than `thickness` in every step, which the list must give.
    #[test]
    fn the_pairs_ahead_are_the_search_s_whether_it_runs_or_not() {
        let (skipped, _, found) = pairs_ahead_against_the_search(3e-3);
        assert!(skipped > 0 && found > 0, "skipped {skipped}, found {found}");
        let (skipped, from_list, found) = pairs_ahead_against_the_search(1.2e-2);
        // The list gives the pairs of the slow steps, and the search runs again once they are
        // too fast for it.
        assert!(
            from_list > 10 && skipped < 40,
            "skipped {skipped}, found by the list {from_list}, found {found}"
        );
    }

    /// Steps the checks of [`the_pairs_ahead_are_the_search_s_whether_it_runs_or_not`] at
    /// `thickness` (m), and returns in how many steps the search was not run, in how many of
    /// those the list gave pairs, and in how many the search found pairs.
    fn pairs_ahead_against_the_search(thickness: f32) -> (u32, u32, u32) {
        let scene = crate::Scene::builtin("twist").unwrap();
        let (model, pos) = Model::new(scene).unwrap();
        let n = model.grid.len();
        let h = 1.0 / 240.0;
        let mut skipping = SelfCollision::new(thickness, 0.0, 1);
        let mut searching = SelfCollision::new(thickness, 0.0, 1);
        searching.ahead_list.always = true;
        let (mut skipped, mut from_list, mut found, mut left_out) = (0, 0, 0, 0);
        for k in 0..40u32 {
            // A wave across the cloth whose speed grows step by step: from rest to vertices
            // closing on their neighbours within the step.
            let speed = 0.05 * k as f32 * k as f32 / 40.0;
            let vel = Vec3s::from_fn(n, |p| {
                let x = pos.get(p);
                let phase = 40.0 * x.x + 17.0 * x.y + 0.3 * k as f32;
                speed * glam::Vec3::new(phase.sin(), (1.3 * phase).cos(), (0.7 * phase).sin())
            });
            let from = Kinematics {
                pos: pos.clone(),
                vel,
            };
            let before = skipping.stats.ahead_searches;
            let mut skip = skipping.pairs_ahead(&model, &from, h).to_vec();
            let all = searching.pairs_ahead(&model, &from, h).to_vec();
            if let Some(apart) = skipping.ahead_apart() {
                // Left out, as too far apart to be held: they are, and given they are the
                // search's.
                assert!(skip.is_empty(), "step {k}");
                let least = all.iter().map(|p| p.d0).fold(f64::INFINITY, f64::min);
                assert!(
                    least >= apart.least && apart.least > thickness as f64,
                    "step {k}"
                );
                assert!(!skipping.pairs_ahead_asked(), "step {k}");
                skip = skipping.give_pairs_ahead(&from).to_vec();
                left_out += 1;
            }
            let bits = |p: &Pair| {
                let (c, n) = (p.c.map(f64::to_bits), p.n.to_array().map(f64::to_bits));
                (p.verts, p.split, c, n, p.d0.to_bits())
            };
            assert_eq!(skip.len(), all.len(), "step {k}");
            assert!(
                skip.iter().zip(&all).all(|(a, b)| bits(a) == bits(b)),
                "step {k}"
            );
            let not_run = skipping.stats.ahead_searches == before;
            skipped += u32::from(not_run);
            from_list += u32::from(not_run && !all.is_empty());
            found += u32::from(!all.is_empty());
        }
        assert_eq!(skipping.stats.ahead_asked, left_out);
        (skipped, from_list, found)
    }
}
