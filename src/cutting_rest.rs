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
//! Only the grid has a flat rest sheet in these coordinates; a mesh cloth keeps the swept
//! surface ([`crate::cutting::StrokeCutter`]).

use glam::DVec2;

use crate::cutting::Crossing;
use crate::grid::{cell_triangle, Grid, SpringKind};
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
    let (r, s) = (q - p, b - a);
    let denom = r.perp_dot(s);
    if denom == 0.0 {
        return None;
    }
    let w = a - p;
    let t = w.perp_dot(s) / denom;
    let u = w.perp_dot(r) / denom;
    ((0.0..1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}

/// A live stroke's memory between frames: the last ray and, if it hit the cloth, the material
/// point it hit and the stroke's direction on the sheet there (a unit vector).
#[derive(Clone, Copy, Debug, Default)]
pub struct LiveStroke {
    pub last_ray: Option<crate::ray::Ray>,
    pub last_point: Option<DVec2>,
    pub heading: Option<DVec2>,
    /// Where the stroke came onto the cloth from off it, until its direction there is known
    /// and the cut is carried back out through the edge.
    pub entry: Option<DVec2>,
    /// A point about one spacing back along the stroke on the sheet, which its heading is
    /// taken from.
    pub tail: Option<DVec2>,
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
