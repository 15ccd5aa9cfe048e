//! What is read off a model and a state without changing them: energy, spring strain, and
//! the mesh (triangles and vertex normals), the last two kept in a cache until the topology or
//! the state changes. Nothing here runs inside a step.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::grid::{cell_triangle, Family, Grid};
use crate::model::{plane_axes, Model};
use crate::parallel::chunk_len;
use crate::soa::Vec3s;
use crate::state::State;

/// Kinetic, gravitational potential and elastic energy in J.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    pub kinetic: f64,
    /// `-sum m g . x`, zero at the origin.
    pub gravitational: f64,
    /// `sum k (l - L)^2 / 2` over the springs of the active families.
    pub elastic: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravitational + self.elastic
    }
}

/// The energy of `state`, in f64: bitwise the same for any thread count and any call.
pub fn energy(model: &Model, state: &State) -> Energy {
    energy_of(model, &state.kin)
}

/// The energy of positions and velocities `kin`, as [`energy`].
pub fn energy_of(model: &Model, kin: &crate::state::Kinematics) -> Energy {
    let g = DVec3::from(model.scene.gravity);
    let (pos, vel, particles) = (&kin.pos, &kin.vel, &model.particles);
    let [kinetic, gravitational] = fixed_sum(model.grid.len(), |p| {
        if !particles.alive[p] {
            return [0.0, 0.0];
        }
        // In f64 before squaring: a finite float32 speed can square past float32's range.
        let m = particles.mass[p] as f64;
        [
            0.5 * m * vel.get(p).as_dvec3().length_squared(),
            -m * g.dot(pos.get(p).as_dvec3()),
        ]
    });
    let mut elastic = model.mesh().map_or(0.0, |mesh| mesh.elastic_energy(pos));
    for family in Family::ALL {
        let k = model.stiffness(family);
        if k == 0.0 {
            continue;
        }
        for kind in family.kinds() {
            model.springs.for_each(model.grid, kind, |a, b, rest| {
                let l = (pos.get(b).as_dvec3() - pos.get(a).as_dvec3()).length();
                let stretch = l - rest as f64;
                elastic += 0.5 * k * stretch * stretch;
            });
        }
    }
    Energy {
        kinetic,
        gravitational,
        elastic,
    }
}

/// Particles per partial sum of [`fixed_sum`].
const SUM_CHUNK: usize = 4096;

/// `sum over p < n of term(p)`, per component, in f64 and bitwise the same for any number of
/// threads and any call: the partial sums are over fixed chunks and added in chunk order (an
/// adaptive parallel reduction splits where the scheduler happens to, and float addition is
/// not associative).
fn fixed_sum<const K: usize>(n: usize, term: impl Fn(usize) -> [f64; K] + Sync) -> [f64; K] {
    let partials: Vec<[f64; K]> = (0..n.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut sum = [0.0; K];
            for p in c * SUM_CHUNK..((c + 1) * SUM_CHUNK).min(n) {
                for (s, t) in sum.iter_mut().zip(term(p)) {
                    *s += t;
                }
            }
            sum
        })
        .collect();
    partials.into_iter().fold([0.0; K], |mut total, part| {
        for (s, t) in total.iter_mut().zip(part) {
            *s += t;
        }
        total
    })
}

/// Per particle, the largest relative stretch `l / L - 1` of the live springs of the active
/// families that touch it (0 for a particle with none).
pub fn spring_strain(model: &Model, state: &State) -> Vec<f32> {
    if let Some(mesh) = model.mesh() {
        return mesh.vertex_strain(&state.kin.pos);
    }
    let mut strain = vec![0.0f32; model.grid.len()];
    let pos = &state.kin.pos;
    for family in Family::ALL
        .into_iter()
        .filter(|&f| model.stiffness(f) > 0.0)
    {
        for kind in family.kinds() {
            model.springs.for_each(model.grid, kind, |a, b, rest| {
                if rest > 0.0 {
                    let s = (pos.get(b) - pos.get(a)).length() / rest - 1.0;
                    strain[a] = strain[a].max(s);
                    strain[b] = strain[b].max(s);
                }
            });
        }
    }
    strain
}

/// The mesh derived from a model and a state, computed on first request and kept until the
/// versions it was made from change.
#[derive(Default)]
pub struct Mesh {
    triangles: Vec<[u32; 3]>,
    /// The topology version `triangles` was made for.
    triangles_for: Option<u64>,
    normals: Vec3s,
    /// The `(state, topology)` versions `normals` were made for.
    normals_for: Option<(u64, u64)>,
}

impl Mesh {
    /// The triangles of the live cloth, two per grid cell, less those a cut or a tear runs
    /// through ([`Model::triangle_drawn`]); in the order of their ids ([`cell_triangle`]).
    pub fn triangles(&mut self, model: &Model) -> &[[u32; 3]] {
        if self.triangles_for != Some(model.topology_version) {
            self.triangles.clear();
            self.triangles.extend(model.triangles());
            self.triangles_for = Some(model.topology_version);
        }
        &self.triangles
    }

    /// Unit vertex normals (area-weighted average of the incident live triangles). A particle
    /// with no live triangle gets `e_i x e_j` of the starting plane.
    pub fn normals(&mut self, model: &Model, state: &State) -> &Vec3s {
        let now = (state.version, model.topology_version);
        if self.normals_for != Some(now) {
            let (e1, e2) = plane_axes(model.scene.cloth.plane);
            let fallback = e1.cross(e2);
            let (grid, pos) = (model.grid, &state.kin.pos);
            if let Some(mesh) = model.mesh() {
                self.normals = mesh.vertex_normals(model.triangles(), pos, Vec3::Y);
                self.normals_for = Some(now);
                return &self.normals;
            }
            let drawn = |id: usize| model.triangle_drawn(id);
            let normals = &mut self.normals;
            if normals.len() != grid.len() {
                *normals = Vec3s::zeros(grid.len());
            }
            let chunk = chunk_len(grid.len());
            normals
                .par_chunks_mut(chunk)
                .enumerate()
                .for_each(|(c, mut out)| {
                    for i in 0..out.len() {
                        let n = vertex_normal(grid, pos, &drawn, c * chunk + i);
                        out.set(i, n.try_normalize().unwrap_or(fallback));
                    }
                });
            self.normals_for = Some(now);
        }
        &self.normals
    }

    pub fn heap_bytes(&self) -> usize {
        self.normals.heap_bytes() + self.triangles.capacity() * size_of::<[u32; 3]>()
    }
}

/// Sum of the area-weighted normals of the drawn triangles around particle `p`; see
/// [`cell_triangle`] for the split of each cell into `(a, b, d)` (id `2 cell`) and `(a, d, c)`
/// (id `2 cell + 1`).
fn vertex_normal(grid: Grid, pos: &Vec3s, drawn: &impl Fn(usize) -> bool, p: usize) -> Vec3 {
    let (i, j) = grid.coords(p);
    let mut sum = Vec3::ZERO;
    let mut add = |id: usize| {
        if drawn(id) {
            let [a, b, c] = cell_triangle(grid, id).map(|q| pos.get(q));
            sum += (b - a).cross(c - a);
        }
    };
    // The four cells with p as a corner, by the cell's lower-left corner (ci, cj).
    for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        if i < di || j < dj || i - di + 1 >= grid.nx || j - dj + 1 >= grid.ny {
            continue;
        }
        let a = grid.index(i - di, j - dj);
        let (b, c) = (a + 1, a + grid.nx);
        let cell = (j - dj) * (grid.nx - 1) + (i - di);
        if p != c {
            add(2 * cell); // (a, b, d): p is a, b or d
        }
        if p != b {
            add(2 * cell + 1); // (a, d, c): p is a, d or c
        }
    }
    sum
}
