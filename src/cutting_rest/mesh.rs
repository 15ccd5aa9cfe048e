//! A mesh cloth's rest sheet, where its rest shape is flat: a live stroke's material points and
//! the springs it severs, in the plane the cloth was made in.
//!
//! The sheet is a set of charts, each a plane with the triangles laid out on it: a garment's
//! panels, each in its own 2-D layout before sewing ([`crate::scene::FlatPanels`]); or, for
//! another mesh, one chart, the plane fitted to the rest shape, onto which every triangle
//! projects. The projection is used only where it is one to one round every triangle: each
//! triangle faces within [`MAX_TILT_DEG`] of the plane's normal, all the same way. A mesh that
//! is curved at rest (a triangle tilted more, or turned over) has no sheet and keeps the swept
//! cut. What matters for a cut is that the map from material to sheet is continuous and does
//! not fold, not that it keeps lengths: a stroke is a polyline through the points the mouse
//! hit, consecutive points a fraction of a spacing apart.
//!
//! A spring is on a chart when the triangles it belongs to are: a stretch spring on each of its
//! (one or two) triangles' charts, a bend spring on the chart of its two triangles when they
//! share it and agree where the edge between them is. A bend spring across a seam (two panels
//! whose sewn edges started on each other and were merged into one) is on no chart: only the
//! swept cut the stroke falls back to where it crosses from one chart to another severs it.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::{lines_meeting, segments_crossing};
use crate::cutting::MeshCrossing;
use crate::mesh_cloth::topology::NONE;
use crate::mesh_cloth::{EdgeKind, EdgeSprings, MeshTopology};

/// The largest angle in degrees between a triangle's normal and the fitted plane's normal for
/// the rest shape to count as flat (default 45). Projected onto the plane, a triangle tilted by
/// `a` shrinks by `cos a` across the tilt, so up to 45 degrees no triangle comes near turning
/// over; `flag_hole`'s 3 cm wave tilts its triangles by up to 17 degrees. Larger admits more
/// curved meshes at the price of sheets whose straight segments bend further from the
/// stroke's path over the cloth.
pub const MAX_TILT_DEG: f64 = 45.0;

/// Cells of a chart's spring buckets, in spacings: a bucket holds the springs whose rest boxes
/// overlap it, so a short stroke segment looks at a few dozen springs.
const CELL_SPACINGS: f64 = 2.0;

/// A mesh cloth's rest sheet (see the module's docs).
#[derive(Clone, Debug)]
pub struct MeshSheet {
    /// Per triangle, its chart.
    chart: Vec<u32>,
    /// Per triangle, its corners on its chart (m).
    corners: Vec<[DVec2; 3]>,
    charts: Vec<Chart>,
    /// The mean rest edge length (m).
    pub spacing: f64,
}

/// One chart's springs, bucketed, and its boundary.
#[derive(Clone, Debug, Default)]
struct Chart {
    lo: DVec2,
    cell: f64,
    dims: [usize; 2],
    /// The springs overlapping cell `c` are `items[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    items: Vec<Item>,
    /// The chart's boundary edges: triangle edges no other triangle of the chart shares.
    boundary: Vec<(DVec2, DVec2)>,
}

/// A spring on a chart: its index and its ends `a`, `b` there.
#[derive(Clone, Copy, Debug)]
struct Item {
    spring: u32,
    a: DVec2,
    b: DVec2,
}

impl MeshSheet {
    /// The sheet of `topology`'s mesh, or `None` if its rest shape is not flat (and it is not a
    /// garment of flat panels).
    pub fn new(topology: &MeshTopology) -> Option<MeshSheet> {
        let mesh = &topology.mesh;
        let (chart, corners) = match &mesh.panels {
            Some(panels) => (
                panels.panel.clone(),
                (panels.corners.iter())
                    .map(|c| c.map(DVec2::from))
                    .collect(),
            ),
            None => (vec![0; mesh.triangles.len()], plane_corners(mesh)?),
        };
        let n_charts = chart.iter().max().map_or(0, |&c| c as usize + 1);
        let spacing = mesh.mean_edge;
        let mut items: Vec<Vec<Item>> = vec![Vec::new(); n_charts];
        let springs = &mesh.springs;
        let oriented = |e: u32, p: u32, q: u32, (x, y): (DVec2, DVec2)| {
            let e = e as usize;
            debug_assert!(springs.kind[e] != EdgeKind::Seam);
            if springs.a[e] == p && springs.b[e] == q {
                Some((x, y))
            } else if springs.a[e] == q && springs.b[e] == p {
                Some((y, x))
            } else {
                None
            }
        };
        // The first triangle met across each bend spring: (triangle, edge).
        let mut first_side: HashMap<u32, (usize, usize)> = HashMap::new();
        // Where each stretch spring listed on a chart starts there: an interior edge is listed
        // once; an edge whose two triangles put it in two places (a panel sewn to itself) twice.
        let mut listed: HashMap<(u32, u32), DVec2> = HashMap::new();
        let mut edge_uses: HashMap<(u32, u32, u32), u32> = HashMap::new();
        for (t, tri) in topology.triangles.iter().enumerate() {
            let (c, at) = (chart[t], corners[t]);
            let (edges, bends) = (topology.edge_springs(t), topology.bend_springs(t));
            for k in 0..3 {
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                *edge_uses.entry((c, p.min(q), p.max(q))).or_default() += 1;
                let e = edges[k];
                if e != NONE {
                    if let Some((a, b)) = oriented(e, p, q, (at[k], at[(k + 1) % 3])) {
                        if listed.insert((c, e), a) != Some(a) {
                            items[c as usize].push(Item { spring: e, a, b });
                        }
                    }
                }
                let b = bends[k];
                if b == NONE {
                    continue;
                }
                let Some(&(u, j)) = first_side.get(&b) else {
                    first_side.insert(b, (t, k));
                    continue;
                };
                // Both triangles on one chart, agreeing on their shared edge's two ends.
                let other = topology.triangles[u];
                let (cu, au) = (chart[u], corners[u]);
                let same_edge = (au[j] == at[(k + 1) % 3] && au[(j + 1) % 3] == at[k])
                    || (au[j] == at[k] && au[(j + 1) % 3] == at[(k + 1) % 3]);
                if cu != c || !same_edge {
                    continue;
                }
                let ends = (at[(k + 2) % 3], au[(j + 2) % 3]);
                if let Some((a, b2)) = oriented(b, tri[(k + 2) % 3], other[(j + 2) % 3], ends) {
                    items[c as usize].push(Item {
                        spring: b,
                        a,
                        b: b2,
                    });
                }
            }
        }
        let mut boundary: Vec<Vec<(DVec2, DVec2)>> = vec![Vec::new(); n_charts];
        for (t, tri) in topology.triangles.iter().enumerate() {
            let (c, at) = (chart[t], corners[t]);
            for k in 0..3 {
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                if edge_uses[&(c, p.min(q), p.max(q))] == 1 {
                    boundary[c as usize].push((at[k], at[(k + 1) % 3]));
                }
            }
        }
        let charts = (items.into_iter().zip(boundary))
            .map(|(items, boundary)| Chart::new(items, boundary, CELL_SPACINGS * spacing))
            .collect();
        Some(MeshSheet {
            chart,
            corners,
            charts,
            spacing,
        })
    }

    /// The material point of triangle `t` at barycentric weights `w`: its chart and where on it.
    pub fn at(&self, t: usize, w: [f32; 3]) -> (u32, DVec2) {
        let c = self.corners[t];
        let point = (0..3).fold(DVec2::ZERO, |sum, k| sum + w[k] as f64 * c[k]);
        (self.chart[t], point)
    }

    /// How far from `from` along the unit direction `dir` the chart's material ends (its first
    /// boundary edge that way), plus one spacing so that the springs on that edge are crossed.
    /// Infinite if no boundary edge lies that way.
    pub fn exit_distance(&self, chart: u32, from: DVec2, dir: DVec2) -> f64 {
        let nearest = (self.charts[chart as usize].boundary.iter())
            .filter_map(|&edge| {
                // Where the ray from `from` crosses the edge, along the ray (`dir` is a unit).
                let (t, along) = lines_meeting(edge, (from, from + dir))?;
                ((0.0..=1.0).contains(&t) && along >= 0.0).then_some(along)
            })
            .fold(f64::INFINITY, f64::min);
        nearest + self.spacing
    }

    /// Appends the live springs on `chart` whose rest segments cross the rest segment `a`-`b`,
    /// each with where it crosses (`t` from its end `a`). Only the buckets the segment's box
    /// touches are looked at; a spring in several of them is reported by the one holding its
    /// crossing, so it is listed once. Allocates nothing beyond `out`.
    pub fn crossings(
        &self,
        chart: u32,
        (springs, alive): (&EdgeSprings, &[bool]),
        (a, b): (DVec2, DVec2),
        out: &mut Vec<MeshCrossing>,
    ) {
        let c = &self.charts[chart as usize];
        let Some(([i0, j0], [i1, j1])) = c.range(a.min(b), a.max(b)) else {
            return;
        };
        for j in j0..=j1 {
            for i in i0..=i1 {
                let cell = j * c.dims[0] + i;
                let run = c.start[cell] as usize..c.start[cell + 1] as usize;
                for item in &c.items[run] {
                    let e = item.spring as usize;
                    let (p, q) = (springs.a[e] as usize, springs.b[e] as usize);
                    if !(springs.active[e] && alive[p] && alive[q]) {
                        continue;
                    }
                    let Some(t) = segments_crossing((item.a, item.b), (a, b)) else {
                        continue;
                    };
                    // The cell of the crossing, within both boxes' cells (they hold it).
                    let x = item.a + t * (item.b - item.a);
                    let Some((lo, hi)) = c.range(item.a.min(item.b), item.a.max(item.b)) else {
                        continue;
                    };
                    let home = c.cell_of(x);
                    let clamp = |k: usize, axis: usize| {
                        let (lo, hi) = (lo[axis].max([i0, j0][axis]), hi[axis].min([i1, j1][axis]));
                        k.clamp(lo, hi.max(lo))
                    };
                    if [clamp(home[0], 0), clamp(home[1], 1)] == [i, j] {
                        out.push((item.spring, t as f32));
                    }
                }
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.chart.capacity() * 4
            + self.corners.capacity() * 48
            + (self.charts.iter())
                .map(|c| {
                    c.start.capacity() * 4
                        + c.items.capacity() * size_of::<Item>()
                        + c.boundary.capacity() * 32
                })
                .sum::<usize>()
    }
}

impl Chart {
    /// Buckets `items` on cells of `cell` m round their boxes.
    fn new(items: Vec<Item>, boundary: Vec<(DVec2, DVec2)>, cell: f64) -> Chart {
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for i in &items {
            (lo, hi) = (lo.min(i.a.min(i.b)), hi.max(i.a.max(i.b)));
        }
        // No more cells than about the items: a mesh of very unequal triangles (a mean edge
        // far below its extent) would otherwise ask for a grid of cells without bound.
        let cell = cell.max((hi - lo).max_element() / (items.len() as f64).sqrt());
        // A cell that is not a positive length (no edges) buckets nothing.
        if items.is_empty() || cell.is_nan() || cell <= 0.0 {
            return Chart {
                boundary,
                ..Chart::default()
            };
        }
        let dims = ((hi - lo) / cell).floor().as_uvec2() + 1;
        let mut chart = Chart {
            lo,
            cell,
            dims: [dims.x as usize, dims.y as usize],
            start: Vec::new(),
            items: Vec::new(),
            boundary,
        };
        let cells = chart.dims[0] * chart.dims[1];
        let mut count = vec![0u32; cells + 1];
        let spans: Vec<_> = (items.iter())
            .map(|i| {
                chart
                    .range(i.a.min(i.b), i.a.max(i.b))
                    .expect("inside the box")
            })
            .collect();
        for &([i0, j0], [i1, j1]) in &spans {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    count[j * chart.dims[0] + i + 1] += 1;
                }
            }
        }
        for c in 0..cells {
            count[c + 1] += count[c];
        }
        let mut next = count.clone();
        let mut placed = vec![items[0]; count[cells] as usize];
        for (item, &([i0, j0], [i1, j1])) in items.iter().zip(&spans) {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let slot = &mut next[j * chart.dims[0] + i];
                    placed[*slot as usize] = *item;
                    *slot += 1;
                }
            }
        }
        chart.start = count;
        chart.items = placed;
        chart
    }

    /// The cell holding `x`, clamped to the chart.
    fn cell_of(&self, x: DVec2) -> [usize; 2] {
        let k = ((x - self.lo) / self.cell).floor();
        let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64 - 1.0) as usize;
        [clamp(k.x, self.dims[0]), clamp(k.y, self.dims[1])]
    }

    /// The cells a box from `lo` to `hi` overlaps, or `None` if it lies off the chart.
    fn range(&self, lo: DVec2, hi: DVec2) -> Option<([usize; 2], [usize; 2])> {
        let (a, b) = ((lo - self.lo) / self.cell, (hi - self.lo) / self.cell);
        let (nx, ny) = (self.dims[0] as f64, self.dims[1] as f64);
        if b.x < 0.0 || b.y < 0.0 || a.x >= nx || a.y >= ny || a.is_nan() || b.is_nan() {
            return None;
        }
        let lo = [a.x.floor().max(0.0) as usize, a.y.floor().max(0.0) as usize];
        let hi = [
            (b.x.floor() as usize).min(self.dims[0] - 1),
            (b.y.floor() as usize).min(self.dims[1] - 1),
        ];
        Some((lo, hi))
    }
}

/// Each triangle's corners on the plane fitted to the rest shape (through the vertices'
/// centroid, normal to the sum of the triangles' area vectors), or `None` if a triangle faces
/// more than [`MAX_TILT_DEG`] away from that normal (the rest shape is curved or folded).
fn plane_corners(mesh: &crate::mesh_cloth::MeshCloth) -> Option<Vec<[DVec2; 3]>> {
    let at = |v: u32| DVec3::from(mesh.rest[v as usize]);
    let area = |t: &[u32; 3]| (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0]));
    let normal = mesh
        .triangles
        .iter()
        .map(area)
        .sum::<DVec3>()
        .try_normalize()?;
    let cos = MAX_TILT_DEG.to_radians().cos();
    let flat = (mesh.triangles.iter()).all(|t| area(t).normalize().dot(normal) >= cos);
    if !flat {
        return None;
    }
    let centre = mesh.rest.iter().map(|&v| DVec3::from(v)).sum::<DVec3>() / mesh.rest.len() as f64;
    let (u, w) = normal.any_orthonormal_pair();
    let on = |v: u32| {
        let d = at(v) - centre;
        DVec2::new(d.dot(u), d.dot(w))
    };
    Some(mesh.triangles.iter().map(|t| t.map(on)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh_cloth::{jittered_square, MeshCloth};
    use crate::scene::MeshSpec;

    #[test]
    fn a_sheet_of_very_unequal_edges_keeps_its_cells_near_its_edge_count() {
        // Many millimetre edges and one a kilometre long: cells two mean edges wide would
        // number about 1e12.
        let mut items: Vec<Item> = (0..1000)
            .map(|k| {
                let a = DVec2::new(k as f64 * 1e-3, 0.0);
                Item {
                    spring: k,
                    a,
                    b: a + DVec2::new(1e-3, 1e-3),
                }
            })
            .collect();
        items.push(Item {
            spring: 1000,
            a: DVec2::ZERO,
            b: DVec2::new(1e3, 1e3),
        });
        let chart = Chart::new(items, Vec::new(), 2e-3);
        let (cells, edges) = (chart.dims[0] * chart.dims[1], 1001);
        assert!(cells <= 2 * edges, "{cells} cells for {edges} edges");
        let fine = Chart::new(
            vec![Item {
                spring: 0,
                a: DVec2::ZERO,
                b: DVec2::ONE,
            }],
            Vec::new(),
            2e-3,
        );
        assert!(fine.dims[0] * fine.dims[1] <= 4, "{:?}", fine.dims);
    }

    fn topology(vertices: Vec<[f64; 3]>, triangles: Vec<[i64; 3]>) -> MeshTopology {
        let spec = MeshSpec {
            vertices,
            triangles,
            ..MeshSpec::default()
        };
        MeshTopology::new(MeshCloth::new(&spec).expect("a valid mesh"))
    }

    /// Each vertex's place on the sheet (chart 0), from a triangle it is a corner of.
    fn places(top: &MeshTopology, sheet: &MeshSheet) -> Vec<DVec2> {
        let mut at = vec![DVec2::NAN; top.mesh.len()];
        for (t, tri) in top.triangles.iter().enumerate() {
            for (k, &v) in tri.iter().enumerate() {
                let mut w = [0.0; 3];
                w[k] = 1.0;
                at[v as usize] = sheet.at(t, w).1;
            }
        }
        at
    }

    #[test]
    fn a_rest_stroke_across_a_flat_mesh_leaves_no_spring_joining_its_two_sides() {
        // A tilted plane with a gentle wave across it, as `flag_hole` has.
        let (flat, triangles) = jittered_square(14, 1.0, [0.0, 0.0, 0.0], 0.3, 11);
        let vertices = (flat.iter())
            .map(|&[x, y, _]| {
                let z = 0.03 * (2.0 * std::f64::consts::PI * x / 0.6).sin();
                [x, 0.8 * y + 0.6 * z, -0.6 * y + 0.8 * z]
            })
            .collect();
        let top = topology(vertices, triangles);
        let sheet = MeshSheet::new(&top).expect("a flat rest shape has a sheet");
        let at = places(&top, &sheet);
        let (lo, hi) = at
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(l, h), &p| {
                (l.min(p), h.max(p))
            });
        // A slanted line from off one side to off the other, in three pieces.
        let (from, to) = (
            DVec2::new(lo.x - 0.1, lo.y + 0.3),
            DVec2::new(hi.x + 0.1, hi.y - 0.2),
        );
        let pts: Vec<DVec2> = (0..4).map(|k| from.lerp(to, k as f64 / 3.0)).collect();
        let springs = &top.mesh.springs;
        let alive = vec![true; top.mesh.len()];
        let mut out = Vec::new();
        for w in pts.windows(2) {
            sheet.crossings(0, (springs, &alive), (w[0], w[1]), &mut out);
        }
        let side = |p: DVec2| (to - from).perp_dot(p - from) > 0.0;
        let cut: std::collections::HashSet<u32> = out.iter().map(|c| c.0).collect();
        assert_eq!(cut.len(), out.len(), "each spring listed once");
        for e in 0..springs.len() {
            let (a, b) = (at[springs.a[e] as usize], at[springs.b[e] as usize]);
            if side(a) != side(b) {
                assert!(cut.contains(&(e as u32)), "spring {e} joins the two sides");
            }
        }
        for &(e, t) in &out {
            let (a, b) = (
                at[springs.a[e as usize] as usize],
                at[springs.b[e as usize] as usize],
            );
            let x = a.lerp(b, t as f64);
            assert!(
                (to - from).normalize().perp_dot(x - from).abs() < 1e-6,
                "crossed on the line"
            );
        }
    }

    #[test]
    fn a_garments_panels_lay_each_triangle_out_at_its_rest_shape() {
        // Placed flat or wrapped on a cylinder, a panel keeps its lengths: each triangle's
        // corners on its panel are as far apart as its vertices at rest, merged seams included.
        for name in ["shirt", "skirt"] {
            let scene = crate::scene::Scene::builtin(name).expect("a built-in scene");
            let mesh = scene
                .cloth
                .mesh
                .as_ref()
                .expect("a garment compiles to a mesh");
            let panels = mesh.panels.as_ref().expect("a garment keeps its panels");
            assert_eq!(panels.corners.len(), mesh.triangles.len());
            for (t, tri) in mesh.triangles.iter().enumerate() {
                let c = panels.corners[t].map(DVec2::from);
                for k in 0..3 {
                    let (p, q) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                    let rest =
                        DVec3::from(mesh.vertices[p]).distance(DVec3::from(mesh.vertices[q]));
                    let flat = c[k].distance(c[(k + 1) % 3]);
                    // A wrapped panel's chord is shorter than its arc by about L^3 / (24 r^2).
                    assert!(
                        (rest - flat).abs() < 1e-2 * flat,
                        "{name} triangle {t}: {rest} {flat}"
                    );
                }
            }
            let top = MeshTopology::new(MeshCloth::new(mesh).expect("a valid mesh"));
            let sheet = MeshSheet::new(&top).expect("a garment of flat panels has a sheet");
            let count = panels.panel.iter().max().map_or(0, |&p| p as usize + 1);
            assert_eq!(sheet.charts.len(), count);
        }
    }

    #[test]
    fn a_curved_rest_shape_has_no_sheet() {
        // Half a cylinder: its triangles face every way over 180 degrees.
        let (flat, triangles) = jittered_square(10, 1.0, [0.5, 0.5, 0.0], 0.2, 3);
        let vertices = (flat.iter())
            .map(|&[x, y, _]| {
                let a = x * std::f64::consts::PI;
                [0.3 * a.cos(), y, 0.3 * a.sin()]
            })
            .collect();
        assert!(MeshSheet::new(&topology(vertices, triangles)).is_none());
    }

    #[test]
    fn the_exit_from_inside_a_flat_mesh_reaches_one_spacing_past_its_edge() {
        let (vertices, triangles) = jittered_square(9, 1.0, [0.0, 0.0, 0.0], 0.3, 2);
        let top = topology(vertices, triangles);
        let sheet = MeshSheet::new(&top).expect("flat");
        let at = places(&top, &sheet);
        let centre = at.iter().sum::<DVec2>() / at.len() as f64;
        for dir in [DVec2::X, DVec2::Y, -DVec2::X, DVec2::new(0.6, -0.8)] {
            let d = sheet.exit_distance(0, centre, dir);
            // The square's half-width is 0.5 m (its sheet turned in the plane, not scaled).
            assert!(
                d > 0.5 + 0.5 * sheet.spacing && d < 0.72 + 1.5 * sheet.spacing,
                "{d}"
            );
        }
    }
}
