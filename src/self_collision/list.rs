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
use rayon::prelude::*;

/// The list and where it was built.
#[derive(Default)]
pub struct PairList {
    /// Positions of every particle when the list was built (only the mesh's vertices count).
    anchor: Option<Vec3s>,
    /// Every pair closer than this at `anchor` is listed, in m.
    reach: f64,
    /// The listed pairs in the order of their keys ([`Candidate::key`]), each with its
    /// distance at the anchor (m). Kept in that order, not sorted by distance, so that the
    /// pairs a substep takes from it come in the order it looks at them: a filter, not a sort.
    candidates: Vec<Candidate>,
    distances: Vec<f64>,
    /// Where in `candidates` the last [`PairList::within`] found its pairs; as long as the
    /// list, so that taking pairs from a kept list never allocates.
    near: Vec<u32>,
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

    /// Whether every pair closer than `needed` at some positions is listed, given `strayed`,
    /// the most any vertex strayed from the cloth's common displacement since the anchor
    /// ([`PairList::strayed`]); `eps` allows for round-off.
    pub fn covers(&self, strayed: Option<f64>, needed: f64, eps: f64) -> bool {
        strayed.is_some_and(|s| self.reach - 2.0 * s - eps >= needed)
    }

    /// The most any of `verts` at `x` strays from the cloth's common displacement since the
    /// anchor (m): the largest `|x_v - anchor_v - T|`, `T` the centre of `drift`, the box of
    /// those displacements. A pair's distance has changed by at most twice that. At most
    /// `drift.radius()`, and below it when no vertex sits in a corner of the box (a cloth whose
    /// rim falls while its middle rests: about three quarters of it in the pile). An exact
    /// reduction (max), so the same for any thread count. None without an anchor.
    pub fn strayed(&self, verts: &[u32], x: &Vec3s, drift: Spread) -> Option<f64> {
        let anchor = self.anchor.as_ref()?;
        let centre = 0.5 * (drift.lo + drift.hi);
        let from_centre = |&v: &u32| {
            let v = v as usize;
            (x.get(v).as_dvec3() - anchor.get(v).as_dvec3() - centre).length()
        };
        Some(
            verts
                .par_iter()
                .with_min_len(4096)
                .map(from_centre)
                .reduce(|| 0.0, f64::max),
        )
    }

    /// Takes `found`, every pair closer than `reach` at `x` with its distance there, in the
    /// order of the pairs' keys, as the new list.
    pub fn rebuild(
        &mut self,
        x: &Vec3s,
        reach: f64,
        found: impl Iterator<Item = (Candidate, f64)>,
    ) {
        match &mut self.anchor {
            Some(a) if a.len() == x.len() => a.copy_from(x),
            anchor => *anchor = Some(x.clone()),
        }
        self.reach = reach;
        self.candidates.clear();
        self.distances.clear();
        for (c, d) in found {
            self.candidates.push(c);
            self.distances.push(d);
        }
        debug_assert!(self.candidates.windows(2).all(|w| w[0].key() < w[1].key()));
        self.near.clear();
        self.near.reserve(self.candidates.len());
    }

    /// The listed pairs that were closer than `d` at the anchor, in the order of their keys.
    pub fn within(&mut self, d: f64) -> impl IndexedParallelIterator<Item = Candidate> + '_ {
        self.near.clear();
        let near = self.distances.iter().enumerate().filter(|(_, &e)| e < d);
        self.near.extend(near.map(|(k, _)| k as u32));
        let candidates = &self.candidates;
        self.near.par_iter().map(move |&k| candidates[k as usize])
    }

    pub fn heap_bytes(&self) -> usize {
        self.anchor.as_ref().map_or(0, Vec3s::heap_bytes)
            + self.candidates.capacity() * size_of::<Candidate>()
            + self.distances.capacity() * 8
            + self.near.capacity() * 4
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
        assert_eq!(list.strayed(&[0, 1], &a, Spread::default()), None);
        list.rebuild(&a, 0.01, std::iter::empty());
        let strayed = |x: &Vec3s| list.strayed(&[0, 1], x, displacements(&[0, 1], &a, x));
        assert!(list.covers(strayed(&a), 0.01, 0.0));
        let mut b = a.clone();
        b.set(1, Vec3::new(1.002, 0.0, 0.0)); // spread 0.001
        assert!(list.covers(strayed(&b), 0.0079, 0.0));
        assert!(!list.covers(strayed(&b), 0.0081, 0.0));
        list.clear();
        assert!(list.anchor().is_none());
    }

    /// The bound the list is kept by is each vertex's own distance from the common
    /// displacement, not the corner of the displacements' box: four vertices moved by 0.002
    /// along +x, -x, +y and -y spread a box whose half diagonal is 0.002 sqrt 2, while none
    /// strays more than 0.002 from its centre.
    #[test]
    fn the_list_is_kept_by_the_farthest_vertex_not_the_box_corner() {
        let a = Vec3s::from_fn(5, |v| Vec3::new(v as f32, 0.0, 0.0));
        let mut list = PairList::default();
        list.rebuild(&a, 0.01, std::iter::empty());
        let mut b = a.clone();
        for (v, step) in [(1, Vec3::X), (2, -Vec3::X), (3, Vec3::Y), (4, -Vec3::Y)] {
            b.set(v, a.get(v) + 0.002 * step);
        }
        let verts = [0, 1, 2, 3, 4];
        let drift = displacements(&verts, &a, &b);
        assert!((drift.radius() - 0.002 * 2f64.sqrt()).abs() < 1e-5);
        let strayed = list.strayed(&verts, &b, drift).unwrap();
        assert!((strayed - 0.002).abs() < 1e-5, "{strayed}");
        // Covered with the farthest vertex's bound, not with the box's.
        assert!(list.covers(Some(strayed), 0.0055, 0.0));
        assert!(!list.covers(Some(drift.radius()), 0.0055, 0.0));
    }

    #[test]
    fn the_nearest_come_in_the_order_of_their_keys() {
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
        let found = [at(0.005, 0), at(0.001, 1), at(0.003, 2), at(0.001, 3)];
        list.rebuild(&a, 0.01, found.into_iter());
        let first: Vec<u32> = list.within(0.004).map(|c| c.verts[0]).collect();
        assert_eq!(first, [1, 2, 3]);
        assert_eq!(list.within(0.001).count(), 0);
        assert_eq!(list.within(1.0).count(), 4);
    }
}
