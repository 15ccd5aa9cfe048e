//! An irregular square graded toward where a clamped sheet's strain is singular.
//!
//! A square hung by two clamps along its top edge has an unbounded strain at each clamp's inner
//! end (where the clamped edge turns free) and at the top corners (where the clamped edge meets
//! a free side). A uniform mesh resolves such a point only to first order in its spacing, so its
//! sag moves by a few per cent from 1k to 16k vertices; a mesh whose spacing shrinks toward
//! those points spends its vertices where the error is. [`graded_square`] builds one: a
//! spacing field `h(d) = h0 clamp((d / R)^a, g, 1)` of the distance `d` to the nearest such
//! point, the boundary's vertices placed along it (with a vertex exactly at every clamp end, so
//! that meshes of every size hold the same clamps), the interior filled by Poisson-disk
//! sampling at that spacing (Bridson's algorithm with a variable radius: no two points closer
//! than the local spacing allows, no gaps), and the whole triangulated by spade's constrained
//! Delaunay triangulation.

use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::uniform_stream;

/// How a [`graded_square`]'s spacing shrinks toward the clamps' ends and the top corners:
/// `h(d) = h0 clamp((d / radius)^exponent, floor, 1)`, `d` the distance to the nearest of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grading {
    /// Distance from a singular point beyond which the spacing is uniform, m. Default 0.3
    /// (for a 1 m square): larger spends more of the vertices near the clamps.
    pub radius: f64,
    /// How fast the spacing grows with the distance. Default 1 (spacing proportional to the
    /// distance, the usual grading toward a point singularity); smaller grades more gently,
    /// 0 gives a uniform mesh.
    pub exponent: f64,
    /// Finest spacing as a fraction of the far spacing `h0`. Default 0.15. Smaller resolves the
    /// singular points further but lowers an explicit step's stable limit in proportion (the
    /// stable step scales with the smallest element).
    pub floor: f64,
}

impl Default for Grading {
    fn default() -> Self {
        Grading {
            radius: 0.3,
            exponent: 1.0,
            floor: 0.15,
        }
    }
}

/// Poisson-disk radius as a fraction of the spacing: Bridson's sampling at radius `r` leaves
/// a Delaunay triangulation whose edges average about `1.25 r`, so this makes the interior's
/// edges about as long as the boundary's (measured by `graded_edges_match_the_boundary`).
const RADIUS_PER_SPACING: f64 = 0.8;
/// Candidates tried around each active point before it retires (Bridson's `k`).
const CANDIDATES: usize = 30;

/// An irregular triangulation of a `size` x `size` square in the plane through `center` along
/// `+x` and `+y` (a hanging sheet, top edge at `+y`), of about `vertices` vertices (within a
/// few per cent), its spacing graded by `grading` toward the top corners and the inner ends of
/// two clamps of length `clamp` (m) along the top edge from each corner: those ends, at `x =
/// +-(size / 2 - clamp)` on the top edge, are vertices of every such mesh. Triangles are wound
/// counter-clockwise seen from `+z`, vertices numbered row by row. The same `seed` gives the
/// same mesh. `clamp` of 0 or `size / 2` grades toward the corners only.
pub fn graded_square(
    vertices: usize,
    size: f64,
    center: [f64; 3],
    clamp: f64,
    grading: Grading,
    seed: u64,
) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    assert!(vertices >= 4, "a square needs at least 4 vertices");
    assert!(
        (0.0..=size / 2.0).contains(&clamp),
        "a clamp runs from a corner to at most the top edge's middle"
    );
    let half = size / 2.0;
    let mut foci = vec![[-half, half], [half, half]];
    if clamp > 0.0 && clamp < half {
        foci.extend([[-half + clamp, half], [half - clamp, half]]);
    }
    // The far spacing that gives the asked count: the count goes about as `1 / h0^2`, so a few
    // rescalings from the uniform guess land within a per cent or two.
    let mut h0 = size / (vertices as f64).sqrt();
    let mut points = sample(size, &foci, clamp, grading, h0, seed);
    for _ in 0..6 {
        let ratio = (points.0.len() + points.1.len()) as f64 / vertices as f64;
        if (ratio - 1.0).abs() < 0.01 {
            break;
        }
        h0 *= ratio.sqrt();
        points = sample(size, &foci, clamp, grading, h0, seed);
    }
    let (boundary, interior) = points;
    triangulate(boundary, interior, size, center)
}

/// The boundary ring (counter-clockwise from the bottom-left corner) and the interior points.
type Points = (Vec<[f64; 2]>, Vec<[f64; 2]>);

fn spacing(p: [f64; 2], foci: &[[f64; 2]], grading: Grading, h0: f64) -> f64 {
    let d = foci
        .iter()
        .map(|f| ((p[0] - f[0]).powi(2) + (p[1] - f[1]).powi(2)).sqrt())
        .fold(f64::INFINITY, f64::min);
    h0 * (d / grading.radius)
        .powf(grading.exponent)
        .clamp(grading.floor, 1.0)
}

fn sample(
    size: f64,
    foci: &[[f64; 2]],
    clamp: f64,
    grading: Grading,
    h0: f64,
    seed: u64,
) -> Points {
    let half = size / 2.0;
    let h = |p: [f64; 2]| spacing(p, foci, grading, h0);
    // The boundary, one straight piece at a time, each piece's ends kept: the corners and the
    // clamps' ends.
    let mut corners = vec![[-half, -half], [half, -half], [half, half]];
    if clamp > 0.0 && clamp < half {
        corners.extend([[half - clamp, half], [-half + clamp, half]]);
    }
    corners.push([-half, half]);
    let mut boundary = Vec::new();
    for k in 0..corners.len() {
        let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
        boundary.extend(piece(a, b, &h));
    }
    // Poisson-disk fill: a candidate is kept when no kept point is nearer than the mean of the
    // two points' radii, and it keeps half a radius off the boundary's line, where a point
    // between two boundary vertices would make a flat triangle.
    let r_min = RADIUS_PER_SPACING * h0 * grading.floor.min(1.0);
    let cell = r_min;
    let cells = (size / cell).ceil() as usize + 1;
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); cells * cells];
    let slot = |p: [f64; 2]| {
        let i = (((p[0] + half) / cell) as usize).min(cells - 1);
        let j = (((p[1] + half) / cell) as usize).min(cells - 1);
        (i, j)
    };
    let mut all: Vec<([f64; 2], f64)> = Vec::new();
    let mut active = Vec::new();
    for &p in &boundary {
        let (i, j) = slot(p);
        grid[j * cells + i].push(all.len() as u32);
        active.push(all.len());
        all.push((p, RADIUS_PER_SPACING * h(p)));
    }
    let n_boundary = all.len();
    let mut uniform = uniform_stream(seed);
    while !active.is_empty() {
        let pick = ((uniform() + 1.0) / 2.0 * active.len() as f64) as usize;
        let pick = pick.min(active.len() - 1);
        let (p, r) = all[active[pick]];
        let mut found = false;
        for _ in 0..CANDIDATES {
            let angle = uniform() * std::f64::consts::PI;
            let dist = r * (1.5 + 0.5 * uniform());
            let c = [p[0] + dist * angle.cos(), p[1] + dist * angle.sin()];
            let rc = RADIUS_PER_SPACING * h(c);
            let margin = 0.5 * rc;
            if c[0].abs() > half - margin || c[1].abs() > half - margin {
                continue;
            }
            // Neighbours' radii are at most about twice this one where the spacing grades.
            let reach = 2.0 * rc;
            let (i0, j0) = slot([c[0] - reach, c[1] - reach]);
            let (i1, j1) = slot([c[0] + reach, c[1] + reach]);
            let clear = (j0..=j1).all(|j| {
                (i0..=i1).all(|i| {
                    grid[j * cells + i].iter().all(|&q| {
                        let (q, rq) = all[q as usize];
                        let d2 = (q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2);
                        d2 >= (0.5 * (rc + rq)).powi(2)
                    })
                })
            });
            if clear {
                let (i, j) = slot(c);
                grid[j * cells + i].push(all.len() as u32);
                active.push(all.len());
                all.push((c, rc));
                found = true;
                break;
            }
        }
        if !found {
            active.swap_remove(pick);
        }
    }
    let interior = all[n_boundary..].iter().map(|&(p, _)| p).collect();
    (boundary, interior)
}

/// The points of the straight piece from `a` to `b` at spacing `h`, `a` included and `b` not:
/// `t` along the piece where `int_0^t ds / h` reaches each whole step of its total, rounded.
fn piece(a: [f64; 2], b: [f64; 2], h: &impl Fn([f64; 2]) -> f64) -> Vec<[f64; 2]> {
    const STEPS: usize = 4000;
    let at = |t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    let mut phi = vec![0.0; STEPS + 1];
    for k in 0..STEPS {
        let t = (k as f64 + 0.5) / STEPS as f64;
        phi[k + 1] = phi[k] + length / STEPS as f64 / h(at(t));
    }
    let m = phi[STEPS].round().max(1.0) as usize;
    let mut out = vec![a];
    let mut k = 0;
    for s in 1..m {
        let target = s as f64 * phi[STEPS] / m as f64;
        while phi[k + 1] < target {
            k += 1;
        }
        let t = (k as f64 + (target - phi[k]) / (phi[k + 1] - phi[k])) / STEPS as f64;
        out.push(at(t));
    }
    out
}

fn triangulate(
    boundary: Vec<[f64; 2]>,
    interior: Vec<[f64; 2]>,
    size: f64,
    center: [f64; 3],
) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    let nb = boundary.len();
    let mut points = boundary;
    points.extend(interior);
    // Row by row (bands of about the mean spacing), as a grid's particles are: neighbours in
    // the mesh stay near in memory.
    let band = size / (points.len() as f64).sqrt();
    let mut order: Vec<usize> = (0..points.len()).collect();
    let key = |p: [f64; 2]| ((p[1] + size) / band).floor() as i64;
    order.sort_by(|&a, &b| {
        let (p, q) = (points[a], points[b]);
        key(p).cmp(&key(q)).then(p[0].total_cmp(&q[0]))
    });
    let mut rank = vec![0usize; points.len()];
    for (r, &i) in order.iter().enumerate() {
        rank[i] = r;
    }
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::new();
    let handles: Vec<_> = points
        .iter()
        .map(|p| {
            cdt.insert(Point2::new(p[0], p[1]))
                .expect("the samples are finite")
        })
        .collect();
    assert_eq!(
        cdt.num_vertices(),
        points.len(),
        "Poisson-disk samples are apart"
    );
    let mut index = vec![0usize; points.len()];
    for (i, h) in handles.iter().enumerate() {
        index[h.index()] = i;
    }
    for k in 0..nb {
        cdt.add_constraint(handles[k], handles[(k + 1) % nb]);
    }
    let vertices = order
        .iter()
        .map(|&i| {
            let p = points[i];
            [center[0] + p[0], center[1] + p[1], center[2]]
        })
        .collect();
    let triangles = cdt
        .inner_faces()
        .map(|f| f.vertices().map(|v| rank[index[v.fix().index()]] as i64))
        .collect();
    (vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area2(v: &[[f64; 3]], t: [i64; 3]) -> f64 {
        let [a, b, c] = t.map(|k| v[k as usize]);
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    }

    fn min_angle_deg(v: &[[f64; 3]], t: [i64; 3]) -> f64 {
        let p = t.map(|k| v[k as usize]);
        (0..3)
            .map(|i| {
                let (a, b, c) = (p[i], p[(i + 1) % 3], p[(i + 2) % 3]);
                let u = [b[0] - a[0], b[1] - a[1]];
                let w = [c[0] - a[0], c[1] - a[1]];
                let cos = (u[0] * w[0] + u[1] * w[1]) / ((u[0].hypot(u[1])) * (w[0].hypot(w[1])));
                cos.clamp(-1.0, 1.0).acos().to_degrees()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn graded_square_is_a_valid_mesh_of_the_square() {
        let (v, t) = graded_square(1000, 1.0, [0.0, 1.0, 0.0], 0.125, Grading::default(), 1);
        let area: f64 = t.iter().map(|&t| area2(&v, t) / 2.0).sum();
        assert!((area - 1.0).abs() < 1e-9, "areas sum to {area}");
        for &tri in &t {
            assert!(area2(&v, tri) > 0.0, "{tri:?} is degenerate or inverted");
            let angle = min_angle_deg(&v, tri);
            assert!(
                angle > 15.0,
                "{tri:?} is a sliver: smallest angle {angle} degrees"
            );
        }
        // One component: a flood over shared vertices reaches every vertex.
        let mut parent: Vec<usize> = (0..v.len()).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for tri in &t {
            for k in 1..3 {
                let (a, b) = (
                    root(&mut parent, tri[0] as usize),
                    root(&mut parent, tri[k] as usize),
                );
                parent[a] = b;
            }
        }
        let r0 = root(&mut parent, 0);
        assert!((0..v.len()).all(|i| root(&mut parent, i) == r0));
    }

    #[test]
    fn graded_square_has_about_the_asked_vertex_count() {
        for asked in [300, 1000, 4000] {
            let (v, _) = graded_square(asked, 1.0, [0.0; 3], 0.125, Grading::default(), 2);
            let off = v.len() as f64 / asked as f64 - 1.0;
            assert!(off.abs() < 0.1, "{} vertices asked {asked}", v.len());
        }
    }

    #[test]
    fn graded_square_holds_a_vertex_at_each_clamp_end() {
        for asked in [300, 1000, 4000] {
            let (v, _) = graded_square(asked, 1.0, [0.0, 1.0, 0.0], 0.125, Grading::default(), 3);
            for x in [-0.375, 0.375, -0.5, 0.5] {
                assert!(
                    v.iter().any(|p| (p[0] - x).abs() < 1e-12 && p[1] == 1.5),
                    "no vertex at x = {x} on the top edge at {asked}"
                );
            }
        }
    }

    /// The mean length of the edges at the vertices within `r` of `p`.
    fn local_edge(v: &[[f64; 3]], t: &[[i64; 3]], p: [f64; 2], r: f64) -> f64 {
        let near = |k: i64| {
            let q = v[k as usize];
            (q[0] - p[0]).hypot(q[1] - p[1]) < r
        };
        let (mut sum, mut count) = (0.0, 0);
        for tri in t {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if near(a) || near(b) {
                    let (a, b) = (v[a as usize], v[b as usize]);
                    sum += (a[0] - b[0]).hypot(a[1] - b[1]);
                    count += 1;
                }
            }
        }
        sum / count as f64
    }

    #[test]
    fn graded_square_is_finer_at_the_clamp_ends_than_far_from_them() {
        let (v, t) = graded_square(4000, 1.0, [0.0; 3], 0.125, Grading::default(), 4);
        let at_end = local_edge(&v, &t, [0.375, 0.5], 0.02);
        let far = local_edge(&v, &t, [0.0, -0.3], 0.05);
        assert!(
            at_end < 0.3 * far,
            "edges {at_end} m at a clamp end against {far} m far from it"
        );
    }

    #[test]
    fn graded_edges_match_the_boundary() {
        // Far from the foci the interior's edges are about the boundary's spacing.
        let (v, t) = graded_square(4000, 1.0, [0.0; 3], 0.125, Grading::default(), 5);
        let bottom: Vec<f64> = {
            let mut xs: Vec<f64> = v.iter().filter(|p| p[1] == -0.5).map(|p| p[0]).collect();
            xs.sort_by(f64::total_cmp);
            xs.windows(2).map(|w| w[1] - w[0]).collect()
        };
        let boundary = bottom.iter().sum::<f64>() / bottom.len() as f64;
        let interior = local_edge(&v, &t, [0.0, -0.2], 0.1);
        let ratio = interior / boundary;
        assert!(
            (0.85..1.15).contains(&ratio),
            "interior / boundary edges {ratio}"
        );
    }

    #[test]
    fn graded_square_is_the_same_for_the_same_seed() {
        let a = graded_square(1000, 1.0, [0.0; 3], 0.125, Grading::default(), 7);
        let b = graded_square(1000, 1.0, [0.0; 3], 0.125, Grading::default(), 7);
        let c = graded_square(1000, 1.0, [0.0; 3], 0.125, Grading::default(), 8);
        assert_eq!(a, b);
        assert_ne!(a.0, c.0);
    }
}
