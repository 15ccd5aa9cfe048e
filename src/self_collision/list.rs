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

use glam::DVec3;
use rayon::prelude::*;

use crate::self_collision::pair::Candidate;
use crate::soa::Vec3s;

/// The list and where it was built.
#[derive(Default)]
pub struct PairList {
    /// Positions of every particle when the list was built (only the mesh's vertices count).
    anchor: Option<Vec3s>,
    /// Every pair closer than this at `anchor` is listed, in m.
    reach: f64,
    pub candidates: Vec<Candidate>,
}

impl PairList {
    /// Forgets the list (the mesh changed).
    pub fn clear(&mut self) {
        self.anchor = None;
        self.candidates.clear();
    }

    /// Whether every pair of `verts` closer than `needed` at `x` is listed, allowing `eps` for
    /// round-off.
    pub fn covers(&self, verts: &[u32], x: &Vec3s, needed: f64, eps: f64) -> bool {
        self.anchor
            .as_ref()
            .is_some_and(|a| self.reach - 2.0 * spread(verts, a, x) - eps >= needed)
    }

    /// Takes `candidates`, every pair closer than `reach` at `x`, as the new list.
    pub fn rebuild(&mut self, x: &Vec3s, reach: f64, candidates: impl Iterator<Item = Candidate>) {
        match &mut self.anchor {
            Some(a) if a.len() == x.len() => a.copy_from(x),
            anchor => *anchor = Some(x.clone()),
        }
        self.reach = reach;
        self.candidates.clear();
        self.candidates.extend(candidates);
    }

    pub fn heap_bytes(&self) -> usize {
        self.anchor.as_ref().map_or(0, Vec3s::heap_bytes)
            + self.candidates.capacity() * size_of::<Candidate>()
    }
}

/// The bounding box of the displacements `b_i - a_i` over `verts` (m; empty if none). Exact
/// reductions (min and max), so the same for any thread count.
pub fn displacements(verts: &[u32], a: &Vec3s, b: &Vec3s) -> Spread {
    verts
        .par_iter()
        .with_min_len(4096)
        .map(|&v| {
            let d = b.get(v as usize).as_dvec3() - a.get(v as usize).as_dvec3();
            Spread { lo: d, hi: d }
        })
        .reduce(Spread::default, Spread::union)
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

/// `displacements(verts, a, b).radius()`.
pub fn spread(verts: &[u32], a: &Vec3s, b: &Vec3s) -> f64 {
    displacements(verts, a, b).radius()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

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
        assert!(
            !list.covers(&[0, 1], &a, 0.0, 0.0),
            "an empty list covers nothing"
        );
        list.rebuild(&a, 0.01, std::iter::empty());
        assert!(list.covers(&[0, 1], &a, 0.01, 0.0));
        let mut b = a.clone();
        b.set(1, Vec3::new(1.002, 0.0, 0.0)); // spread 0.001
        assert!(list.covers(&[0, 1], &b, 0.0079, 0.0));
        assert!(!list.covers(&[0, 1], &b, 0.0081, 0.0));
        list.clear();
        assert!(!list.covers(&[0, 1], &a, 0.0, 0.0));
    }
}
