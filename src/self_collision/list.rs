//! The pair list: which vertex-triangle and edge-edge pairs a substep must look at, kept across
//! substeps instead of searched for in each (a Verlet list, as molecular dynamics keeps its
//! neighbour lists).
//!
//! Built at positions `anchor` with a `reach`, it holds every pair closer than `reach` there.
//! The distance of a pair is 1-Lipschitz in the relative motion of its vertices, and blind to
//! a common translation: if every vertex has moved from the anchor by `T + e_i` for one `T`,
//! with `|e_i| <= r`, a pair's distance has changed by at most `2 r`. So while
//! `reach - 2 r` stays above what a substep needs, every pair the substep needs is in the list
//! ([`PairList::covers`]); when it no longer does, the list is built again where the cloth is.
//! The translation is the centre of the displacements' bounding box, so a cloth that falls
//! or is carried as a whole keeps its list however far it goes.

use crate::self_collision::pair::Candidate;
use crate::soa::Vec3s;
use glam::DVec3;

/// The list and where it was built.
#[derive(Default)]
pub struct PairList {
    /// Positions of every particle when the list was built (only the mesh's vertices count).
    anchor: Option<Vec3s>,
    /// Every pair closer than this at `anchor` is listed, in m.
    reach: f64,
    /// The listed pairs, nearest at the anchor first, each with its distance there (m).
    candidates: Vec<Candidate>,
    distances: Vec<f64>,
}

impl PairList {
    /// Forgets the list (the mesh changed).
    pub fn clear(&mut self) {
        self.anchor = None;
        self.candidates.clear();
        self.distances.clear();
    }

    /// Where the list was built, if it was.
    pub fn anchor(&self) -> Option<&Vec3s> {
        self.anchor.as_ref()
    }

    /// Whether every pair closer than `needed` at some positions is listed, given `drift`, the
    /// displacements from the anchor to those positions; `eps` allows for round-off.
    pub fn covers(&self, drift: Option<Spread>, needed: f64, eps: f64) -> bool {
        drift.is_some_and(|d| self.reach - 2.0 * d.radius() - eps >= needed)
    }

    /// Takes `found`, every pair closer than `reach` at `x` with its distance there, as the new
    /// list.
    pub fn rebuild(&mut self, x: &Vec3s, reach: f64, mut found: Vec<(Candidate, f64)>) {
        match &mut self.anchor {
            Some(a) if a.len() == x.len() => a.copy_from(x),
            anchor => *anchor = Some(x.clone()),
        }
        self.reach = reach;
        // Nearest first, ties by the pair (unique), so the order is the same however `found`
        // was.
        found.sort_unstable_by(|p, q| p.1.total_cmp(&q.1).then(p.0.key().cmp(&q.0.key())));
        self.candidates.clear();
        self.distances.clear();
        for (c, d) in found {
            self.candidates.push(c);
            self.distances.push(d);
        }
    }

    /// The listed pairs that were closer than `d` at the anchor.
    pub fn within(&self, d: f64) -> &[Candidate] {
        &self.candidates[..self.distances.partition_point(|&e| e < d)]
    }

    pub fn heap_bytes(&self) -> usize {
        self.anchor.as_ref().map_or(0, Vec3s::heap_bytes)
            + self.candidates.capacity() * size_of::<Candidate>()
            + self.distances.capacity() * 8
    }
}

/// A bounding box of displacements. Half its diagonal bounds `|d_i - T|` for every
/// displacement `d_i` in it, with `T` its centre: twice that bounds how much the distance
/// between any two of the vertices changed, and along the straight path between.
#[derive(Clone, Copy, Debug)]
pub struct Spread {
    lo: DVec3,
    hi: DVec3,
}

impl Default for Spread {
    fn default() -> Self {
        Spread {
            lo: DVec3::INFINITY,
            hi: DVec3::NEG_INFINITY,
        }
    }
}

impl Spread {
    /// The box of the one displacement `d`.
    pub fn of(d: DVec3) -> Spread {
        Spread { lo: d, hi: d }
    }

    pub fn union(self, other: Spread) -> Spread {
        Spread {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    /// Adds the displacement `d`.
    pub fn add(&mut self, d: DVec3) {
        self.lo = self.lo.min(d);
        self.hi = self.hi.max(d);
    }

    /// Half the diagonal (m): the most any displacement strays from the common one.
    pub fn radius(&self) -> f64 {
        if self.lo.x > self.hi.x {
            return 0.0;
        }
        0.5 * (self.hi - self.lo).length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use rayon::prelude::*;

    /// The bounding box of the displacements `b_i - a_i` over `verts` (m; empty if none). Exact
    /// reductions (min and max), so the same for any thread count.
    fn displacements(verts: &[u32], a: &Vec3s, b: &Vec3s) -> Spread {
        verts
            .par_iter()
            .with_min_len(4096)
            .map(|&v| Spread::of(b.get(v as usize).as_dvec3() - a.get(v as usize).as_dvec3()))
            .reduce(Spread::default, Spread::union)
    }

    /// `displacements(verts, a, b).radius()`.
    fn spread(verts: &[u32], a: &Vec3s, b: &Vec3s) -> f64 {
        displacements(verts, a, b).radius()
    }

    #[test]
    fn a_common_translation_does_not_spread() {
        let a = Vec3s::from_fn(5, |v| Vec3::new(v as f32, 0.0, 0.0));
        let b = Vec3s::from_fn(5, |v| a.get(v) + Vec3::new(0.0, -2.5, 1.0));
        assert_eq!(spread(&[0, 1, 2, 3, 4], &a, &b), 0.0);
        // One vertex 0.2 off the others: half of it each way from the midpoint.
        let mut c = b.clone();
        c.set(3, c.get(3) + Vec3::new(0.0, 0.2, 0.0));
        let s = spread(&[0, 1, 2, 3, 4], &a, &c);
        assert!((s - 0.1).abs() < 1e-6, "{s}");
        // Only the listed vertices count.
        assert_eq!(spread(&[0, 1, 2, 4], &a, &c), 0.0);
        // Off along two axes: half the diagonal of the displacements' box.
        c.set(0, c.get(0) + Vec3::new(0.0, 0.0, 0.2));
        let s = spread(&[0, 1, 2, 3, 4], &a, &c);
        assert!((s - 0.1 * 2f64.sqrt()).abs() < 1e-6, "{s}");
    }

    #[test]
    fn the_list_covers_what_it_reaches_less_twice_the_spread() {
        let a = Vec3s::from_fn(2, |v| Vec3::new(v as f32, 0.0, 0.0));
        let mut list = PairList::default();
        assert!(list.anchor().is_none(), "an empty list covers nothing");
        assert!(!list.covers(None, 0.0, 0.0));
        list.rebuild(&a, 0.01, Vec::new());
        let drift = |x: &Vec3s| Some(displacements(&[0, 1], &a, x));
        assert!(list.covers(drift(&a), 0.01, 0.0));
        let mut b = a.clone();
        b.set(1, Vec3::new(1.002, 0.0, 0.0)); // spread 0.001
        assert!(list.covers(drift(&b), 0.0079, 0.0));
        assert!(!list.covers(drift(&b), 0.0081, 0.0));
        list.clear();
        assert!(list.anchor().is_none());
    }

    #[test]
    fn the_nearest_are_first_whatever_their_order() {
        let a = Vec3s::zeros(1);
        let at = |d: f64, v: u32| {
            (
                Candidate {
                    verts: [v, 1, 2, 3],
                    split: 1,
                },
                d,
            )
        };
        let mut list = PairList::default();
        list.rebuild(
            &a,
            0.01,
            vec![at(0.005, 0), at(0.001, 1), at(0.003, 2), at(0.001, 3)],
        );
        let first: Vec<u32> = list.within(0.004).iter().map(|c| c.verts[0]).collect();
        assert_eq!(first, [1, 3, 2]);
        assert_eq!(list.within(0.001).len(), 0);
        assert_eq!(list.within(1.0).len(), 4);
    }
}
