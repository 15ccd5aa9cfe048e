//! A panel's flat outline: the checks that refuse a bad one, and walking along it.

use glam::DVec2;

use crate::error::{check_vector, Bound, Error, Result};

/// Twice the signed area of a closed polygon (positive counter-clockwise).
pub fn signed_area2(points: &[DVec2]) -> f64 {
    (0..points.len())
        .map(|i| points[i].perp_dot(points[(i + 1) % points.len()]))
        .sum()
}

/// The points of a closed polygon named `name`, checked: at least three, finite, a positive
/// no two of its sides crossing or touching (sides next to each other share only their common
/// corner), and an area above a millionth of a square of side `min_side` (m).
pub fn check_polygon(name: &str, points: &[[f64; 2]], min_side: f64) -> Result<Vec<DVec2>> {
    if points.len() < 3 {
        return Err(Error::value(
            name,
            format!("a polygon needs at least 3 points, got {}", points.len()),
        ));
    }
    for (k, p) in points.iter().enumerate() {
        check_vector(&format!("{name}[{k}]"), p, Bound::Any)?;
    }
    let pts: Vec<DVec2> = points.iter().map(|&p| DVec2::from(p)).collect();
    // Points on one line fold the outline onto itself: name that, not the overlap it makes.
    let far = pts.iter().map(|p| p.distance(pts[0])).fold(0.0, f64::max);
    let span = pts
        .iter()
        .copied()
        .max_by(|p, q| p.distance(pts[0]).total_cmp(&q.distance(pts[0])));
    let axis = span.map_or(DVec2::ZERO, |p| (p - pts[0]) / far.max(f64::MIN_POSITIVE));
    if pts
        .iter()
        .all(|p| axis.perp_dot(*p - pts[0]).abs() <= 1e-12 * far.max(1.0))
    {
        return Err(Error::value(
            name,
            "the outline has zero area: its points are all on one line",
        ));
    }
    if let Some((i, j)) = first_crossing(&pts, &pts, true) {
        return Err(Error::value(
            name,
            format!(
                "the outline intersects itself: side {i} ({} -> {}) meets side {j}; an outline \
                 must be a simple polygon",
                i,
                (i + 1) % pts.len()
            ),
        ));
    }
    let area = 0.5 * signed_area2(&pts).abs();
    if area <= min_side * min_side * 1e-6 {
        return Err(Error::value(
            name,
            format!(
                "the outline has zero area ({area:e} m^2): its points are collinear or repeated"
            ),
        ));
    }
    Ok(pts)
}

/// The first pair of sides `(i, j)` of the closed polygons `a` and `b` that cross or touch;
/// with `same` (`a` is `b`), sides sharing a corner may meet there.
pub fn first_crossing(a: &[DVec2], b: &[DVec2], same: bool) -> Option<(usize, usize)> {
    let (na, nb) = (a.len(), b.len());
    for i in 0..na {
        let (p, q) = (a[i], a[(i + 1) % na]);
        let start = if same { i + 1 } else { 0 };
        for j in start..nb {
            let (r, s) = (b[j], b[(j + 1) % nb]);
            let adjacent = same && (j == i + 1 || (i == 0 && j == na - 1));
            if adjacent {
                // Neighbours share a corner; they meet elsewhere only if they fold back onto
                // each other (collinear and overlapping).
                let (shared, other_a, other_b) = if j == i + 1 { (q, p, s) } else { (p, q, r) };
                let (u, v) = (other_a - shared, other_b - shared);
                if u.perp_dot(v).abs() <= 1e-12 * u.length() * v.length() && u.dot(v) > 0.0 {
                    return Some((i, j));
                }
                continue;
            }
            if segments_meet(p, q, r, s) {
                return Some((i, j));
            }
        }
    }
    None
}

/// Whether the closed segments `pq` and `rs` share a point.
fn segments_meet(p: DVec2, q: DVec2, r: DVec2, s: DVec2) -> bool {
    let orient = |a: DVec2, b: DVec2, c: DVec2| (b - a).perp_dot(c - a);
    let on = |a: DVec2, b: DVec2, c: DVec2| {
        c.x >= a.x.min(b.x) && c.x <= a.x.max(b.x) && c.y >= a.y.min(b.y) && c.y <= a.y.max(b.y)
    };
    let (d1, d2) = (orient(r, s, p), orient(r, s, q));
    let (d3, d4) = (orient(p, q, r), orient(p, q, s));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on(r, s, p))
        || (d2 == 0.0 && on(r, s, q))
        || (d3 == 0.0 && on(p, q, r))
        || (d4 == 0.0 && on(p, q, s))
}

/// The outline's points from `start` to `end` going forward (wrapping), both included.
pub fn chain_corners(outline: &[DVec2], start: usize, end: usize) -> Vec<DVec2> {
    let n = outline.len();
    let mut out = vec![outline[start]];
    let mut i = start;
    while i != end {
        i = (i + 1) % n;
        out.push(outline[i]);
    }
    out
}

/// Length of an open polyline.
pub fn length(points: &[DVec2]) -> f64 {
    points.windows(2).map(|w| w[0].distance(w[1])).sum()
}

/// The corners' arc-length parameters in `[0, 1]` along an open polyline.
pub fn corner_parameters(points: &[DVec2]) -> Vec<f64> {
    let total = length(points);
    let mut s = 0.0;
    let mut out = vec![0.0];
    for w in points.windows(2) {
        s += w[0].distance(w[1]);
        out.push(s / total);
    }
    out
}

/// The point at arc-length parameter `t` in `[0, 1]` along an open polyline.
pub fn point_at(points: &[DVec2], t: f64) -> DVec2 {
    let target = t * length(points);
    let mut s = 0.0;
    for w in points.windows(2) {
        let l = w[0].distance(w[1]);
        if s + l >= target && l > 0.0 {
            return w[0] + (w[1] - w[0]) * ((target - s) / l).clamp(0.0, 1.0);
        }
        s += l;
    }
    *points.last().expect("a chain has points")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bow_tie_is_refused_naming_its_crossing_sides() {
        let bow = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        let err = check_polygon("p.outline", &bow, 0.03).unwrap_err();
        assert!(err.to_string().contains("intersects itself"), "{err}");
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(check_polygon("p.outline", &square, 0.03).is_ok());
    }

    #[test]
    fn a_side_folded_back_onto_its_neighbour_is_refused() {
        let spike = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.0], [0.5, 1.0]];
        assert!(check_polygon("p", &spike, 0.03).is_err());
    }

    #[test]
    fn points_along_a_chain_follow_arc_length() {
        let chain = [DVec2::ZERO, DVec2::new(1.0, 0.0), DVec2::new(1.0, 3.0)];
        assert_eq!(corner_parameters(&chain), vec![0.0, 0.25, 1.0]);
        assert!(point_at(&chain, 0.5).distance(DVec2::new(1.0, 1.0)) < 1e-12);
    }
}
