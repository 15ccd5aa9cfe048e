//! The nearest-point query of a mesh collider, answered from a uniform grid over its triangles.
//!
//! Contact asks every particle near a mesh for the surface point nearest it within a short
//! distance: the collider's thickness plus the particle's travel over the substep, a few mm for
//! cloth at rest on it. Parry's `TriMesh` answers through its BVH, a walk from the root of about
//! 15 levels for a 20k-triangle body, repeated for every near particle in every substep, where
//! the question is local and asks for no walk at all. The grid answers the same question from one cell: each cell lists every triangle whose bounding
//! box comes within `reach` of the cell, so a query of at most `reach` from a point in the cell
//! has every triangle that can answer it in that list, and the answer is exact, not a
//! neighbourhood guess.
//!
//! Queries the grid cannot answer from one list go to the BVH, unchanged: a longer one (a fast
//! particle, a fast shape), one in a crowded cell (a mesh much finer in one place than the mean),
//! a point that is not finite, and every query of a mesh that would list its triangles too often
//! (large overlapping triangles among small ones; see [`ENTRIES_PER_TRIANGLE`]). The swept ray
//! cast stays with the BVH too: it runs only for a particle that may have crossed the surface,
//! rarely at rest.
//!
//! The winner is projected by parry's own triangle projection and told inside or outside by the
//! mesh's own angle-weighted pseudo-normals, as `TriMesh`'s query does, so the two answer alike:
//! the same distance, and the same side, on every point (tested). Where two triangles are exactly
//! as near, the lower index wins here; the BVH may pick the other, at the same point.

use glam::{Vec3, Vec3A};
use parry3d::query::{PointProjection, PointQueryWithLocation};
use parry3d::shape::{TriMesh, TrianglePointLocation};

/// Cells with more candidates than this send their queries to the BVH: a list that long costs
/// more to scan than the tree's walk.
const MAX_CANDIDATES: usize = 64;

/// At most this many cells per triangle (and never fewer than [`MIN_CELLS`]); a mesh whose
/// triangles are small against its extent gets coarser cells rather than a huge grid.
const CELLS_PER_TRIANGLE: usize = 16;
const MIN_CELLS: usize = 1 << 15;

/// At most this many list entries per triangle on average (and never fewer than
/// [`MIN_ENTRIES`] in all), counted before the grid is built; a mesh that would need more
/// (triangles far larger than its mean edge, overlapping) gets no grid, and all its queries go
/// to the BVH. This bounds the grid's memory (36 bytes an entry) and build time for any mesh.
const ENTRIES_PER_TRIANGLE: usize = 64;
const MIN_ENTRIES: usize = 1 << 20;

/// A uniform grid over a mesh's triangles, in the mesh's frame.
pub(super) struct MeshGrid {
    /// The corner of cell (0, 0, 0), m.
    origin: Vec3,
    /// 1 / the cell's edge, 1/m.
    inv_cell: f32,
    dims: [usize; 3],
    /// The longest query (m) the grid answers from one cell's list.
    reach: f32,
    /// Cell `c`'s triangles are `triangles[starts[c]..starts[c + 1]]`, in index order, each
    /// with its bounding box at the same place in `boxes` (`[min, max]`): a candidate whose box
    /// is further than the best so far is passed over on these, without projecting onto it, and
    /// they lie in the order they are read.
    starts: Vec<u32>,
    triangles: Vec<u32>,
    boxes: Vec<[Vec3A; 2]>,
}

/// What the grid says of one query.
pub(super) enum Nearest {
    /// The nearest surface point within the query's distance, on triangle `subshape`.
    Found(PointProjection),
    /// No triangle is within the query's distance.
    None,
    /// The grid cannot tell from one cell: ask the BVH.
    AskTheTree,
}

impl MeshGrid {
    /// Bytes the grid holds on the heap.
    pub(super) fn heap_bytes(&self) -> usize {
        self.starts.capacity() * size_of::<u32>()
            + self.triangles.capacity() * size_of::<u32>()
            + self.boxes.capacity() * size_of::<[Vec3A; 2]>()
    }

    /// The grid of `mesh`, for queries up to `reach` m (the collider's thickness and some
    /// travel). A longer reach answers faster particles from the grid, at the price of longer
    /// lists for every query.
    pub(super) fn new(mesh: &TriMesh, reach: f32) -> MeshGrid {
        let count = mesh.indices().len() as u32;
        let boxes: Vec<[Vec3; 2]> = (0..count)
            .map(|t| {
                let tri = mesh.triangle(t);
                [tri.a.min(tri.b).min(tri.c), tri.a.max(tri.b).max(tri.c)]
            })
            .collect();
        let (lo, hi) = boxes.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), b| (lo.min(b[0]), hi.max(b[1])),
        );
        // Cells about a triangle's size: a cell's list then holds a handful of triangles.
        let mean_edge = (0..count)
            .map(|t| {
                let tri = mesh.triangle(t);
                (tri.b - tri.a).length() + (tri.c - tri.b).length() + (tri.a - tri.c).length()
            })
            .sum::<f32>()
            / (3 * count).max(1) as f32;
        // No smaller than the reach either: a triangle's box grown by the reach then spans a few
        // cells on each axis, however thick the collider.
        let mut cell = mean_edge.max(reach).max(f32::MIN_POSITIVE);
        let max_cells = (CELLS_PER_TRIANGLE * boxes.len()).max(MIN_CELLS);
        let dims_of = |cell: f32| {
            let extent = hi - lo + Vec3::splat(2.0 * reach);
            let d = (extent / cell).ceil().max(Vec3::ONE);
            [d.x as usize, d.y as usize, d.z as usize]
        };
        // Counted in f64: a mesh kilometres across would overflow the product.
        let cells_of = |cell: f32| dims_of(cell).iter().map(|&d| d as f64).product::<f64>();
        while cells_of(cell) > max_cells as f64 {
            cell *= 1.25;
        }
        let dims = dims_of(cell);
        let origin = lo - Vec3::splat(reach);
        let inv_cell = 1.0 / cell;
        // Triangle `t` is listed in every cell within `reach` of it: first the cells its box,
        // grown by `reach`, overlaps; of those, the cells its plane passes within `reach` of
        // (a tilted triangle's box spans many cells its plane is far from).
        // The first and last cell (unclamped) along each axis of triangle `t`'s box grown by
        // `reach`.
        let span = |t: usize| {
            let [b_lo, b_hi] = boxes[t];
            (
                ((b_lo - Vec3::splat(reach) - origin) * inv_cell).floor(),
                ((b_hi + Vec3::splat(reach) - origin) * inv_cell).floor(),
            )
        };
        let visit = |t: u32, f: &mut dyn FnMut(usize)| {
            let (first, last) = span(t as usize);
            let clamp = |v: f32, d: usize| (v.max(0.0) as usize).min(d - 1);
            let tri = mesh.triangle(t);
            let normal = tri.normal().unwrap_or(Vec3::Y);
            // How far the plane may be from a cell's centre and still come within `reach` of
            // the cell: `reach` plus the cell's half-extent along the normal.
            let slack = reach + 0.5 * cell * normal.abs().element_sum();
            for z in clamp(first.z, dims[2])..=clamp(last.z, dims[2]) {
                for y in clamp(first.y, dims[1])..=clamp(last.y, dims[1]) {
                    for x in clamp(first.x, dims[0])..=clamp(last.x, dims[0]) {
                        let centre =
                            origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                        if normal.dot(centre - tri.a).abs() <= slack * (1.0 + 1e-5) {
                            f((z * dims[1] + y) * dims[0] + x);
                        }
                    }
                }
            }
        };
        // The cells the grown boxes span bound the entries, before any is made.
        let spanned: f64 = (0..boxes.len())
            .map(|t| {
                let (first, last) = span(t);
                let n = (last - first + Vec3::ONE).as_dvec3();
                n.x * n.y * n.z
            })
            .sum();
        if spanned > (ENTRIES_PER_TRIANGLE * boxes.len()).max(MIN_ENTRIES) as f64 {
            return MeshGrid::none();
        }
        // Two passes (count, then fill) into one flat array: a cell's list is contiguous, and
        // filled in triangle order, which is what breaks exact ties.
        let cells = dims.iter().product::<usize>();
        let mut starts = vec![0u32; cells + 1];
        for t in 0..count {
            visit(t, &mut |c| starts[c + 1] += 1);
        }
        for c in 0..cells {
            starts[c + 1] += starts[c];
        }
        let mut fill = starts.clone();
        let mut triangles = vec![0u32; starts[cells] as usize];
        for t in 0..count {
            visit(t, &mut |c| {
                triangles[fill[c] as usize] = t;
                fill[c] += 1;
            });
        }
        let boxes = triangles
            .iter()
            .map(|&t| boxes[t as usize].map(Vec3A::from))
            .collect();
        MeshGrid {
            origin,
            inv_cell,
            dims,
            reach,
            starts,
            triangles,
            boxes,
        }
    }

    /// A grid that answers nothing, sending every query to the BVH.
    fn none() -> MeshGrid {
        MeshGrid {
            origin: Vec3::ZERO,
            inv_cell: 1.0,
            dims: [1; 3],
            reach: f32::NEG_INFINITY,
            starts: vec![0; 2],
            triangles: Vec::new(),
            boxes: Vec::new(),
        }
    }

    /// The surface point of `mesh` (the mesh this grid was built over) nearest `point`, closer
    /// than `max_dist` (m), as `TriMesh::project_local_point_and_get_location_with_max_dist`
    /// with `solid = false` answers it.
    #[inline]
    pub(super) fn nearest(&self, mesh: &TriMesh, point: Vec3, max_dist: f32) -> Nearest {
        if !(max_dist <= self.reach && point.is_finite()) {
            return Nearest::AskTheTree;
        }
        let cell = (point - self.origin) * self.inv_cell;
        if cell.min_element() < 0.0 {
            return Nearest::None; // further than `reach` from every triangle
        }
        // Non-negative, so truncation is the floor.
        let [x, y, z] = [cell.x as usize, cell.y as usize, cell.z as usize];
        if x >= self.dims[0] || y >= self.dims[1] || z >= self.dims[2] {
            return Nearest::None;
        }
        let c = (z * self.dims[1] + y) * self.dims[0] + x;
        let range = self.starts[c] as usize..self.starts[c + 1] as usize;
        if range.len() > MAX_CANDIDATES {
            return Nearest::AskTheTree;
        }
        let p = Vec3A::from(point);
        let mut best = max_dist * max_dist;
        let mut found = None;
        for (&t, &[lo, hi]) in self.triangles[range.clone()].iter().zip(&self.boxes[range]) {
            let outside = (lo - p).max(p - hi).max(Vec3A::ZERO);
            if outside.length_squared() >= best {
                continue;
            }
            let (projection, location) = mesh
                .triangle(t)
                .project_local_point_and_get_location(point, false);
            let d2 = (projection.point - point).length_squared();
            if d2 < best {
                best = d2;
                found = Some((t, projection, location));
            }
        }
        let Some((triangle, mut projection, location)) = found else {
            return Nearest::None;
        };
        if let Some(pseudo_normal) = pseudo_normal(mesh, triangle, location) {
            projection.is_inside = (point - projection.point).dot(pseudo_normal) <= 0.0;
        }
        projection.subshape = triangle;
        Nearest::Found(projection)
    }
}

/// The outward pseudo-normal of the feature of `triangle` a point projected onto, when the mesh
/// has them (`ORIENTED`): the face's normal, or the angle-weighted normal of an edge or vertex,
/// which tells inside from outside where a face's normal alone does not. Parry's own rule.
fn pseudo_normal(mesh: &TriMesh, triangle: u32, location: TrianglePointLocation) -> Option<Vec3> {
    let normals = mesh.pseudo_normals_if_oriented()?;
    match location {
        TrianglePointLocation::OnFace(..) | TrianglePointLocation::OnSolid => {
            Some(mesh.triangle(triangle).scaled_normal())
        }
        TrianglePointLocation::OnEdge(i, _) => normals
            .edges_pseudo_normal
            .get(triangle as usize)
            .map(|pn| pn[i as usize]),
        TrianglePointLocation::OnVertex(i) => {
            let vertex = mesh.indices()[triangle as usize][i as usize];
            normals.vertices_pseudo_normal.get(vertex as usize).copied()
        }
    }
}

#[cfg(test)]
mod tests_support {
    use super::*;
    use parry3d::shape::TriMeshFlags;

    /// An octahedron subdivided `level` times (8 * 4^level triangles), on the sphere of
    /// `radius`, wound counter-clockwise seen from outside.
    pub fn octasphere(level: u32, radius: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut v = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let mut f: Vec<[u32; 3]> = vec![
            [0, 2, 4],
            [4, 2, 1],
            [1, 2, 5],
            [5, 2, 0],
            [4, 3, 0],
            [1, 3, 4],
            [5, 3, 1],
            [0, 3, 5],
        ];
        for _ in 0..level {
            let mut middle = std::collections::HashMap::new();
            let mut mid = |a: u32, b: u32, v: &mut Vec<Vec3>| {
                *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push((v[a as usize] + v[b as usize]).normalize());
                    v.len() as u32 - 1
                })
            };
            f = f
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        (v.into_iter().map(|p| p * radius).collect(), f)
    }

    /// A deterministic stream of points in `[-half, half]^3` (a 64-bit LCG).
    pub fn points(n: usize, half: f32) -> Vec<Vec3> {
        let mut s = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        (0..n)
            .map(|_| Vec3::new(next(), next(), next()) * half)
            .collect()
    }

    pub fn oriented(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> TriMesh {
        let flags = TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES;
        TriMesh::with_flags(vertices, triangles, flags).unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::*;
    use super::*;

    /// The grid and parry's BVH agree on every point: both find nothing, or both find a point
    /// at the same distance on the same side; and the grid answered at least `share` of the
    /// queries itself (the rest it sent to the tree).
    fn agree(mesh: &TriMesh, queries: &[Vec3], max_dist: f32, share: f64) {
        let grid = MeshGrid::new(mesh, max_dist);
        let mut answered = 0;
        for &p in queries {
            let tree = mesh.project_local_point_and_get_location_with_max_dist(p, false, max_dist);
            match (grid.nearest(mesh, p, max_dist), tree) {
                (Nearest::AskTheTree, _) => continue,
                (Nearest::None, None) => {}
                (Nearest::Found(projection), Some((expected, _))) => {
                    let (d, e) = (
                        (projection.point - p).length(),
                        (expected.point - p).length(),
                    );
                    assert!((d - e).abs() <= 1e-6 * (1.0 + e), "{p}: {d} against {e}");
                    assert_eq!(
                        projection.is_inside, expected.is_inside,
                        "{p} (distance {d})"
                    );
                }
                (Nearest::None, Some((e, _))) => panic!("{p}: missed {}", (e.point - p).length()),
                (Nearest::Found(projection), None) => {
                    panic!(
                        "{p}: found {} beyond the reach",
                        (projection.point - p).length()
                    )
                }
            }
            answered += 1;
        }
        let wanted = (share * queries.len() as f64).ceil() as usize;
        assert!(
            answered >= wanted,
            "{answered} of {} answered",
            queries.len()
        );
    }

    #[test]
    fn the_grid_answers_as_the_tree_does_near_a_closed_mesh() {
        let (v, f) = octasphere(5, 0.5);
        let mesh = oriented(v, f);
        // Points in a shell around the surface, inside and out, and a few far ones.
        let shell: Vec<Vec3> = points(20_000, 1.0)
            .into_iter()
            .map(|p| p.normalize_or(Vec3::Y) * (0.5 + 0.02 * p.x.sin()) + 0.001 * p)
            .chain(points(2000, 0.8))
            .collect();
        agree(&mesh, &shell, 0.01, 0.9);
    }

    #[test]
    fn the_grid_answers_as_the_tree_does_at_a_box_meshs_edges_and_corners() {
        // Twelve large triangles: the pseudo-normals at edges and corners decide the side.
        let h = Vec3::new(0.4, 0.2, 0.3);
        let vertices: Vec<Vec3> = (0..8)
            .map(|k| {
                let s = |bit: u32| if k & (1 << bit) != 0 { 1.0 } else { -1.0 };
                Vec3::new(s(0), s(1), s(2)) * h
            })
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
        ];
        let triangles = quads
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .collect();
        let mesh = oriented(vertices, triangles);
        let near: Vec<Vec3> = points(20_000, 1.0)
            .into_iter()
            // Near a corner, offset either way on each axis: inside and outside alike.
            .map(|p| p.signum() * h + 0.03 * (37.0 * p).sin())
            .collect();
        let inside = near.iter().filter(|p| p.abs().cmplt(h).all()).count();
        assert!(inside > near.len() / 20, "{inside} inside");
        agree(&mesh, &near, 0.05, 1.0);
    }

    #[test]
    fn the_grid_answers_as_the_tree_does_near_an_open_sheet() {
        // A wavy 20 x 20 sheet of 800 triangles.
        let n = 21;
        let vertices: Vec<Vec3> = (0..n * n)
            .map(|k| {
                let (i, j) = ((k % n) as f32 / 20.0, (k / n) as f32 / 20.0);
                Vec3::new(i, 0.05 * (6.0 * i).sin() * (4.0 * j).cos(), j)
            })
            .collect();
        let triangles: Vec<[u32; 3]> = (0..20 * 20)
            .flat_map(|q| {
                let (i, j) = ((q % 20) as u32, (q / 20) as u32);
                let a = j * n as u32 + i;
                let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
                [[a, c, b], [b, c, d]]
            })
            .collect();
        let mesh = oriented(vertices, triangles);
        let near: Vec<Vec3> = points(20_000, 0.6)
            .into_iter()
            .map(|p| Vec3::new(p.x + 0.5, 0.1 * p.y, p.z + 0.5))
            .collect();
        agree(&mesh, &near, 0.02, 0.9);
    }

    /// The regression test of a grid that listed a triangle in every cell its grown box spans,
    /// however many: a mesh of 500 large overlapping triangles among ten thousand small
    /// ones, which would list the large ones millions of times, gets no grid, and every query
    /// still finds the right answer (through the tree).
    #[test]
    fn a_mesh_the_grid_would_list_too_often_is_left_to_the_tree() {
        let corners = points(3 * 11_000, 1.0);
        let vertices: Vec<Vec3> = corners
            .chunks(3)
            .enumerate()
            .flat_map(|(k, c)| {
                // Triangles 0..500 span the 10 m box; the rest are 1 mm, near their first corner.
                let (centre, size) = if k < 500 {
                    (Vec3::ZERO, 5.0)
                } else {
                    (c[0], 0.001)
                };
                c.iter().map(move |&p| centre * 5.0 + p * size)
            })
            .collect();
        let triangles: Vec<[u32; 3]> = (0..11_000u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        let mesh = TriMesh::new(vertices, triangles).unwrap();
        let grid = MeshGrid::new(&mesh, 0.01);
        assert!(grid.triangles.is_empty() && grid.boxes.is_empty());
        for p in points(100, 5.0) {
            assert!(matches!(grid.nearest(&mesh, p, 0.01), Nearest::AskTheTree));
        }
    }

    #[test]
    fn a_thick_collider_keeps_its_grid_small() {
        // Thickness of 5 cm against triangles of about 1 cm: cells grow to the reach.
        let (v, f) = octasphere(5, 0.5);
        let mesh = oriented(v, f);
        let grid = MeshGrid::new(&mesh, 0.1);
        // Built (not given up on), and within the entry budget.
        let entries = grid.triangles.len();
        assert!(
            entries > 0 && entries <= ENTRIES_PER_TRIANGLE * 8192,
            "{entries}"
        );
        agree(&mesh, &points(5000, 0.6), 0.1, 0.0);
    }

    #[test]
    fn longer_queries_crowded_cells_and_points_that_are_not_finite_go_to_the_tree() {
        let (v, f) = octasphere(2, 0.5);
        let mesh = oriented(v, f);
        let grid = MeshGrid::new(&mesh, 0.01);
        let on = Vec3::new(0.0, 0.5, 0.0);
        assert!(matches!(
            grid.nearest(&mesh, on, 2.0 * grid.reach),
            Nearest::AskTheTree
        ));
        assert!(matches!(
            grid.nearest(&mesh, Vec3::NAN, 0.01),
            Nearest::AskTheTree
        ));
        assert!(matches!(grid.nearest(&mesh, on, 0.01), Nearest::Found(_)));
        // Far outside the grid: nothing within reach.
        assert!(matches!(
            grid.nearest(&mesh, Vec3::splat(5.0), 0.01),
            Nearest::None
        ));
        // Every triangle at one point: a cell too crowded to scan.
        let fan: Vec<Vec3> = std::iter::once(Vec3::ZERO)
            .chain((0..=100).map(|k| {
                let a = k as f32 * 0.06;
                Vec3::new(a.cos(), 0.0, -a.sin())
            }))
            .collect();
        let spokes: Vec<[u32; 3]> = (1..=100).map(|k| [0, k, k + 1]).collect();
        let fan = oriented(fan, spokes);
        let grid = MeshGrid::new(&fan, 0.01);
        assert!(matches!(
            grid.nearest(&fan, Vec3::new(0.0, 0.001, 0.0), 0.01),
            Nearest::AskTheTree
        ));
    }
}
