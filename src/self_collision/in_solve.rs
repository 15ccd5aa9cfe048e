//! The pairs ahead of an implicit solve: those the step's inertial motion could bring within
//! `thickness`, found at the step's start by the swept search, for implicit Euler to hold
//! apart inside its linear solve (`src/integrators/self_contact.rs`). The pass after the solve
//! is unchanged: the solve only makes it rarely have to stop anything far.

use rayon::prelude::*;

use super::pair::Pair;
use super::search::Reuse;
use super::{SelfCollision, Survey};
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
        let Some(survey) = Survey::of(&self.topology.vertices, x0, &self.ahead, None) else {
            self.ahead_pairs.clear();
            return &self.ahead_pairs;
        };
        let eps = 1e-6 * (1.0 + survey.reach);
        let ahead = std::mem::replace(&mut self.ahead, Vec3s::zeros(0));
        self.sweep_boxes(x0, &ahead, eps as f32);
        self.ahead = ahead;
        let mut pairs = std::mem::take(&mut self.ahead_pairs);
        self.swept_search(x0, eps, Reuse::Keep, &mut pairs);
        self.ahead_pairs = pairs;
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
