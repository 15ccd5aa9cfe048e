//! Closest points between a point and a triangle and between two segments, in f64: the narrow
//! phase of self-collision. Distances are what the pass's guarantee rests on (see `mod.rs`), and
//! unlike the roots of a continuous-collision cubic they are well conditioned, so f64 from
//! float32 inputs is accurate to far below the margin the pass keeps.

use glam::DVec3;

/// The point of triangle `(a, b, c)` nearest `p`, as barycentric weights `(wa, wb, wc)` (each
/// in [0, 1], summing to 1). Ericson, *Real-Time Collision Detection*, 5.1.5: the Voronoi
/// regions of the vertices, then the edges, then the face. A degenerate triangle (a segment or
/// a point) falls into a vertex or edge region and still gives its nearest point.
pub fn point_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if denom.is_nan() || denom <= 0.0 {
        // Degenerate beyond what the regions caught (collinear with p off the line): the
        // nearest of the three vertices is a safe answer, never a NaN.
        let d = [
            ap.length_squared(),
            bp.length_squared(),
            cp.length_squared(),
        ];
        let k = (0..3).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap_or(0);
        let mut w = [0.0; 3];
        w[k] = 1.0;
        return w;
    }
    let (v, w) = (vb / denom, vc / denom);
    [1.0 - v - w, v, w]
}

/// Parameters `(s, t)` in [0, 1] of the nearest points `p1 + s (q1 - p1)` and
/// `p2 + t (q2 - p2)` of two segments. Ericson 5.1.9, with its handling of degenerate
/// (point-like) segments; parallel segments get one of their nearest pairs.
pub fn segment_segment(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> (f64, f64) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    // Relative to the squared lengths: a segment shorter than this is a point.
    let tiny = 1e-30;
    if a <= tiny && e <= tiny {
        return (0.0, 0.0);
    }
    if a <= tiny {
        return (0.0, (f / e).clamp(0.0, 1.0));
    }
    let c = d1.dot(r);
    if e <= tiny {
        return ((-c / a).clamp(0.0, 1.0), 0.0);
    }
    let b = d1.dot(d2);
    let denom = a * e - b * b;
    let mut s = if denom > 1e-14 * a * e {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0 // parallel: any s, t is refined below
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (s, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn point_above_the_face_projects_inside_it() {
        let w = point_triangle(
            v(0.25, 1.0, 0.25),
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 0.0, 1.0),
        );
        let q = v(0.0, 0.0, 0.0) * w[0] + v(1.0, 0.0, 0.0) * w[1] + v(0.0, 0.0, 1.0) * w[2];
        assert!((q - v(0.25, 0.0, 0.25)).length() < 1e-12, "{q}");
    }

    #[test]
    fn point_beyond_an_edge_or_vertex_projects_onto_it() {
        let (a, b, c) = (v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 0.0, 1.0));
        assert_eq!(point_triangle(v(-1.0, 0.0, -1.0), a, b, c), [1.0, 0.0, 0.0]);
        assert_eq!(point_triangle(v(2.0, 1.0, -0.5), a, b, c), [0.0, 1.0, 0.0]);
        let w = point_triangle(v(0.5, 0.0, -1.0), a, b, c);
        assert!((w[1] - 0.5).abs() < 1e-12 && w[2] == 0.0, "{w:?}");
        let w = point_triangle(v(1.0, 0.0, 1.0), a, b, c);
        assert!(w[0].abs() < 1e-12 && (w[1] - 0.5).abs() < 1e-12, "{w:?}");
    }

    #[test]
    fn degenerate_triangles_give_finite_weights() {
        let (a, b) = (v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
        for w in [
            point_triangle(v(0.5, 1.0, 0.0), a, b, b),
            point_triangle(v(0.5, 1.0, 0.0), a, a, a),
            point_triangle(v(0.5, 1.0, 0.0), a, v(0.5, 0.0, 0.0), b),
        ] {
            assert!(
                w.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
                "{w:?}"
            );
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{w:?}");
        }
    }

    #[test]
    fn crossing_and_parallel_segments() {
        let (s, t) = segment_segment(
            v(-1.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 1.0, -1.0),
            v(0.0, 1.0, 1.0),
        );
        assert!((s - 0.5).abs() < 1e-12 && (t - 0.5).abs() < 1e-12);
        let (s, t) = segment_segment(
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.5, 1.0, 0.0),
            v(2.0, 1.0, 0.0),
        );
        let p = v(s, 0.0, 0.0);
        let q = v(0.5 + 1.5 * t, 1.0, 0.0);
        assert!(((p - q).length() - 1.0).abs() < 1e-12, "{s} {t}");
    }
}
