//! The model: what a scene compiles to and what the calls between steps change, never a step
//! itself. The validated scene with its run-time settings, the grid, each particle's mass and
//! flags, and the springs with their rest lengths; `topology_version` counts the cuts.

use glam::{DVec3, Vec3};

use std::collections::HashMap;
use std::sync::Arc;

use crate::error::{check_scalar, Bound, Error, Result};
use crate::grid::{Grid, SpringSlot};
use crate::mesh_cloth::{MeshCloth, MeshTopology};
use crate::scene::{Plane, Scene};
use crate::soa::Vec3s;
use crate::springs::Springs;

pub use crate::particles::Particles;

/// How the cloth's particles are joined.
#[derive(Clone, Debug)]
pub enum Topology {
    /// The `nx` x `ny` grid and its 12-neighbour stencil ([`Model::springs`]): the fast path.
    Grid,
    /// A triangle mesh with its springs as an explicit list ([`crate::mesh_cloth`]); the
    /// particles are laid out as one row ([`Model::grid`] is `vertices x 1`) and the stencil
    /// holds no spring.
    Mesh(MeshTopology),
}

/// Where each stable triangle id's corners are: the grid's cells ([`crate::grid::cell_triangle`],
/// two per cell, some not drawn after cuts) or a mesh's triangle list (id = position). What the
/// picking tree keeps to refit and cast without the model.
#[derive(Clone, Debug)]
pub enum TriangleIds {
    Grid(Grid),
    Mesh(Arc<[[u32; 3]]>),
}

impl TriangleIds {
    /// The number of ids, drawn or not.
    pub fn slots(&self) -> usize {
        match self {
            TriangleIds::Grid(grid) => crate::grid::triangle_slots(*grid),
            TriangleIds::Mesh(triangles) => triangles.len(),
        }
    }

    /// The corners of triangle `id`.
    #[inline]
    pub fn corners(&self, id: usize) -> [usize; 3] {
        match self {
            TriangleIds::Grid(grid) => crate::grid::cell_triangle(*grid, id),
            TriangleIds::Mesh(triangles) => triangles[id].map(|q| q as usize),
        }
    }
}

/// A scene compiled into the cloth it describes.
pub struct Model {
    /// The scene, with the run-time settings (integrator, dt, substeps) as they are now.
    pub scene: Scene,
    pub topology: Topology,
    pub grid: Grid,
    pub particles: Particles,
    pub springs: Springs,
    /// Where a stroke crossed each spring it severed: the parameter `t` in `[0, 1]` along the
    /// spring's segment from its anchor, as the cut found it (see
    /// [`crate::cutting::springs_crossing_stroke`]). Springs severed without a stroke (a tear)
    /// have none; the drawn mesh puts their cut at the midpoint. Nothing in a step reads it.
    pub crossings: HashMap<SpringSlot, f32>,
    /// Increments whenever the springs or the particles that make up the cloth change (a cut,
    /// a severed spring, a tear), and with them the triangle list, on the grid and on a mesh.
    pub topology_version: u64,
}

impl Model {
    /// The cloth `scene` describes (validated here), and its particles' starting positions.
    pub fn new(scene: Scene) -> Result<(Model, Vec3s)> {
        let scene = match scene.cloth.garment {
            Some(_) => scene.sewn()?,
            None => scene,
        };
        scene.validate()?;
        let grid = scene.grid();
        if let Some(spec) = &scene.cloth.mesh {
            return Self::new_mesh(MeshCloth::new(spec)?, scene);
        }
        let pos = initial_positions(&scene);
        let springs = Springs::new(grid, &pos);
        let mut particles = Particles::new(grid.len(), scene.particle_mass() as f32);
        for p in scene.cloth.pinned_indices() {
            particles.set_pinned(p, true);
        }
        let model = Model {
            scene,
            topology: Topology::Grid,
            grid,
            particles,
            springs,
            crossings: HashMap::new(),
            topology_version: 0,
        };
        Ok((model, pos))
    }

    /// A mesh cloth: its vertices at rest, their lumped masses, no stencil springs.
    fn new_mesh(mesh: MeshCloth, scene: Scene) -> Result<(Model, Vec3s)> {
        let grid = scene.grid();
        let pos = Vec3s::from_fn(grid.len(), |p| DVec3::from(mesh.rest[p]).as_vec3());
        let mut particles = Particles::new(grid.len(), 1.0);
        for (p, &m) in mesh.masses.iter().enumerate() {
            particles.set_mass(p, m as f32);
        }
        for p in scene.cloth.pinned_indices() {
            particles.set_pinned(p, true);
        }
        let model = Model {
            springs: Springs::none(grid.len()),
            scene,
            topology: Topology::Mesh(MeshTopology::new(mesh)),
            grid,
            particles,
            crossings: HashMap::new(),
            topology_version: 0,
        };
        Ok((model, pos))
    }

    /// The mesh of a mesh cloth; None on the grid.
    pub fn mesh(&self) -> Option<&MeshCloth> {
        self.mesh_topology().map(|topology| &*topology.mesh)
    }

    /// The mesh of a mesh cloth with the tables its cuts read; None on the grid.
    pub fn mesh_topology(&self) -> Option<&MeshTopology> {
        match &self.topology {
            Topology::Grid => None,
            Topology::Mesh(topology) => Some(topology),
        }
    }

    /// Replaces every particle's mass (kg, each finite and > 0, with a finite float32 inverse).
    /// Rejects a bad value, changing nothing.
    pub fn set_masses(&mut self, masses: &[f64]) -> Result<()> {
        let n = self.grid.len();
        if masses.len() != n {
            return Err(Error::value(
                "masses",
                format!("must hold {n} values, got {}", masses.len()),
            ));
        }
        for (p, &m) in masses.iter().enumerate() {
            check_scalar(&format!("masses[{p}]"), m, Bound::Positive)?;
            if (m as f32) == 0.0 || !(1.0 / m as f32).is_finite() {
                return Err(Error::value(
                    format!("masses[{p}]"),
                    format!("must be representable in float32 with a finite inverse, got {m}"),
                ));
            }
        }
        for (p, &m) in masses.iter().enumerate() {
            self.particles.set_mass(p, m as f32);
        }
        Ok(())
    }

    /// Removes particle `p` and its springs; its triangles leave the mesh.
    pub fn cut(&mut self, p: usize) {
        self.particles.cut(p);
        match &mut self.topology {
            Topology::Grid => self.springs.remove_particle(self.grid, p),
            Topology::Mesh(topology) => _ = topology.sever_vertex(p),
        }
        self.topology_version += 1;
    }

    /// Severs the mesh cloth's springs `springs` (indices into its spring list) and the bend
    /// springs that go with them ([`crate::mesh_cloth::topology`]); those already severed are
    /// skipped. Returns how many were live; the topology version moves only if one was. No
    /// particle changes. Does nothing on the grid.
    pub fn sever_mesh(&mut self, springs: &[u32]) -> usize {
        let Topology::Mesh(topology) = &mut self.topology else {
            return 0;
        };
        let severed = topology.sever(springs.iter().copied());
        if severed > 0 {
            self.topology_version += 1;
        }
        severed
    }

    /// [`Model::sever_mesh`] for springs a stroke crossed, each with where it crossed (kept by
    /// the topology for the drawn mesh). A spring listed twice keeps its first crossing.
    pub fn sever_mesh_crossing(&mut self, crossings: &[crate::cutting::MeshCrossing]) -> usize {
        let Topology::Mesh(topology) = &mut self.topology else {
            return 0;
        };
        let severed = topology.sever_crossing(crossings);
        if severed > 0 {
            self.topology_version += 1;
        }
        severed
    }

    /// Severs the springs `slots` (kind, anchor) without a stroke (a tear: the drawn mesh
    /// opens at their midpoints); those already severed are skipped. Returns how many were
    /// live; the topology version moves only if one was. No particle changes, so the cloth's
    /// mass stays exactly what it was.
    pub fn sever(&mut self, slots: &[SpringSlot]) -> usize {
        self.sever_each(slots.iter().map(|&slot| (slot, None)))
    }

    /// [`Model::sever`] for springs a stroke crossed, each with where it crossed (`t` from the
    /// anchor, kept in [`Model::crossings`] for the drawn mesh). A spring listed twice keeps
    /// its first crossing.
    pub fn sever_crossing(&mut self, crossings: &[(SpringSlot, f32)]) -> usize {
        self.sever_each(crossings.iter().map(|&(slot, t)| (slot, Some(t))))
    }

    fn sever_each(&mut self, cuts: impl Iterator<Item = (SpringSlot, Option<f32>)>) -> usize {
        let mut severed = 0;
        for ((kind, anchor), t) in cuts {
            let flag = &mut self.springs.active[kind.index()][anchor];
            if *flag != 0.0 {
                *flag = 0.0;
                severed += 1;
                if let Some(t) = t {
                    self.crossings.insert((kind, anchor), t);
                }
            }
        }
        if severed > 0 {
            self.topology_version += 1;
        }
        severed
    }

    /// Whether triangle `id` is drawn: of the grid's cells, see
    /// [`crate::cutting::triangle_drawn`]; of a mesh, [`MeshTopology::drawn`].
    pub fn triangle_drawn(&self, id: usize) -> bool {
        match &self.topology {
            Topology::Grid => {
                crate::cutting::triangle_drawn(self.grid, &self.springs, &self.particles.alive, id)
            }
            Topology::Mesh(topology) => topology.drawn(&self.particles.alive, id),
        }
    }

    /// The triangles' stable ids and their corners.
    pub fn triangle_ids(&self) -> TriangleIds {
        match &self.topology {
            Topology::Grid => TriangleIds::Grid(self.grid),
            Topology::Mesh(topology) => TriangleIds::Mesh(Arc::clone(&topology.triangles)),
        }
    }

    /// The triangles of the cloth: two per grid cell, less those a cut or a tear runs through
    /// ([`Model::triangle_drawn`]), in the order of their ids ([`crate::grid::cell_triangle`]). What
    /// the renderer draws and what self-collision keeps apart are the same surface.
    /// A mesh cloth's are its mesh's, in their order, less those a cut or a tear opened.
    pub fn triangles(&self) -> Box<dyn Iterator<Item = [u32; 3]> + '_> {
        if let Some(topology) = self.mesh_topology() {
            let alive = &self.particles.alive;
            return Box::new(
                (0..topology.triangles.len())
                    .filter(move |&t| topology.drawn(alive, t))
                    .map(|t| topology.triangles[t]),
            );
        }
        Box::new(
            (0..crate::grid::triangle_slots(self.grid))
                .filter(|&id| self.triangle_drawn(id))
                .map(|id| crate::grid::cell_triangle(self.grid, id).map(|q| q as u32)),
        )
    }

    /// The vertex pairs a garment's seams sew together (each seam spring's ends): one point
    /// once sewn, so self-collision takes them as neighbours. None on the grid.
    pub fn sewn(&self) -> Box<dyn Iterator<Item = [u32; 2]> + '_> {
        match self.mesh() {
            Some(mesh) => Box::new(mesh.seam_pairs()),
            None => Box::new(std::iter::empty()),
        }
    }

    /// The smaller of the two grid spacings at rest, in m; a mesh cloth's mean edge length at
    /// rest (the distance between neighbouring particles, as the grid spacing is).
    pub fn min_spacing(&self) -> f64 {
        if let Some(mesh) = self.mesh() {
            return mesh.mean_edge;
        }
        let size = self.scene.cloth.size;
        let dx = size[0] / (self.grid.nx - 1) as f64;
        let dy = size[1] / (self.grid.ny - 1) as f64;
        dx.min(dy)
    }

    /// The largest substep (s) at which `integrator` is estimated to stay stable
    /// ([`crate::scene::stable_substep`]) with the lightest moving particle's mass, which bounds
    /// the stiffest mode also when masses differ; None when any substep is (the implicit
    /// solvers, no springs, nothing moving).
    pub fn stable_substep(&self, integrator: crate::scene::IntegratorKind) -> Option<f64> {
        let particles = &self.particles;
        let m = (0..self.grid.len())
            .filter(|&p| particles.is_dynamic(p))
            .map(|p| particles.mass[p] as f64)
            .fold(f64::INFINITY, f64::min);
        if !m.is_finite() {
            return None;
        }
        crate::scene::stable_substep(&self.scene, integrator, m)
    }

    /// The stiffness (N/m) of a spring family in the scene.
    pub fn stiffness(&self, family: crate::grid::Family) -> f64 {
        let cloth = &self.scene.cloth;
        match family {
            crate::grid::Family::Structural => cloth.k_structural,
            crate::grid::Family::Shear => cloth.k_shear,
            crate::grid::Family::Bend => cloth.k_bend,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.scene.heap_bytes()
            + self.particles.heap_bytes()
            + self.springs.heap_bytes()
            + self.crossings.capacity() * size_of::<(SpringSlot, f32)>()
            + self.mesh_topology().map_or(0, MeshTopology::heap_bytes)
    }
}

/// The unit vectors `(e_i, e_j)` the cloth's grid starts along.
pub fn plane_axes(plane: Plane) -> (Vec3, Vec3) {
    plane.axes()
}

/// `center + (i/(nx-1) - 1/2) size[0] e1 + (j/(ny-1) - 1/2) size[1] e2`.
fn initial_positions(scene: &Scene) -> Vec3s {
    let grid = scene.grid();
    let cloth = &scene.cloth;
    let (e1, e2) = plane_axes(cloth.plane);
    let (e1, e2) = (e1.as_dvec3(), e2.as_dvec3());
    let center = DVec3::from(cloth.center);
    Vec3s::from_fn(grid.len(), |p| {
        let (i, j) = grid.coords(p);
        let u = i as f64 / (grid.nx - 1) as f64 - 0.5;
        let v = j as f64 / (grid.ny - 1) as f64 - 0.5;
        (center + u * cloth.size[0] * e1 + v * cloth.size[1] * e2).as_vec3()
    })
}
