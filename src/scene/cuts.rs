//! Cuts made in a grid cloth as it is built (`[[cloth.cuts]]`): a slit or a perforated line a
//! tear is meant to run along. A rip runs where the tension across its path is largest, and in a
//! sheet pulled at one point that is round the point; a line of cuts concentrates the tension of
//! the uncut springs between them, so a pull rips along it first.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{check_vector, Bound, Error, Result};

/// One cut: a polyline on the cloth as built, severed as a scissor stroke severs it
/// (`Simulation::sever_stroke`, with rays along the cloth plane's normal through its points).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSpec {
    /// The polyline's points in m, at least two, in the cloth's starting plane (the coordinate
    /// along its normal is ignored).
    pub points: Vec<[f64; 3]>,
    /// `[cut, gap]` in m, both > 0: cut the polyline in dashes `cut` long, `gap` apart, from
    /// its first point on (a perforation: the springs left between dashes carry the tension
    /// across the line, concentrated, so a pull rips along it). A gap under the grid spacing
    /// may leave no spring uncut; a dash under it may cut none. Absent (default): cut it whole.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dash: Option<[f64; 2]>,
}

impl CutSpec {
    /// Checks `cloth.cuts[k]` (named `at`): two or more finite points, consecutive ones apart,
    /// and a positive finite dash.
    pub(crate) fn validate(&self, at: &str) -> Result<()> {
        if self.points.len() < 2 {
            return Err(Error::value(
                format!("{at}.points"),
                format!("must hold at least two points, got {}", self.points.len()),
            ));
        }
        for (k, p) in self.points.iter().enumerate() {
            check_vector(&format!("{at}.points[{k}]"), p, Bound::Any)?;
        }
        if self.points.windows(2).any(|w| w[0] == w[1]) {
            return Err(Error::value(
                format!("{at}.points"),
                "consecutive points must differ",
            ));
        }
        if let Some(dash) = &self.dash {
            check_vector(&format!("{at}.dash"), dash, Bound::Positive)?;
        }
        Ok(())
    }

    /// The strokes that make this cut on a cloth whose starting plane has the in-plane `axes`
    /// (`Plane::axes`): each the `(origin, direction)` rays of one dash (the whole polyline
    /// without a dash), from one metre in front of the plane through the point at `centre`'s
    /// depth.
    pub(crate) fn strokes(&self, axes: (Vec3, Vec3), centre: [f64; 3]) -> Vec<Vec<(Vec3, Vec3)>> {
        let (ei, ej) = axes;
        let normal = ei.cross(ej).as_dvec3();
        let c = glam::DVec3::from(centre);
        let on_plane = |p: glam::DVec3| p - normal * (p - c).dot(normal);
        let points: Vec<glam::DVec3> = self.points.iter().map(|&p| on_plane(p.into())).collect();
        let dashes = match self.dash {
            None => vec![points],
            Some([cut, gap]) => dashes(&points, cut, gap),
        };
        let ray = |p: glam::DVec3| ((p + normal).as_vec3(), (-normal).as_vec3());
        dashes
            .into_iter()
            .map(|dash| dash.into_iter().map(ray).collect())
            .collect()
    }
}

/// The polyline `points` cut into dashes `cut` long, `gap` apart along it, the first starting at
/// its first point; each dash as its own polyline (a last one shorter where the line ends).
fn dashes(points: &[glam::DVec3], cut: f64, gap: f64) -> Vec<Vec<glam::DVec3>> {
    let period = cut + gap;
    let mut out: Vec<Vec<glam::DVec3>> = Vec::new();
    let mut along = 0.0; // arc length at the start of the current segment
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        let length = a.distance(b);
        let at = |s: f64| a + (b - a) * ((s - along) / length);
        let end = along + length;
        // Every dash overlapping [along, end]: from the period the segment starts in.
        let mut k = (along / period).floor();
        while k * period < end {
            let (d0, d1) = (k * period, k * period + cut);
            let (s0, s1) = (d0.max(along), d1.min(end));
            if s1 > s0 {
                let continues = d0 < along && out.last().is_some();
                if continues {
                    out.last_mut().expect("checked").push(at(s1));
                } else {
                    out.push(vec![at(s0), at(s1)]);
                }
            }
            k += 1.0;
        }
        along = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn a_dash_pattern_cuts_a_line_into_dashes_a_period_apart() {
        let line = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
        let d = dashes(&line, 0.2, 0.1);
        let starts: Vec<f64> = d.iter().map(|s| s[0].x).collect();
        let ends: Vec<f64> = d.iter().map(|s| s.last().unwrap().x).collect();
        for (k, (s, e)) in starts.iter().zip(&ends).enumerate() {
            assert!((s - 0.3 * k as f64).abs() < 1e-12, "{starts:?}");
            assert!(
                (e - (0.3 * k as f64 + 0.2).min(1.0)).abs() < 1e-12,
                "{ends:?}"
            );
        }
        assert_eq!(d.len(), 4);
    }

    #[test]
    fn a_dash_across_a_corner_of_the_polyline_follows_it() {
        let line = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        let d = dashes(&line, 0.5, 0.4);
        // The second dash starts at 0.9 and turns the corner at 1.0, ending 0.4 up.
        assert_eq!(d[1].len(), 3, "{d:?}");
        assert!(
            (d[1][2] - DVec3::new(1.0, 0.4, 0.0)).length() < 1e-12,
            "{d:?}"
        );
    }
}
