//! The pairs ahead of an implicit solve: those the step's inertial motion could bring within
//! `thickness`, found at the step's start by the swept search, for implicit Euler to hold
//! apart inside its linear solve (`src/integrators/self_contact.rs`). The pass after the solve
//! is unchanged: the solve only makes it rarely have to stop anything far.
//!
//! A cloth where nothing is close would pay for that search over the whole mesh before every
//! solve only to find nothing. A pair list of its own ([`Quiet`], `list.rs`), reaching as far
//! as the search could look and a skin more, shows when no pair can be found: then the search
//! is not run, and its result, no pair, is the same. The list is kept while the cloth moves
//! little from its anchor, so a cloth at rest builds it once.

use rayon::prelude::*;

use super::list::PairList;
use super::pair::Pair;
use super::search::Reuse;
use super::{list_boxes, per_surface_vertex, SelfCollision, Survey, SKIN};
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
        // The round-off margin of `apply`, from the largest coordinate at either end; with a
        // non-finite position the step fails anyway, and nothing is held.
        self.ahead_kept = false;
        let verts = &self.topology.vertices;
        let anchor = self.ahead_list.list.anchor();
        let Some(survey) = Survey::of(verts, x0, &self.ahead, anchor) else {
            self.ahead_pairs.clear();
            return &self.ahead_pairs;
        };
        let eps = 1e-6 * (1.0 + survey.reach);
        self.ahead_pairs.clear();
        if !self.ahead_always() && self.nothing_ahead(x0, survey, eps) {
            return &self.ahead_pairs;
        }
        self.stats.ahead_searches += 1;
        let ahead = std::mem::replace(&mut self.ahead, Vec3s::zeros(0));
        self.sweep_boxes(x0, &ahead, eps as f32);
        self.ahead = ahead;
        let mut pairs = std::mem::take(&mut self.ahead_pairs);
        self.swept_search(x0, eps, Reuse::Keep, &mut pairs);
        self.ahead_pairs = pairs;
        self.ahead_list.found_none = self.ahead_pairs.is_empty();
        // The pass after the solve searches from the same start and takes over the closest
        // points this search took.
        if self.ahead_from.len() == n {
            self.ahead_from.copy_from(x0);
        } else {
            self.ahead_from = x0.clone();
        }
        self.ahead_kept = true;
        &self.ahead_pairs
    }
}

/// The pairs that may matter to the search ahead of a solve, and when to build their list
/// again.
#[derive(Default)]
pub struct Quiet {
    /// Every pair closer than its reach at its anchor, and the round-off margin (m) it was
    /// built with.
    list: PairList,
    eps: f64,
    /// Whether the last search ahead found no pair: only then is the list built, so that a
    /// cloth in contact, where the search always finds some, never pays for it. Whether the
    /// list has spared a search since it was built; if not, how many more steps a failed cover
    /// waits before the next build (`wait`, doubled after each build that spared none, so a
    /// cloth moving fast pays for few builds), and how many of them are left. None of this
    /// changes which pairs a step finds, only what finding them costs.
    found_none: bool,
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

impl Quiet {
    /// Forgets the list (the mesh changed).
    pub fn clear(&mut self) {
        self.list.clear();
        self.found_none = false;
        self.spared = false;
        self.wait = 0;
        self.left = 0;
    }

    pub fn heap_bytes(&self) -> usize {
        self.list.heap_bytes() + self.sides.capacity() * 8
    }
}

impl SelfCollision {
    /// Whether the swept search ahead of a solve from `x0` to `self.ahead` (`survey`, with
    /// the drift from the list's anchor; `eps` the search's round-off margin) would find no
    /// pair. It finds a pair closer than `thickness`, `eps` and its two primitives' sides, a
    /// side the most any of its vertices' paths is long (`|x1 - x0|`, as the search measures
    /// it) and the capsule's radius. So it finds none when the list covers
    /// `thickness + 2 s + 2 eps` (`s` the longest side; one `eps` more than the search allows,
    /// for its own round-off) at `x0` and none of the listed pairs may be closer than
    /// `thickness + 2 eps` and its own sides ([`PairList::clear_of`]). Exact either way: a pair
    /// the search would find is never left out, so the choice changes what a step costs,
    /// never what it finds.
    fn nothing_ahead(&mut self, x0: &Vec3s, survey: Survey, eps: f64) -> bool {
        if self.ahead_list.list.anchor().is_none() && !self.ahead_list.found_none {
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
        if !quiet.list.covers(strayed, needed, margin) {
            if !quiet.found_none {
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
            self.stats.ahead_rebuilds += 1;
        }
        let quiet = &mut self.ahead_list;
        let nothing = quiet.list.clear_of(base, &quiet.sides, quiet.eps.max(eps));
        quiet.spared |= nothing;
        nothing
    }
}

impl SelfCollision {
    #[cfg(test)]
    fn ahead_always(&self) -> bool {
        self.ahead_list.always
    }

    #[cfg(not(test))]
    fn ahead_always(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Skipping the search ahead never leaves out a pair it would find: on a resting cloth
    /// given velocities from none to fast enough to bring its neighbours together within the
    /// step, the pairs ahead are those of the search run every time, in the same order.
    #[test]
    fn the_pairs_ahead_are_the_search_s_whether_it_runs_or_not() {
        let scene = crate::Scene::builtin("twist").unwrap();
        let (model, pos) = Model::new(scene).unwrap();
        let n = model.grid.len();
        let h = 1.0 / 240.0;
        let mut skipping = SelfCollision::new(3e-3, 0.0, 1);
        let mut searching = SelfCollision::new(3e-3, 0.0, 1);
        searching.ahead_list.always = true;
        let (mut skipped, mut found) = (0, 0);
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
            let skip = skipping.pairs_ahead(&model, &from, h).to_vec();
            let all = searching.pairs_ahead(&model, &from, h).to_vec();
            assert_eq!(skip.len(), all.len(), "step {k}");
            let same = |a: &Pair, b: &Pair| a.verts == b.verts && a.d0.to_bits() == b.d0.to_bits();
            assert!(skip.iter().zip(&all).all(|(a, b)| same(a, b)), "step {k}");
            skipped += u32::from(skipping.stats.ahead_searches == before);
            found += u32::from(!all.is_empty());
        }
        assert!(skipped > 0 && found > 0, "skipped {skipped}, found {found}");
    }
}
