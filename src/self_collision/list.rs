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
//!
//! The bound holds for any anchor, not only one where the cloth once was: so when a few
//! vertices pass their bound, only they are given a new anchor (where they are, less the common
//! translation), and only the pairs through them are searched for again there and merged in.
//! The list is then still every pair closer than `reach` at the anchor, in key order, exactly
//! what a search of the whole mesh at the anchor finds.

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
    /// Which of those [`PairList::hot`] found may act in the substep, as long as the list too.
    hot: Vec<u32>,
    /// Each particle's own stray from the cloth's common displacement since the anchor, as the
    /// last [`PairList::strayed`] found it (m; zero at a rebuild and for a particle in no
    /// triangle), the most of them, and that common displacement (m).
    strays: Vec<f64>,
    most_strayed: f64,
    common: DVec3,
    /// The vertices [`PairList::mark_past`] marked to be queried again, one flag a particle,
    /// and which they are.
    moved: Vec<bool>,
    past: Vec<u32>,
    /// The list being merged into ([`PairList::merge`]), swapped with it after.
    merged_candidates: Vec<Candidate>,
    merged_distances: Vec<f64>,
}

impl PairList {
    /// Forgets the list (the mesh changed).
    pub fn clear(&mut self) {
        self.anchor = None;
        self.candidates.clear();
        self.distances.clear();
        self.strays.clear();
        self.most_strayed = 0.0;
        self.moved.clear();
        self.past.clear();
    }

    /// How far every pair is listed to at the anchor (m).
    pub fn reach(&self) -> f64 {
        self.reach
    }

    /// The most any vertex strays, as the last [`PairList::strayed`] or requery left it (m).
    pub fn most_strayed(&self) -> f64 {
        self.most_strayed
    }

    /// The most a vertex may stray for the list to cover a substep that needs `needed`
    /// ([`PairList::covers`]; m, negative when the reach itself is short).
    pub fn bound(&self, needed: f64, eps: f64) -> f64 {
        0.5 * (self.reach - needed - eps)
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

    /// The most any vertex at `x` (a particle `in_mesh`) strays from the cloth's common
    /// displacement since the anchor (m): the largest `|x_v - anchor_v - T|`, `T` the centre of
    /// `drift`, the box of those displacements. A pair's distance has changed by at most twice
    /// that. At most `drift.radius()`, and below it when no vertex sits in a corner of the box
    /// (a cloth whose rim falls while its middle rests: about three quarters of it in the
    /// pile). An exact reduction (max), so the same for any thread count. None without an
    /// anchor.
    ///
    /// Each vertex's own stray is kept for [`PairList::within`]: a pair's distance has changed
    /// by at most the most either of its primitives' vertices strayed, and most of a settling
    /// cloth's vertices stray far less than its farthest.
    pub fn strayed(&mut self, in_mesh: &[bool], x: &Vec3s, drift: Spread) -> Option<f64> {
        let anchor = self.anchor.as_ref()?;
        let centre = 0.5 * (drift.lo + drift.hi);
        let from_centre = |(v, stray): (usize, &mut f64)| {
            if in_mesh[v] {
                *stray = (x.get(v).as_dvec3() - anchor.get(v).as_dvec3() - centre).length();
            }
            *stray
        };
        self.most_strayed = self
            .strays
            .par_iter_mut()
            .with_min_len(4096)
            .enumerate()
            .map(from_centre)
            .reduce(|| 0.0, f64::max);
        self.common = centre;
        Some(self.most_strayed)
    }

    /// Marks the vertices of `verts` that stray more than `beyond` (m) to be queried again, and
    /// returns how many there are.
    pub fn mark_past(&mut self, verts: &[u32], beyond: f64) -> usize {
        self.unmark();
        self.moved.resize(self.strays.len(), false);
        let strays = &self.strays;
        self.past
            .extend(verts.iter().filter(|&&v| strays[v as usize] > beyond));
        for &v in &self.past {
            self.moved[v as usize] = true;
        }
        self.past.len()
    }

    /// Forgets the marks of [`PairList::mark_past`].
    pub fn unmark(&mut self) {
        for &v in &self.past {
            self.moved[v as usize] = false;
        }
        self.past.clear();
    }

    /// Moves the anchor of each marked vertex to where it is at `x`, less the cloth's common
    /// displacement since the anchor (so it strays no more): every listed pair through a
    /// marked vertex must then be measured again at the anchor, and merged in
    /// ([`PairList::merge`]). The other pairs keep their distances, which are still those at
    /// the anchor: the list stays what a search at the anchor would list.
    pub fn reanchor_marked(&mut self, x: &Vec3s) {
        let anchor = self.anchor.as_mut().expect("a list to re-anchor");
        for &v in &self.past {
            let v = v as usize;
            let at = x.get(v).as_dvec3() - self.common;
            anchor.set(v, at.as_vec3());
            let stray = x.get(v).as_dvec3() - anchor.get(v).as_dvec3() - self.common;
            self.strays[v] = stray.length();
        }
        self.most_strayed = self.strays.iter().copied().fold(0.0, f64::max);
    }

    /// Which particles [`PairList::mark_past`] marked.
    pub fn marked(&self) -> &[bool] {
        &self.moved
    }

    /// Replaces every listed pair through a marked vertex with `found`, the pairs through a
    /// marked vertex closer than the reach at the anchor, in the order of their keys, with
    /// their distances there; then forgets the marks.
    pub fn merge(&mut self, found: impl Iterator<Item = (Candidate, f64)>) {
        let (candidates, distances) = (&mut self.merged_candidates, &mut self.merged_distances);
        candidates.clear();
        distances.clear();
        let moved = &self.moved;
        let mut found = found.peekable();
        for (c, &d) in self.candidates.iter().zip(&self.distances) {
            if c.verts.iter().any(|&v| moved[v as usize]) {
                continue;
            }
            while let Some((f, e)) = found.next_if(|(f, _)| f.key() < c.key()) {
                candidates.push(f);
                distances.push(e);
            }
            candidates.push(*c);
            distances.push(d);
        }
        for (f, e) in found {
            candidates.push(f);
            distances.push(e);
        }
        std::mem::swap(&mut self.candidates, candidates);
        std::mem::swap(&mut self.distances, distances);
        debug_assert!(self.candidates.windows(2).all(|w| w[0].key() < w[1].key()));
        self.reserve_near();
        self.unmark();
    }

    /// Room for every listed pair in `near` and `hot`, so that a substep on a kept list never
    /// allocates.
    fn reserve_near(&mut self) {
        self.near.clear();
        self.near.reserve(self.candidates.len());
        self.hot.clear();
        self.hot.reserve(self.candidates.len());
    }

    /// The least distance of a listed pair at the anchor (m; infinite with none listed).
    pub fn least_distance(&self) -> f64 {
        self.distances.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// The listed pairs and their distances at the anchor.
    #[cfg(test)]
    pub fn listed(&self) -> (&[Candidate], &[f64]) {
        (&self.candidates, &self.distances)
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
            Some(a) => a.assign(x),
            anchor => *anchor = Some(x.clone()),
        }
        self.reach = reach;
        self.strays.clear();
        self.strays.resize(x.len(), 0.0);
        self.most_strayed = 0.0;
        // Where the cloth is now is the anchor: a re-anchoring before the next
        // [`PairList::strayed`] puts a vertex where it is.
        self.common = DVec3::ZERO;
        self.unmark();
        self.candidates.clear();
        self.distances.clear();
        for (c, d) in found {
            self.candidates.push(c);
            self.distances.push(d);
        }
        debug_assert!(self.candidates.windows(2).all(|w| w[0].key() < w[1].key()));
        self.reserve_near();
    }

    /// The listed pairs that may be closer than `d` now, in the order of their keys: those
    /// whose distance at the anchor, less the most any vertex of each of their two primitives
    /// strayed since ([`PairList::strayed`], or nothing since a rebuild) and `eps` for each, is
    /// below `d`.
    pub fn within(
        &mut self,
        d: f64,
        eps: f64,
    ) -> impl IndexedParallelIterator<Item = Candidate> + '_ {
        self.near.clear();
        let strays = &self.strays;
        let side = |s: &[u32]| s.iter().map(|&v| strays[v as usize]).fold(0.0, f64::max);
        // The farthest vertex's stray first: it passes over most pairs by their distance
        // alone, without reading the pair.
        let loose = d + 2.0 * (self.most_strayed + eps);
        let candidates = &self.candidates;
        let near = |&(k, &e): &(usize, &f64)| {
            e < loose && {
                let c = &candidates[k];
                let (a, b) = c.verts.split_at(usize::from(c.split).min(4));
                e < d + side(a) + side(b) + 2.0 * eps
            }
        };
        let listed = self.distances.iter().enumerate().filter(near);
        self.near.extend(listed.map(|(k, _)| k as u32));
        self.near.par_iter().map(move |&k| candidates[k as usize])
    }

    /// The listed pairs that may now be closer than `base` and the most that any vertex of
    /// each of its primitives reaches (`reach`, by particle, at least `least` for a vertex of
    /// the mesh; m), in the order of their keys, as their places in the list: those whose
    /// distance at the anchor, less the most any vertex of each primitive strayed since
    /// ([`PairList::strayed`]) and `eps` for each, is below that. With [`PairList::covers`]
    /// for `base + 2 max(reach)`, no pair of the mesh left out is closer.
    pub fn unclear(&mut self, base: f64, (reach, least): (&[f64], f64), eps: f64) -> &[u32] {
        let strays = &self.strays;
        let farthest = reach.iter().copied().fold(0.0, f64::max);
        // Most pairs are farther than the farthest vertex allows for, read by distance alone,
        // and most of a cloth at rest are nearer than the nearest allows for (a sum of sides
        // no smaller, rounded alike).
        let loose = base + 2.0 * (self.most_strayed + farthest + eps);
        let sure = base + least + least + 2.0 * eps;
        let candidates = &self.candidates;
        let near = |(k, &e): (usize, &f64)| {
            let near = e < loose
                && (e < sure || {
                    let (a, b) = sides(&candidates[k], strays, reach);
                    e < base + a + b + 2.0 * eps
                });
            near.then_some(k as u32)
        };
        self.near.clear();
        let listed = self.distances.par_iter().enumerate().with_min_len(4096);
        self.near.par_extend(listed.filter_map(near));
        &self.near
    }

    /// The pairs the last [`PairList::unclear`] picked.
    pub fn picked(&self) -> &[u32] {
        &self.near
    }

    /// Of the pairs the last [`PairList::within`] found, those that may come within `limit`
    /// (m) of each other in the substep, in the order of their keys: a pair whose distance at
    /// the anchor, less the most any vertex of each primitive strayed since
    /// ([`PairList::strayed`]) and the most any of them strays in the substep (`moving`, each
    /// particle's distance from the substep's common displacement, m), and `eps` for each, is
    /// not below `limit`, is at least `limit` apart at the substep's start and end and along the
    /// straight path between them.
    pub fn hot(
        &mut self,
        limit: f64,
        eps: f64,
        moving: &[f64],
    ) -> impl IndexedParallelIterator<Item = Candidate> + '_ {
        self.hot.clear();
        let (strays, candidates, distances) = (&self.strays, &self.candidates, &self.distances);
        let hot = |&&k: &&u32| {
            let c = &candidates[k as usize];
            let (a, b) = sides(c, strays, moving);
            distances[k as usize] < limit + a + b + 2.0 * eps
        };
        self.hot.extend(self.near.iter().filter(hot));
        self.hot.par_iter().map(move |&k| candidates[k as usize])
    }

    pub fn heap_bytes(&self) -> usize {
        self.anchor.as_ref().map_or(0, Vec3s::heap_bytes)
            + self.candidates.capacity() * size_of::<Candidate>()
            + self.distances.capacity() * 8
            + (self.near.capacity() + self.hot.capacity()) * 4
            + self.strays.capacity() * 8
            + self.moved.capacity()
            + self.past.capacity() * 4
            + self.merged_candidates.capacity() * size_of::<Candidate>()
            + self.merged_distances.capacity() * 8
    }
}

/// How far each of the pair `c`'s two primitives may have moved towards the other: the most any
/// of its vertices strayed since the anchor (`strays`) and the most any of them reaches
/// (`reach`, by particle), both in m.
fn sides(c: &Candidate, strays: &[f64], reach: &[f64]) -> (f64, f64) {
    let side = |s: &[u32]| {
        let most = |a: &[f64]| s.iter().map(|&v| a[v as usize]).fold(0.0, f64::max);
        most(strays) + most(reach)
    };
    let (a, b) = c.verts.split_at(usize::from(c.split).min(4));
    (side(a), side(b))
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

    /// The box's centre: the common displacement its displacements stray from.
    pub fn centre(&self) -> DVec3 {
        0.5 * (self.lo + self.hi)
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
        assert_eq!(list.strayed(&[true; 2], &a, Spread::default()), None);
        list.rebuild(&a, 0.01, std::iter::empty());
        let mut strayed = |x: &Vec3s| list.strayed(&[true; 2], x, displacements(&[0, 1], &a, x));
        let (at_a, mut b) = (strayed(&a), a.clone());
        b.set(1, Vec3::new(1.002, 0.0, 0.0)); // spread 0.001
        let at_b = strayed(&b);
        assert!(list.covers(at_a, 0.01, 0.0));
        assert!(list.covers(at_b, 0.0079, 0.0));
        assert!(!list.covers(at_b, 0.0081, 0.0));
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
        let strayed = list.strayed(&[true; 5], &b, drift).unwrap();
        assert!((strayed - 0.002).abs() < 1e-5, "{strayed}");
        // Covered with the farthest vertex's bound, not with the box's.
        assert!(list.covers(Some(strayed), 0.0055, 0.0));
        assert!(!list.covers(Some(drift.radius()), 0.0055, 0.0));
    }

    /// A substep looks at the listed pairs that its own vertices' strays could have brought
    /// within reach, not all those the farthest vertex's could: a settling cloth's farthest
    /// vertex strays several times as far as most, and each pair looked at costs its closest
    /// points.
    #[test]
    fn a_pair_is_near_by_its_own_vertices_stray_not_the_farthest() {
        let a = Vec3s::from_fn(8, |v| Vec3::new(v as f32, 0.0, 0.0));
        let pair = |v: u32, d: f64| {
            let verts = [v, v + 1, v + 2, v + 3];
            (Candidate { verts, split: 1 }, d)
        };
        let mut list = PairList::default();
        list.rebuild(&a, 0.01, [pair(0, 0.005), pair(4, 0.005)].into_iter());
        assert_eq!(list.within(0.004, 0.0).count(), 0);
        // Vertices 6 and 7 (of the second pair's triangle) stray 0.002 either way from the
        // common displacement (zero: the others stay); the first pair's vertices do not stray.
        let mut b = a.clone();
        b.set(6, a.get(6) - Vec3::new(0.0, 0.002, 0.0));
        b.set(7, a.get(7) + Vec3::new(0.0, 0.002, 0.0));
        let verts: Vec<u32> = (0..8).collect();
        let strayed = list.strayed(&[true; 8], &b, displacements(&verts, &a, &b));
        assert!((strayed.unwrap() - 0.002).abs() < 1e-6, "{strayed:?}");
        // The second pair may be 0.005 - 0.002 apart now, the first is still 0.005 apart
        // (twice the farthest stray would let both through below 0.0035).
        let near: Vec<u32> = list.within(0.0035, 0.0).map(|c| c.verts[0]).collect();
        assert_eq!(near, [4]);
        assert_eq!(list.within(0.0029, 0.0).count(), 0);
        assert_eq!(list.within(0.0051, 0.0).count(), 2);
    }

    #[test]
    fn the_nearest_come_in_the_order_of_their_keys() {
        let a = Vec3s::zeros(4);
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
        let first: Vec<u32> = list.within(0.004, 0.0).map(|c| c.verts[0]).collect();
        assert_eq!(first, [1, 2, 3]);
        assert_eq!(list.within(0.001, 0.0).count(), 0);
        assert_eq!(list.within(1.0, 0.0).count(), 4);
    }
}
