//! What shape a collider is, and the two questions every shape answers: the surface point
//! nearest a particle, and where a path first enters the solid.
//!
//! A mesh asks the same two questions: the nearest point within `thickness` plus the particle's
//! path length over the substep (a particle further than that from the surface cannot have
//! touched it, so the query stays local however large the mesh), answered from a uniform grid
//! over the triangles when it is short (`collisions::mesh`, exact) and by parry's `TriMesh` BVH
//! when not; and a ray cast through the BVH that ignores back faces, for the entry point. A
//! closed mesh tells inside from outside by the angle-weighted pseudo-normals
//! (`TriMeshFlags::ORIENTED`); an open one is a one-sided sheet: only the side its triangles
//! face pushes, a particle that crosses it from the front within a substep is stopped where it
//! crossed, one behind it within `thickness` is put `thickness` in front, and one further behind
//! is free.

use glam::{DVec3, Vec3};
use parry3d::query::{PointQuery, PointQueryWithLocation, Ray, RayCast, RayCullingMode};
use parry3d::shape::{
    Ball, Capsule, Cuboid, Cylinder, HalfSpace, TopoFace, TopoHalfEdge, TopoVertex, TriMesh,
    TriMeshFlags,
};

use crate::collisions::mesh::{MeshGrid, Nearest};
use crate::scene::{is_closed, ColliderSpec, ShapeKind};

/// A triangle mesh, whether it is closed (a solid) or open (a one-sided sheet), and the grid
/// that answers its short nearest-point queries.
pub(super) struct MeshShape {
    mesh: TriMesh,
    closed: bool,
    grid: MeshGrid,
}

/// A collider's shape in its own frame.
pub(super) enum Geometry {
    Ball(Ball),
    Cuboid(Cuboid),
    Capsule(Capsule),
    Cylinder(Cylinder),
    HalfSpace(HalfSpace),
    Mesh(Box<MeshShape>),
}

/// The surface point nearest a local point, whether the point is inside, and the normal to use
/// where the point is on the surface (no direction to it).
pub(super) struct Projection {
    pub(super) point: Vec3,
    pub(super) inside: bool,
    pub(super) fallback: Vec3,
}

impl Geometry {
    /// The shape of a validated spec, and the radius of a ball about its frame's origin
    /// holding it.
    pub(super) fn of(s: &ColliderSpec) -> (Geometry, f32) {
        let r = s.radius.unwrap_or(0.0) as f32;
        let hh = s.half_height.unwrap_or(0.0) as f32;
        match s.shape {
            ShapeKind::Sphere => (Geometry::Ball(Ball::new(r)), r),
            ShapeKind::Box => {
                let h = DVec3::from(s.half_extents.unwrap_or([0.0; 3])).as_vec3();
                (Geometry::Cuboid(Cuboid::new(h)), h.length())
            }
            ShapeKind::Capsule => (Geometry::Capsule(Capsule::new_y(hh, r)), hh + r),
            ShapeKind::Cylinder => (Geometry::Cylinder(Cylinder::new(hh, r)), hh.hypot(r)),
            ShapeKind::Plane => (Geometry::HalfSpace(HalfSpace::new(Vec3::Y)), 0.0),
            ShapeKind::Mesh => mesh_geometry(s),
        }
    }

    /// Bytes a mesh holds on the heap (its triangles, parry's tree, normals and topology, and
    /// the grid); nothing for the other shapes.
    pub(super) fn heap_bytes(&self) -> usize {
        let Geometry::Mesh(m) = self else {
            return 0;
        };
        let mesh = &m.mesh;
        let normals = mesh.pseudo_normals().map_or(0, |p| {
            p.vertices_pseudo_normal.len() * size_of::<Vec3>()
                + p.edges_pseudo_normal.len() * size_of::<[Vec3; 3]>()
        });
        let topology = mesh.topology().map_or(0, |t| {
            t.vertices.len() * size_of::<TopoVertex>()
                + t.faces.len() * size_of::<TopoFace>()
                + t.half_edges.len() * size_of::<TopoHalfEdge>()
        });
        size_of_val(mesh.vertices())
            + size_of_val(mesh.indices())
            + mesh.bvh().heap_memory_size()
            + normals
            + topology
            + m.grid.heap_bytes()
    }

    /// The nearest surface point to `local`; a mesh answers only within `max_dist` of it.
    #[inline]
    pub(super) fn project(&self, local: Vec3, max_dist: f32) -> Option<Projection> {
        // `solid = false`: a point inside gets the nearest boundary point, not itself. The
        // direction from the centre is outward on every convex shape here.
        let convex = |p: parry3d::query::PointProjection| Projection {
            point: p.point,
            inside: p.is_inside,
            fallback: local.normalize_or(Vec3::Y),
        };
        Some(match self {
            Geometry::Ball(s) => convex(s.project_local_point(local, false)),
            Geometry::Cuboid(s) => convex(s.project_local_point(local, false)),
            Geometry::Capsule(s) => convex(s.project_local_point(local, false)),
            Geometry::Cylinder(s) => convex(s.project_local_point(local, false)),
            Geometry::HalfSpace(s) => Projection {
                fallback: Vec3::Y,
                ..convex(s.project_local_point(local, false))
            },
            Geometry::Mesh(m) => {
                // Either way, the projection's `subshape` is the triangle it lies on.
                let p = match m.grid.nearest(&m.mesh, local, max_dist) {
                    Nearest::Found(projection) => projection,
                    Nearest::None => return None,
                    Nearest::AskTheTree => {
                        m.mesh
                            .project_local_point_and_get_location_with_max_dist(
                                local, false, max_dist,
                            )?
                            .0
                    }
                };
                Projection {
                    point: p.point,
                    inside: p.is_inside,
                    fallback: m.mesh.triangle(p.subshape).normal().unwrap_or(Vec3::Y),
                }
            }
        })
    }

    /// Whether only one side pushes and the inside is no solid: an open mesh.
    #[inline]
    pub(super) fn one_sided(&self) -> bool {
        matches!(self, Geometry::Mesh(m) if !m.closed)
    }

    /// Whether faces meet at edges (a box, a cylinder's caps and side, a mesh): the face nearest
    /// a point inside may then be one the point never came near. A ball's and a capsule's
    /// surfaces turn smoothly, and their nearest point is where a shallow contact is.
    #[inline]
    pub(super) fn has_edges(&self) -> bool {
        matches!(
            self,
            Geometry::Cuboid(_) | Geometry::Cylinder(_) | Geometry::Mesh(_)
        )
    }

    /// Where the segment `from + t d`, `t` in `[0, 1]`, first meets the solid shape, and the
    /// outward normal there; `t = 0` when `from` is inside.
    #[inline]
    pub(super) fn entry(&self, from: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
        let ray = Ray::new(from, d);
        let hit = match self {
            Geometry::Ball(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Cuboid(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Capsule(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Cylinder(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::HalfSpace(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            // Front faces only: where the path entered the solid (or crossed the sheet's
            // pushing side); leaving through a back face is no contact.
            Geometry::Mesh(m) => {
                m.mesh
                    .cast_local_ray_with_culling(&ray, 1.0, RayCullingMode::IgnoreBackfaces)
            }
        };
        hit.map(|h| (h.time_of_impact, h.normal))
    }
}

/// How far beyond the thickness a particle may travel relative to a mesh in a substep (m) and
/// still have its nearest-point query answered from the mesh's grid (the grid's reach is this plus
/// twice the thickness). 2 mm is 4 m/s at a 0.5 ms substep; faster particles are answered by
/// the BVH, exactly, only slower, and a longer reach would make every cell's list longer.
const MESH_GRID_TRAVEL: f32 = 0.002;

/// The triangle mesh of a validated `mesh` spec, and the radius of a ball about its frame's
/// origin holding it.
fn mesh_geometry(s: &ColliderSpec) -> (Geometry, f32) {
    let vertices: Vec<Vec3> = s
        .vertices
        .iter()
        .flatten()
        .map(|&v| DVec3::from(v).as_vec3())
        .collect();
    let triangles: Vec<[u32; 3]> = s
        .triangles
        .iter()
        .flatten()
        .map(|t| t.map(|k| k as u32))
        .collect();
    let closed = is_closed("mesh", s.vertices.as_deref().unwrap_or(&[]), &triangles)
        .expect("a validated mesh is wound consistently");
    let bound = vertices.iter().map(|v| v.length()).fold(0.0, f32::max);
    // ORIENTED: the pseudo-normals of the inside test; merged duplicates, so that a mesh with
    // one vertex per corner has shared edges and vertices to average them over.
    let flags = TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES;
    let mesh =
        TriMesh::with_flags(vertices, triangles, flags).expect("a validated mesh has triangles");
    let grid = MeshGrid::new(&mesh, 2.0 * s.thickness as f32 + MESH_GRID_TRAVEL);
    (
        Geometry::Mesh(Box::new(MeshShape { mesh, closed, grid })),
        bound,
    )
}
