//! The cap (hard, what makes the guarantee). The distance between a vertex and a triangle, or
//! between two edges, is 1-Lipschitz in the relative position of the two primitives: along the
//! straight motion `x0 + t dx`, `t` in `[0, 1]`, it is at least `d0 - t m` with `d0` its value
//! at `x0` and `m = max |dx_i - dx_j|` over vertices `i` of one primitive and `j` of the other.
//! So a pair with `m < d0` cannot touch during the substep.
//!
//! Sliding and separating motion count in `m` too, so a second bound is used beside it: the
//! plane through the closest points at `x0`, normal `n`, separates the two primitives (both are
//! convex), `(x_i - x_j) . n >= d0` for all such `i, j`; each of these is linear in `t`, so if
//! all are positive at the end of the substep the plane separates them all along. A pair is
//! safe when `m <= APPROACH d0 - eps` or every `(x_i - x_j) . n >= (1 - APPROACH) d0 + eps` at
//! the end.
//!
//! The cap scales the displacement of the vertices of every pair safe by neither bound toward
//! `x0` (`dx_i -> s_i dx_i`), for a few rounds in proportion, then by stopping them (`s = 0`),
//! until no pair is left: it ends because each round stops at least one more vertex, and a pair
//! whose vertices all stand still has `m = 0`. Capped vertices get their velocity scaled by `s`
//! too, and stay in their capsule (see the parent module).

use glam::{DVec3, Vec3};

use super::pair::Pair;
use super::SelfCollision;
use crate::soa::Vec3s;
use crate::state::Kinematics;

/// Fraction of a pair's distance at the start of a substep that its relative motion may close
/// within it. Close to 1 so that the cap seldom acts (the repulsion keeps pairs at
/// `thickness`, and only a relative motion of 0.9 `thickness` per substep reaches the cap);
/// below 1 so that a pair keeps a tenth of its distance, far above float32 round-off.
pub(super) const APPROACH: f64 = 0.9;

/// Rounds of proportional scaling before the cap stops the vertices of the pairs still too
/// fast. More rounds keep more motion in a tangle of contacts, at one pass over the pairs each.
const SCALE_ROUNDS: u32 = 8;

impl SelfCollision {
    /// The cap (see the module's comment): scales displacements from `x0` until every pair's
    /// relative motion is below `APPROACH` of its distance at `x0`, less `eps`. Unless the
    /// pairs are `whole` (every pair the substep must look at), returns false, changing
    /// nothing, when any of them is too fast: the later rounds look at the pairs of the
    /// vertices the first rescaled, which may be any.
    pub(super) fn cap(&mut self, x0: &Vec3s, next: &mut Kinematics, eps: f64, whole: bool) -> bool {
        let n = x0.len();
        self.stopped_last = 0;
        self.scale.clear();
        self.scale.resize(n, 1.0);
        self.scale_next.clear();
        self.scale_next.resize(n, 1.0);
        self.rescaled.clear();
        self.rescaled.resize(n, false);
        // Each vertex's start and move in f64 once, not once for each pair and vertex of the
        // other primitive it is in (a few dozen): the same values, so the same factors.
        self.cap_start.clear();
        self.cap_move.clear();
        if !self.pairs.is_empty() {
            let (start, moved) = (&mut self.cap_start, &mut self.cap_move);
            start.extend((0..n).map(|v| x0.get(v).as_dvec3()));
            moved.extend((0..n).map(|v| next.pos.get(v).as_dvec3() - start[v]));
        }
        let mut rounds = 0;
        loop {
            // Each pair's factor depends only on the scales of the round before (a Jacobi
            // round), so the pairs are checked in parallel; taking the least factor per vertex
            // is exact whatever the order. After the first round only a pair with a vertex
            // the last round rescaled can be unsafe: any other has the scales it was safe
            // with (a violated pair rescales its own vertices).
            let (s, rescaled) = (&self.scale, &self.rescaled);
            let motion = (&self.cap_start[..], &self.cap_move[..]);
            let unsafe_pair = |k: usize, pair: &Pair| {
                if rounds > 0 && !pair.verts.iter().any(|&v| rescaled[v as usize]) {
                    return None;
                }
                cap_factor(pair, s, motion, eps, rounds).map(|f| (k as u32, f))
            };
            let mut violations = std::mem::take(&mut self.violations);
            violations.clear();
            self.violation_parts
                .filter_map_into(&self.pairs, 1024, unsafe_pair, &mut violations);
            let violated = !violations.is_empty();
            if violated && !whole {
                self.violations = violations;
                return false;
            }
            for &(k, f) in &violations {
                for &v in &self.pairs[k as usize].verts {
                    let v = v as usize;
                    self.scale_next[v] = self.scale_next[v].min(self.scale[v] * f);
                }
            }
            self.violations = violations;
            if !violated {
                break;
            }
            rounds += 1;
            for (v, changed) in self.rescaled.iter_mut().enumerate() {
                *changed = self.scale_next[v] != self.scale[v];
            }
            self.scale.copy_from_slice(&self.scale_next);
        }
        self.stats.max_cap_rounds = self.stats.max_cap_rounds.max(rounds);
        if rounds == 0 {
            return true;
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
                self.stopped_last += (s == 0.0) as u64;
            }
        }
        self.stats.stopped += self.stopped_last;
        true
    }
}

/// The factor the cap scales a pair's vertices' displacements by in round `round`, given the
/// scales `s` so far and each vertex's start and move (`x1 - x0`, in f64), or None when the
/// pair is safe by either bound (see the module's comment).
#[inline]
fn cap_factor(
    pair: &Pair,
    s: &[f64],
    (start, disp): (&[DVec3], &[DVec3]),
    eps: f64,
    round: u32,
) -> Option<f64> {
    let pairs = || {
        (0..pair.split)
            .flat_map(move |i| (pair.split..4).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (a, b) = (pair.verts[i] as usize, pair.verts[j] as usize);
                (a, b, s[a] * disp[a] - s[b] * disp[b])
            })
    };
    // Safe by either bound: relative motion below the distance, or the plane through the
    // closest points at the start separating the two at the end (and so, by linearity, all
    // along). The Lipschitz bound first, alone: most pairs pass it, and then the plane's
    // terms are not needed.
    // Its relative motion `m` from the largest square: the square root is monotonic, so the
    // root of the largest square is the largest root, to the bit.
    let m = (pairs().map(|(_, _, rel)| rel.length_squared()))
        .fold(0.0f64, f64::max)
        .sqrt();
    let allowed = (APPROACH * pair.d0 - eps).max(0.0);
    if m <= allowed {
        return None;
    }
    // The plane bound: the least gap along `n` at the end and the most approach along it.
    let (mut gap_end, mut approach) = (f64::INFINITY, 0.0f64);
    let mut slack_start = f64::INFINITY;
    for (a, b, rel) in pairs() {
        let base = (start[a] - start[b]).dot(pair.n);
        gap_end = gap_end.min(base + rel.dot(pair.n));
        approach = approach.max(-rel.dot(pair.n));
        slack_start = slack_start.min(base);
    }
    let keep = (1.0 - APPROACH) * pair.d0 + eps;
    if gap_end >= keep {
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

#[cfg(test)]
mod tests {
    use super::super::{SelfCollisionStats, Survey};
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
        pass.cap(x0, &mut next, eps, true);
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
}
