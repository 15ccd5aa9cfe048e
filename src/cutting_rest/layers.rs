//! A live stroke held on every layer of a crumpled cloth, not only the one under the mouse.
//!
//! A ray through a folded or curled cloth meets several layers; each hit names a material
//! point of the rest sheet. The layers keep their order on the sheet from ray to ray (each
//! moves a fraction of a spacing a ray), so each ray's points are matched to the last ray's by
//! nearness on the sheet and each matched pair is joined there: every layer the mouse passed
//! over gets its own cut along its own material line. Depth order is not used for matching: it
//! changes wherever a layer ends, and a layer that comes from behind to the front (or goes
//! behind) is the same material.
//!
//! Where a layer's track starts or ends in the middle of the stroke, the ray passed a fold's or
//! a curl's silhouette, or the cloth's edge: two tracks starting (or ending) at one ray close
//! together on the sheet are the two sides of one fold, joined; a track starting or ending
//! within a spacing of the sheet's edge is carried out through it. Only the layer a stroke
//! came onto the cloth on, from off it, or left it from, is carried out farther (as
//! [`super::LiveStroke`] does: its edge may be curled out of sight).

use glam::DVec2;

use super::{Cut, Reach, SheetPoint};
use crate::ray::Ray;

/// The most layers one ray is followed through (6): each is another pick along the ray.
pub const MAX_LAYERS: usize = 6;

/// How far apart on the sheet, in spacings, two layers' tracks that start (or end) at the same
/// ray may be and still count as the two sides of one fold, joined across it (3). A ray grazes
/// a fold at its silhouette, so its two sides' points are about a pick's margin apart there;
/// farther apart, a join would cut material the stroke never passed over.
pub const FOLD_SPACINGS: f64 = 3.0;

/// One layer's cut in progress.
#[derive(Clone, Copy, Debug)]
struct Track {
    chart: u32,
    /// Where the last ray met this layer.
    at: DVec2,
    /// A point about one spacing back along the track, its heading's start.
    tail: DVec2,
    heading: Option<DVec2>,
    /// Where the track started and how far back through the edge its cut may be carried
    /// there, until its heading is known.
    entry: Option<(DVec2, Carry, Layer)>,
    /// Whether the last ray met this layer first.
    front: bool,
}

/// How far a track's end is carried out through the sheet's edge.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Carry {
    /// Up to a jump: the stroke came onto the cloth, or left it, on this layer.
    Far,
    /// Only where the edge is within about a spacing.
    Near,
}

/// Which of a live stroke's cuts a cut is: the one [`super::LiveStroke`] makes on the layer
/// under the mouse (its point to point on the front layer, its carries through the edge where
/// the stroke came onto the cloth or left it, its swept jumps), or one on the layers behind
/// (and the joins and short carries between tracks), which a caller may drop where it would
/// cut out a sliver beside the front's cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    Front,
    Behind,
}

impl Carry {
    /// Whose cut a carry is: a far one [`super::LiveStroke`] makes too, unless its track was
    /// joined to another layer's at that end (it may then run beside that layer's cut).
    fn layer_beside(self, joined: Option<DVec2>) -> Layer {
        match (self, joined) {
            (Carry::Far, None) => Layer::Front,
            _ => Layer::Behind,
        }
    }
}

/// A live stroke over every layer its rays pass through ([`LayeredStroke::advance`]).
#[derive(Clone, Debug, Default)]
pub struct LayeredStroke {
    last_ray: Option<Ray>,
    tracks: Vec<Track>,
}

impl LayeredStroke {
    /// Continues the stroke with `ray`, whose hits on the cloth name the material points
    /// `hits` (nearest first; empty where it missed), and hands `cut` what to sever for it;
    /// `exit(chart, from, dir)` is how far from `from` along `dir` the chart's material ends,
    /// plus a spacing.
    pub fn advance(
        &mut self,
        ray: Ray,
        hits: &[SheetPoint],
        reach: Reach,
        exit: impl Fn(u32, DVec2, DVec2) -> f64,
        mut cut: impl FnMut(Cut, Layer),
    ) {
        let Some(before) = self.last_ray.replace(ray) else {
            // A stroke's first sample: it starts where the mouse was pressed.
            self.tracks = (hits.iter().enumerate())
                .map(|(k, &h)| Track::fresh(h, k == 0))
                .collect();
            return;
        };
        let tracks = std::mem::take(&mut self.tracks);
        let sample = Sample {
            before,
            ray,
            hits,
            reach,
            exit,
        };
        let (track_of, hit_of) = match_nearest(&tracks, hits, reach.jump);
        self.tracks = sample.go_on(&tracks, &track_of, &mut cut);
        sample.end(&tracks, &hit_of, &mut cut);
        (self.tracks).extend(sample.start(&tracks, &track_of, &mut cut));
    }
}

impl Track {
    /// A track starting at `point`, met first by its ray where `front`.
    fn fresh((chart, at): SheetPoint, front: bool) -> Track {
        Track {
            chart,
            at,
            tail: at,
            heading: None,
            entry: None,
            front,
        }
    }
}

/// One ray of a stroke after the last, `before`: its hits, and the sheet's edge through `exit`.
struct Sample<'a, E> {
    before: Ray,
    ray: Ray,
    hits: &'a [SheetPoint],
    reach: Reach,
    exit: E,
}

impl<E: Fn(u32, DVec2, DVec2) -> f64> Sample<'_, E> {
    /// Carried out of `from` along `dir` through the edge: `None` where `Near` and the edge is
    /// farther than about a spacing.
    fn out(&self, c: u32, from: DVec2, dir: DVec2, carry: Carry) -> Option<DVec2> {
        let d = (self.exit)(c, from, dir);
        match carry {
            Carry::Far => Some(from + d.min(self.reach.jump) * dir),
            Carry::Near => (d <= 2.0 * self.reach.step).then(|| from + d * dir),
        }
    }

    /// Tracks that go on (`track_of`: each hit's track), joined to their new point on the
    /// sheet; returns them, moved on.
    fn go_on(
        &self,
        tracks: &[Track],
        track_of: &[Option<usize>],
        cut: &mut impl FnMut(Cut, Layer),
    ) -> Vec<Track> {
        let step = self.reach.step;
        let mut moved = Vec::with_capacity(self.hits.len());
        for (k, &(c, b)) in self.hits.iter().enumerate() {
            let Some(i) = track_of[k] else { continue };
            let t = tracks[i];
            let layer = if t.front && k == 0 {
                Layer::Front
            } else {
                Layer::Behind
            };
            cut(Cut::Rest(c, t.at, b), layer);
            let mut next = Track {
                at: b,
                front: k == 0,
                ..t
            };
            // The heading over about the last spacing on the sheet: one ray's step is a
            // fraction of a spacing, and near a curl seen edge on it points anywhere.
            let heading = (b - t.tail).try_normalize();
            if let Some(dir) = heading.filter(|_| b.distance(t.tail) >= step) {
                if let Some((entry, carry, layer)) = t.entry {
                    let back = (entry - b).try_normalize().unwrap_or(-dir);
                    if let Some(edge) = self.out(c, entry, back, carry) {
                        cut(Cut::Rest(c, entry, edge), layer);
                    }
                    next.entry = None;
                }
                next.tail = b - step * dir;
            }
            next.heading = heading.or(t.heading);
            moved.push(next);
        }
        moved
    }

    /// Tracks that end (`hit_of`: each track's hit): this ray passed their layer's edge, a
    /// fold's silhouette, or left the cloth. A fold's silhouette: the layer goes on as the
    /// fold's other side, which this ray meets near it on the sheet or which ends with it.
    fn end(&self, tracks: &[Track], hit_of: &[Option<usize>], cut: &mut impl FnMut(Cut, Layer)) {
        let (hits, now_on) = (self.hits, !self.hits.is_empty());
        let radius = FOLD_SPACINGS * self.reach.step;
        let ended: Vec<Track> = (tracks.iter().zip(hit_of))
            .filter(|(_, hit)| hit.is_none())
            .map(|(&t, _)| t)
            .collect();
        for (e, t) in ended.iter().enumerate() {
            let (c, a) = (t.chart, t.at);
            if t.front && now_on {
                // The front layer jumped, over a fold's edge onto another layer or across a
                // seam: joined on the sheet to where the ray now meets the cloth first when
                // that is near on the same chart (what lies between is the fold's turn, seen
                // edge on), else cut by the surface the two rays sweep.
                match hits[0] {
                    (hc, b) if hc == c && a.distance(b) <= self.reach.jump => {
                        // Beside the layers' own cuts there: not to cut out a sliver.
                        cut(Cut::Rest(c, a, b), Layer::Behind);
                    }
                    _ => cut(Cut::Swept(self.before, self.ray), Layer::Front),
                }
                continue;
            }
            let dir = match t.entry {
                // On the cloth for less than a spacing: in and out the same way.
                Some((entry, entry_carry, layer)) => {
                    let dir = (a - entry).try_normalize();
                    if let Some(edge) = dir.and_then(|d| self.out(c, entry, -d, entry_carry)) {
                        cut(Cut::Rest(c, entry, edge), layer);
                    }
                    dir
                }
                None => t.heading,
            };
            // A pair of ends found from both is cut twice along one segment: the second
            // finds its springs severed already.
            let others = (ended.iter().enumerate())
                .filter(|&(o, _)| o != e)
                .map(|(_, t)| (t.chart, t.at))
                .chain(hits.iter().copied());
            let joined = nearest(others, (c, a), radius);
            if let Some(b) = joined {
                cut(Cut::Rest(c, a, b), Layer::Behind);
            }
            // Left the cloth: out through its edge, which may be curled out of sight.
            let carry = if t.front && !now_on {
                Carry::Far
            } else {
                Carry::Near
            };
            if let Some(edge) = dir.and_then(|d| self.out(c, a, d, carry)) {
                cut(Cut::Rest(c, a, edge), carry.layer_beside(joined));
            }
        }
    }

    /// Points with no track (`track_of`: each hit's track): a layer the ray has just come
    /// over, at the cloth's edge, or as a fold's other side, which the last ray met near it on
    /// the sheet or which starts with it; returns their new tracks.
    fn start(
        &self,
        tracks: &[Track],
        track_of: &[Option<usize>],
        cut: &mut impl FnMut(Cut, Layer),
    ) -> Vec<Track> {
        let (hits, was_on) = (self.hits, !tracks.is_empty());
        let radius = FOLD_SPACINGS * self.reach.step;
        let started: Vec<usize> = (0..hits.len()).filter(|&k| track_of[k].is_none()).collect();
        let mut new = Vec::with_capacity(started.len());
        for &k in &started {
            let (c, b) = hits[k];
            let mut t = Track::fresh((c, b), k == 0);
            let others = (started.iter())
                .filter(|&&o| o != k)
                .map(|&o| hits[o])
                .chain(tracks.iter().map(|t| (t.chart, t.at)));
            let joined = nearest(others, (c, b), radius);
            if let Some(other) = joined {
                cut(Cut::Rest(c, b, other), Layer::Behind);
            }
            // Came onto the cloth: back out through the edge it came over, once the track's
            // heading is known.
            let carry = if k == 0 && !was_on {
                Carry::Far
            } else {
                Carry::Near
            };
            t.entry = Some((b, carry, carry.layer_beside(joined)));
            new.push(t);
        }
        new
    }
}

/// The nearest of `points` to `(c, b)` on its chart, within `radius`.
fn nearest(
    points: impl Iterator<Item = SheetPoint>,
    (c, b): SheetPoint,
    radius: f64,
) -> Option<DVec2> {
    points
        .filter(|&(pc, p)| pc == c && p.distance(b) <= radius)
        .min_by(|x, y| x.1.distance(b).total_cmp(&y.1.distance(b)))
        .map(|(_, p)| p)
}

/// Each hit's track and each track's hit: pairs on one chart within `jump` of each other on
/// the sheet, nearest first (ties in index order, so the result is deterministic).
fn match_nearest(
    tracks: &[Track],
    hits: &[SheetPoint],
    jump: f64,
) -> (Vec<Option<usize>>, Vec<Option<usize>>) {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, t) in tracks.iter().enumerate() {
        for (k, &(c, b)) in hits.iter().enumerate() {
            let d = t.at.distance(b);
            if c == t.chart && d <= jump {
                pairs.push((d, i, k));
            }
        }
    }
    pairs.sort_by(|p, q| p.0.total_cmp(&q.0).then((p.1, p.2).cmp(&(q.1, q.2))));
    let (mut track_of, mut hit_of) = (vec![None; hits.len()], vec![None; tracks.len()]);
    for (_, i, k) in pairs {
        if track_of[k].is_none() && hit_of[i].is_none() {
            track_of[k] = Some(i);
            hit_of[i] = Some(k);
        }
    }
    (track_of, hit_of)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutting_rest::LiveStroke;
    use glam::Vec3;

    /// How far from `from` along `dir` the unit square's material ends, plus a spacing.
    fn exit_square(step: f64) -> impl Fn(u32, DVec2, DVec2) -> f64 {
        move |_, from: DVec2, dir: DVec2| {
            let t = |p: f64, d: f64| match d {
                d if d > 0.0 => (1.0 - p) / d,
                d if d < 0.0 => -p / d,
                _ => f64::INFINITY,
            };
            t(from.x, dir.x).min(t(from.y, dir.y)).max(0.0) + step
        }
    }

    fn ray(k: usize) -> Ray {
        Ray::new(Vec3::new(k as f32, 0.0, 1.0), Vec3::NEG_Z).unwrap()
    }

    const REACH: Reach = Reach {
        step: 0.05,
        jump: 0.4,
    };

    #[test]
    fn one_layer_is_cut_as_the_live_stroke_cuts_it() {
        // Off the sheet, across it in small steps with a wobble, off it, and back on.
        let hit = |k: usize| {
            let x = -0.1 + 0.013 * k as f64;
            let p = DVec2::new(x, 0.4 + 0.05 * (7.0 * x).sin());
            (0.0..=1.0).contains(&x).then_some((0, p))
        };
        let (mut live, mut layered) = (LiveStroke::default(), LayeredStroke::default());
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for k in (0..110).chain(150..190) {
            let here = hit(if k < 150 { k } else { k - 140 });
            live.advance(ray(k), here, REACH, exit_square(REACH.step), |c| a.push(c));
            let hits: Vec<SheetPoint> = here.into_iter().collect();
            (layered).advance(ray(k), &hits, REACH, exit_square(REACH.step), |c, layer| {
                assert_eq!(layer, Layer::Front);
                b.push(c)
            });
        }
        assert!(a.len() > 100, "{}", a.len());
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }

    #[test]
    fn two_sides_of_a_fold_that_end_together_are_joined_across_it() {
        // Two layers of one fold, their points closing on the fold's line at y = 0.5 from
        // both sides as the stroke nears the fold's silhouette; then the ray meets neither.
        let mut stroke = LayeredStroke::default();
        let mut cuts = Vec::new();
        for k in 0..12 {
            let gap = 0.2 - 0.015 * k as f64;
            let hits = [
                (0, DVec2::new(0.3, 0.5 + gap)),
                (0, DVec2::new(0.32, 0.5 - gap)),
            ];
            let hits = if k < 11 { &hits[..] } else { &[][..] };
            stroke.advance(ray(k), hits, REACH, exit_square(REACH.step), |c, l| {
                cuts.push((c, l))
            });
        }
        let (near, far) = (DVec2::new(0.3, 0.5 + 0.05), DVec2::new(0.32, 0.5 - 0.05));
        let joined = cuts.iter().any(|&(c, l)| match c {
            Cut::Rest(0, a, b) => {
                l == Layer::Behind
                    && ((a.distance(near) < 1e-12 && b.distance(far) < 1e-12)
                        || (a.distance(far) < 1e-12 && b.distance(near) < 1e-12))
            }
            _ => false,
        });
        assert!(joined, "{cuts:?}");
        // Each side is cut along itself, ray to ray, and nothing is cut across the fold's
        // far side: every cut stays between the two tracks' lines.
        for (c, _) in &cuts {
            if let Cut::Rest(_, a, b) = c {
                assert!(
                    a.x >= 0.3 - 1e-12 && b.x <= 0.32 + 1e-12
                        || b.x >= 0.3 - 1e-12 && a.x <= 0.32 + 1e-12,
                    "{c:?}"
                );
            }
        }
    }
}
