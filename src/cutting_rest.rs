//! A live cut held in the cloth's own coordinates. A stroke drawn over several frames meets a
//! cloth that moves between them (the first springs cut let the cloth below sag and swing), so
//! cutting each frame's piece of stroke against the cloth as it is then puts the pieces of the
//! cut at different places in the material, and the springs between their ends stay: a dashed
//! line of slits, the cloth still one piece. Here each mouse ray that hits the cloth names a
//! material point, the point of the grid's rest sheet (`(i dx, j dy)`) under the hit, and
//! consecutive points are joined by a straight segment of that sheet; every spring whose rest
//! segment crosses one is severed, at the parameter where it crosses. Where the last frame's
//! stroke ended is a material point, so the next frame's stroke starts there, wherever that
//! point has moved.
//!
//! A mesh cloth whose rest shape is flat (or a garment of flat panels) has a rest sheet of its
//! own, [`MeshSheet`], in charts (a garment's panels); a curved one keeps the swept surface
//! ([`crate::cutting::StrokeCutter`]). The stroke's course over the sheet ([`LiveStroke::advance`])
//! is the same for both.

mod layers;
mod mesh;

use glam::DVec2;

pub use layers::{Layer, LayeredStroke, FOLD_SPACINGS, MAX_LAYERS};
pub use mesh::{MeshSheet, MAX_TILT_DEG};

use crate::cutting::Crossing;
use crate::grid::{cell_triangle, Grid, SpringKind};
use crate::ray::Ray;
use crate::springs::Springs;

/// The grid's rest sheet: particle `(i, j)` at `(i dx, j dy)` (m).
#[derive(Clone, Copy, Debug)]
pub struct RestSheet {
    pub grid: Grid,
    /// The rest spacings `(dx, dy)` in m.
    pub spacing: DVec2,
}

impl RestSheet {
    /// Where particle `p` is on the rest sheet.
    #[inline]
    pub fn point(&self, p: usize) -> DVec2 {
        let (i, j) = self.grid.coords(p);
        DVec2::new(i as f64, j as f64) * self.spacing
    }

    /// The material point of triangle `id` ([`cell_triangle`]) at barycentric weights `w`.
    pub fn at(&self, id: usize, w: [f32; 3]) -> DVec2 {
        let corners = cell_triangle(self.grid, id);
        (0..3).fold(DVec2::ZERO, |sum, k| {
            sum + w[k] as f64 * self.point(corners[k])
        })
    }

    /// The far corner of the sheet (its near corner is the origin).
    pub fn size(&self) -> DVec2 {
        DVec2::new((self.grid.nx - 1) as f64, (self.grid.ny - 1) as f64) * self.spacing
    }

    /// How far from `from` (on the sheet) along the unit direction `dir` the sheet ends, plus
    /// one spacing so that the springs on its edge are crossed.
    pub fn exit_distance(&self, from: DVec2, dir: DVec2) -> f64 {
        let size = self.size();
        let axis = |x: f64, d: f64, hi: f64| {
            if d > 0.0 {
                (hi - x) / d
            } else if d < 0.0 {
                -x / d
            } else {
                f64::INFINITY
            }
        };
        let inside = axis(from.x, dir.x, size.x).min(axis(from.y, dir.y, size.y));
        inside.max(0.0) + self.spacing.max_element()
    }

    /// Appends the live springs whose rest segments cross the rest segment `a`-`b`, each with
    /// where it crosses. Only the springs of the cells the segment's box touches (widened by
    /// the two cells a bending spring spans) are looked at, so a short segment costs a few
    /// dozen tests whatever the cloth's size.
    pub fn crossings(
        &self,
        springs: &Springs,
        alive: &[bool],
        (a, b): (DVec2, DVec2),
        out: &mut Vec<Crossing>,
    ) {
        let grid = self.grid;
        let (lo, hi) = (a.min(b) / self.spacing, a.max(b) / self.spacing);
        let range = |lo: f64, hi: f64, n: usize| {
            let first = (lo.floor() - 2.0).max(0.0) as usize;
            let last = (hi.ceil() + 2.0).min(n as f64 - 1.0);
            (last >= 0.0 && (first as f64) <= last).then_some(first..=last as usize)
        };
        let (Some(is), Some(js)) = (range(lo.x, hi.x, grid.nx), range(lo.y, hi.y, grid.ny)) else {
            return;
        };
        for j in js {
            for i in is.clone() {
                let anchor = grid.index(i, j);
                if !alive[anchor] {
                    continue;
                }
                for kind in SpringKind::ALL {
                    if springs.active[kind.index()][anchor] == 0.0 {
                        continue;
                    }
                    let Some(partner) = grid.partner(anchor, kind) else {
                        continue;
                    };
                    if !alive[partner] {
                        continue;
                    }
                    let (p, q) = (self.point(anchor), self.point(partner));
                    if let Some(t) = segments_crossing((p, q), (a, b)) {
                        out.push(((kind, anchor), t as f32));
                    }
                }
            }
        }
    }
}

/// Where the spring's segment `p`-`q` crosses the stroke's segment `a`-`b` in the plane: the
/// parameter `t` of `p + t (q - p)`, in `[0, 1)`, with the stroke's own parameter in `[0, 1]`.
/// Half-open on the spring, so that a stroke through a particle severs the springs that leave
/// it (it anchors them) and not those that arrive: a stroke along a row of particles separates
/// the row from one side, not from both. Parallel segments never cross: a stroke along a spring
/// does not cut it.
pub fn segments_crossing((p, q): (DVec2, DVec2), (a, b): (DVec2, DVec2)) -> Option<f64> {
    let (t, u) = lines_meeting((p, q), (a, b))?;
    ((0.0..1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Where the lines through `p`-`q` and `a`-`b` meet: the parameters `(t, u)` of the point
/// `p + t (q - p) = a + u (b - a)`; `None` for parallel lines.
pub fn lines_meeting((p, q): (DVec2, DVec2), (a, b): (DVec2, DVec2)) -> Option<(f64, f64)> {
    let (r, s) = (q - p, b - a);
    let denom = r.perp_dot(s);
    if denom == 0.0 {
        return None;
    }
    let w = a - p;
    Some((w.perp_dot(s) / denom, w.perp_dot(r) / denom))
}

/// A material point: the chart of the rest sheet it is on (the grid's one sheet is chart 0;
/// a garment's panels are its charts) and where on it (m).
pub type SheetPoint = (u32, DVec2);

/// What a live stroke cuts for one of its rays ([`LiveStroke::advance`]).
#[derive(Clone, Copy, Debug)]
pub enum Cut {
    /// The springs whose rest segments cross this rest segment of the chart.
    Rest(u32, DVec2, DVec2),
    /// The springs the surface these two rays sweep through the cloth as it is now crosses.
    Swept(Ray, Ray),
}

/// A live stroke's memory between frames: the last ray and, if it hit the cloth, the material
/// point it hit and the stroke's direction on the sheet there (a unit vector). `entry` and
/// `tail` are on `last_point`'s chart.
#[derive(Clone, Copy, Debug, Default)]
pub struct LiveStroke {
    pub last_ray: Option<Ray>,
    pub last_point: Option<SheetPoint>,
    pub heading: Option<DVec2>,
    /// Where the stroke came onto the cloth from off it, until its direction there is known
    /// and the cut is carried back out through the edge.
    pub entry: Option<DVec2>,
    /// A point about one spacing back along the stroke on the sheet, which its heading is
    /// taken from.
    pub tail: Option<DVec2>,
}

/// How a live stroke meets a rest sheet: `step` (m), about one spacing, the stretch of sheet its
/// direction is taken over; `jump` (m), the farthest two consecutive points are joined on the
/// sheet (`REST_JUMP_SPACINGS` spacings, `src/simulation/interaction.rs`).
#[derive(Clone, Copy, Debug)]
pub struct Reach {
    pub step: f64,
    pub jump: f64,
}

impl LiveStroke {
    /// Continues the stroke with `ray`, which hit the material point `here` (or missed the
    /// cloth), and hands `cut` what to sever for it, in order; `exit(chart, from, dir)` is how
    /// far from `from` along `dir` the chart's material ends, plus a spacing. Consecutive
    /// points on one chart and within `reach.jump` are joined on it; the cut is carried out
    /// through the edge where the stroke comes on or goes off; two points on different charts
    /// or farther apart (over a fold's edge, across a seam) are cut by their rays' swept
    /// surface, and the stroke goes on from the new point.
    pub fn advance(
        &mut self,
        ray: Ray,
        here: Option<SheetPoint>,
        reach: Reach,
        exit: impl Fn(u32, DVec2, DVec2) -> f64,
        mut cut: impl FnMut(Cut),
    ) {
        let Reach { step, jump } = reach;
        let live = *self;
        *self = LiveStroke {
            last_ray: Some(ray),
            last_point: here,
            ..live
        };
        let Some(before) = live.last_ray else {
            return; // a stroke's first sample: nothing to join yet
        };
        // Out past the sheet's edge from `from` along `dir`, no farther than a jump.
        let out = |c: u32, from: DVec2, dir: DVec2| from + exit(c, from, dir).min(jump) * dir;
        match (live.last_point, here) {
            (Some((ca, a)), Some((c, b))) if ca == c && a.distance(b) <= jump => {
                cut(Cut::Rest(c, a, b));
                // The stroke's direction over about its last spacing on the sheet: a single
                // sample's step is a fraction of a spacing, and near a curl seen edge on it
                // points anywhere.
                let tail = live.tail.unwrap_or(a);
                let heading = (b - tail).try_normalize();
                if let Some(dir) = heading.filter(|_| b.distance(tail) >= step) {
                    if let Some(entry) = live.entry {
                        // The stroke came onto the cloth at `entry`: carried back out through
                        // the edge it came over, on the sheet, where the cloth's edge and the
                        // stroke's start are the same material whatever the cloth did between
                        // frames.
                        let back = (entry - b).try_normalize().unwrap_or(-dir);
                        cut(Cut::Rest(c, entry, out(c, entry, back)));
                        self.entry = None;
                    }
                    self.tail = Some(b - step * dir);
                } else {
                    self.tail = Some(tail);
                }
                self.heading = heading.or(live.heading);
            }
            (Some((c, a)), None) => {
                // Leaving the cloth: out through its edge along the stroke's direction.
                if let Some(entry) = live.entry {
                    // On the cloth for less than a spacing: in and out the same way.
                    if let Some(dir) = (a - entry).try_normalize() {
                        cut(Cut::Rest(c, entry, out(c, entry, -dir)));
                        cut(Cut::Rest(c, a, out(c, a, dir)));
                    }
                } else if let Some(dir) = live.heading {
                    cut(Cut::Rest(c, a, out(c, a, dir)));
                }
                *self = LiveStroke {
                    last_ray: Some(ray),
                    ..LiveStroke::default()
                };
            }
            (None, Some((_, b))) => {
                // Onto the cloth from off it: cut back out once the stroke's direction on the
                // sheet is known.
                self.entry = Some(b);
                self.tail = Some(b);
                self.heading = None;
            }
            (Some(_), Some((_, b))) => {
                // A jump on the sheet, or onto another chart: the stroke went over a fold's
                // edge onto another layer, or across a seam. The surface the two rays sweep
                // cuts what lies between; the new layer's cut starts at its point.
                cut(Cut::Swept(before, ray));
                self.tail = Some(b);
                self.heading = None;
                self.entry = None;
            }
            (None, None) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet(nx: usize, ny: usize) -> RestSheet {
        RestSheet {
            grid: Grid { nx, ny },
            spacing: DVec2::new(0.1, 0.2),
        }
    }

    #[test]
    fn a_stroke_through_a_particle_severs_the_springs_leaving_it_not_those_arriving() {
        let (p, q) = (DVec2::new(0.0, 0.0), DVec2::new(0.0, 1.0));
        let along_x = |y: f64| (DVec2::new(-1.0, y), DVec2::new(1.0, y));
        assert_eq!(segments_crossing((p, q), along_x(0.0)), Some(0.0));
        assert_eq!(segments_crossing((p, q), along_x(1.0)), None);
        assert_eq!(segments_crossing((p, q), along_x(0.25)), Some(0.25));
        assert_eq!(segments_crossing((p, q), (p, q)), None, "parallel");
    }

    #[test]
    fn a_rest_stroke_across_the_sheet_leaves_no_spring_joining_its_two_sides() {
        let s = sheet(9, 7);
        let n = s.grid.len();
        let springs = Springs::new(
            s.grid,
            &crate::soa::Vec3s::from_fn(n, |p| {
                let r = s.point(p);
                glam::DVec3::new(r.x, r.y, 0.0).as_vec3()
            }),
        );
        let alive = vec![true; n];
        let mut out = Vec::new();
        // A slanted line from off the left edge to off the right edge, in three pieces.
        let pts = [(-0.05, 0.33), (0.31, 0.5), (0.55, 0.61), (0.85, 0.75)];
        for w in pts.windows(2) {
            let (a, b) = (DVec2::from(w[0]), DVec2::from(w[1]));
            s.crossings(&springs, &alive, (a, b), &mut out);
        }
        let cut: std::collections::HashSet<_> = out.iter().map(|c| c.0).collect();
        // Every spring with one end below the line and one above is among those cut.
        let below = |p: usize| {
            let r = s.point(p);
            let x = r.x.clamp(-0.05, 0.85);
            let k = pts.windows(2).find(|w| x <= w[1].0).unwrap_or(&pts[2..]);
            let f = (x - k[0].0) / (k[1].0 - k[0].0);
            r.y < k[0].1 + f * (k[1].1 - k[0].1)
        };
        for kind in SpringKind::ALL {
            for anchor in 0..n {
                if let Some(partner) = s.grid.partner(anchor, kind) {
                    if below(anchor) != below(partner) {
                        assert!(cut.contains(&(kind, anchor)), "{kind:?} at {anchor} joins");
                    }
                }
            }
        }
        for &(_, t) in &out {
            assert!((0.0..1.0).contains(&t));
        }
    }
}
