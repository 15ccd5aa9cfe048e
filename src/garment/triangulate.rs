//! A panel's flat mesh: spade's constrained Delaunay triangulation of its boundary points,
//! refined to triangles of about the edge length.

use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

use glam::DVec2;

use crate::error::{Error, Result};

/// Smallest interior angle the refinement aims at, in degrees. Ruppert's refinement
/// terminates for limits up to about 20.7 degrees with any input; spade's default (30) may
/// add many vertices next to sharp input corners, and more does not change the springs much.
const ANGLE_LIMIT: f64 = 25.0;

/// A flat triangle mesh: points in the panel's plane, triangles counter-clockwise.
pub struct FlatMesh {
    pub points: Vec<DVec2>,
    pub triangles: Vec<[u32; 3]>,
}

/// Triangulates the closed ring `outline` (its points in order, every one kept as a vertex:
/// they are vertices `0..outline.len()` of the result, in order) and the `holes` (closed rings
/// too), with triangles of about `edge` on a side (see `target` below). Only
/// the inside of the outline, outside the holes, is meshed. `name` is the panel, for errors.
pub fn triangulate(
    name: &str,
    outline: &[DVec2],
    holes: &[Vec<DVec2>],
    edge: f64,
) -> Result<FlatMesh> {
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::new();
    let mut rings = Vec::with_capacity(1 + holes.len());
    let mut count = 0usize;
    for (r, ring) in std::iter::once(outline)
        .chain(holes.iter().map(Vec::as_slice))
        .enumerate()
    {
        let mut handles = Vec::with_capacity(ring.len());
        for p in ring {
            let h = cdt.insert(Point2::new(p.x, p.y)).map_err(|e| {
                Error::value(name, format!("point {p} cannot be triangulated: {e:?}"))
            })?;
            if h.index() != count {
                let what = if r == 0 {
                    "outline".to_string()
                } else {
                    format!("holes[{}]", r - 1)
                };
                return Err(Error::value(
                    format!("{name}.{what}"),
                    format!(
                        "a boundary point at {p} lands on another boundary point: the \
                         outline touches itself or a hole (or the edge length is far too small)"
                    ),
                ));
            }
            count += 1;
            handles.push(h);
        }
        rings.push(handles);
    }
    for ring in &rings {
        for k in 0..ring.len() {
            let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
            if !cdt.can_add_constraint(a, b) {
                return Err(Error::value(
                    name,
                    "the outline and its holes cross each other: a hole must lie inside the \
                     outline, apart from every other hole",
                ));
            }
            cdt.add_constraint(a, b);
        }
    }
    // Refinement stops once every triangle is under the area limit, so a limit of an
    // equilateral triangle of side `edge` leaves edges of about 0.8 `edge`: 1.6 times that
    // area gives a median edge of about `edge` (measured by the panel test).
    let target = 1.6 * 3f64.sqrt() / 4.0 * edge * edge;
    let area = outline_area(outline);
    let budget = (8.0 * area / target) as usize + 10_000;
    let result = cdt.refine(
        RefinementParameters::new()
            .exclude_outer_faces(true)
            .keep_constraint_edges()
            .with_angle_limit(AngleLimit::from_deg(ANGLE_LIMIT))
            .with_max_allowed_area(target)
            .with_max_additional_vertices(budget),
    );
    if !result.refinement_complete {
        return Err(Error::value(
            name,
            format!(
                "refining the mesh to an edge length of {edge} m needed more than {budget} \
                 extra vertices: make the edge length larger"
            ),
        ));
    }
    let excluded: std::collections::HashSet<_> = result.excluded_faces.into_iter().collect();
    let mut used = vec![u32::MAX; cdt.num_vertices()];
    let mut points = Vec::new();
    // The boundary's points first, in order, so that ring point k is vertex k.
    for v in cdt.vertices().take(count) {
        used[v.fix().index()] = points.len() as u32;
        let p = v.position();
        points.push(DVec2::new(p.x, p.y));
    }
    let mut triangles = Vec::new();
    for face in cdt.inner_faces() {
        if excluded.contains(&face.fix()) {
            continue;
        }
        let tri = face.vertices().map(|v| {
            let slot = &mut used[v.fix().index()];
            if *slot == u32::MAX {
                *slot = points.len() as u32;
                let p = v.position();
                points.push(DVec2::new(p.x, p.y));
            }
            *slot
        });
        triangles.push(tri);
    }
    Ok(FlatMesh { points, triangles })
}

fn outline_area(outline: &[DVec2]) -> f64 {
    0.5 * super::outline::signed_area2(outline).abs()
}
