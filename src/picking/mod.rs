//! Picking: what a ray hits on the cloth, a particle or a triangle. The [`Picker`] owns the
//! picking trees and answers queries on a model and a state; the ray tests and the brute-force
//! scans are in `ray.rs`, the trees in `bvh.rs`.
//!
//! Everything here is built on request and cached: a step never pays for it. The caches carry
//! the state's and the model's versions they were last brought up to date with:
//!
//! - no tree yet: the first query builds it (`O(n log n)`);
//! - the cloth moved: the next query moves every leaf box and refits the tree (`O(n)`, no
//!   rebuild);
//! - particles were cut: their leaves are removed from the tree (`O(log n)` each; the tree is
//!   not rebuilt). A cut made by a query (`cut_ray`, `cut_stroke`) removes the leaves at once
//!   and, since a cut moves nothing, spares the next query a refit ([`Picker::after_cut`]);
//!   after a cut made elsewhere the next query finds the dead particles in an `O(n)` scan;
//! - springs were severed (`sever_stroke`, tearing): no particle died, so the particle tree
//!   keeps every leaf; the triangle tree drops the triangles no longer drawn
//!   ([`Model::triangle_drawn`]) in one pass over its leaf flags at the next query, without a
//!   rebuild.
//!
//! The particle tree and the triangle tree are kept separately, so picking particles never
//! pays for the triangles and the other way round.
//!
//! A refit reads every position and rewrites the tree, so one query after the cloth moved is
//! cheaper without the tree: a straight scan of the positions gives the same answer (bit for
//! bit). [`PickStrategy::Auto`], the default, therefore scans for the first query on a new
//! state and refits only when a second query comes on the same state (a cut stroke of
//! [`STROKE_TREE_MIN_RAYS`] rays or more refits at once). docs/picking.md has the measurements.

mod bvh;
pub mod ray;

/// Where the triangle ids live (re-exported: picking is where they are used most).
pub use crate::grid::{cell_triangle, triangle_slots};
pub use bvh::{ParticleBvh, TriangleBvh};
pub use ray::{
    hit_particle, pick_particle_brute_force, pick_particle_scan, pick_triangle_brute_force,
    pick_triangle_brute_force_where, pick_triangle_scan, pick_triangle_scan_where, ray_aabb,
    ray_triangle, ParticleHit, Ray, TriangleHit,
};

use crate::error::{Error, Result};
use crate::grid::triangle_alive;
use crate::model::Model;
use crate::state::State;

/// How many particle queries a caller makes on one state: with many (a cut stroke), building
/// the particle tree pays off at once under [`PickStrategy::Auto`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Queries {
    One,
    Many,
}

/// Under [`PickStrategy::Auto`], a cut stroke of at least this many rays refits the particle
/// tree and queries it; a shorter one scans for each ray. A refit costs a few scans
/// (docs/picking.md), a tree query almost nothing.
pub const STROKE_TREE_MIN_RAYS: usize = 5;

/// How `pick`, `pick_triangle` and the cuts find what a ray hits. All three give the same
/// answer; they differ in cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PickStrategy {
    /// A scan for the first query on each new state of the cloth (`O(n)`, cheaper than a
    /// refit), the tree (refitted, `O(n)` once, then `O(log n)` per query) from the second
    /// query on the same state, and for cut strokes of [`STROKE_TREE_MIN_RAYS`] rays or more.
    #[default]
    Auto,
    /// Always the tree, refitted after every move.
    Bvh,
    /// Always a scan; no tree is ever built.
    Scan,
}

impl PickStrategy {
    pub const ALL: [PickStrategy; 3] = [PickStrategy::Auto, PickStrategy::Bvh, PickStrategy::Scan];

    pub fn name(self) -> &'static str {
        match self {
            PickStrategy::Auto => "auto",
            PickStrategy::Bvh => "bvh",
            PickStrategy::Scan => "scan",
        }
    }

    pub fn by_name(name: &str) -> Result<PickStrategy> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|s| s.name()).collect();
                Error::value(
                    "pick_strategy",
                    format!("must be one of {names:?}, got {name:?}"),
                )
            })
    }
}

/// Counts of the work done on the picking trees, to check that they are lazy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BvhStats {
    /// Particle queries answered by a scan instead of the tree.
    pub particle_scans: u64,
    pub particle_builds: u64,
    pub particle_refits: u64,
    /// Leaves removed from the particle tree after cuts.
    pub particle_removals: u64,
    pub triangle_scans: u64,
    pub triangle_builds: u64,
    pub triangle_refits: u64,
    pub triangle_removals: u64,
}

/// A tree and the `(state, topology)` versions it was last brought up to date with.
struct Cached<T> {
    tree: T,
    versions: (u64, u64),
}

/// The picking trees, built on request, and the picking settings.
#[derive(Default)]
pub struct Picker {
    /// `None`: half the smaller grid spacing.
    radius: Option<f32>,
    strategy: PickStrategy,
    particles: Option<Cached<ParticleBvh>>,
    triangles: Option<Cached<TriangleBvh>>,
    /// The triangles whose corners are alive, severed or not: the material a live stroke
    /// names ([`Picker::material_triangles`]).
    material: Option<Cached<TriangleBvh>>,
    /// Stable triangle id -> position in `Simulation::triangles()`, for a topology version.
    triangle_rank: Option<(u64, Vec<u32>)>,
    /// Versions of the last particle / triangle scan.
    particle_scanned_at: Option<(u64, u64)>,
    triangle_scanned_at: Option<(u64, u64)>,
    stats: BvhStats,
}

fn versions(model: &Model, state: &State) -> (u64, u64) {
    (state.version, model.topology_version)
}

impl Picker {
    /// Half-size in m of the box around each particle that a particle query tests the ray
    /// against. Defaults to half the smaller grid spacing (a mesh's mean edge), so that
    /// neighbouring boxes just touch.
    pub fn radius(&self, model: &Model) -> f32 {
        self.radius
            .unwrap_or_else(|| (0.5 * model.min_spacing()) as f32)
    }

    /// The radius if one was set (None: the default).
    pub fn radius_setting(&self) -> Option<f32> {
        self.radius
    }

    /// Sets the pick radius (m, finite and > 0). The particle tree is refitted at the next
    /// query, not rebuilt.
    pub fn set_radius(&mut self, radius: f64) -> Result<()> {
        let r = radius as f32;
        if !(radius.is_finite() && r.is_finite() && r > 0.0) {
            return Err(Error::value(
                "pick_radius",
                format!("must be a finite number > 0 within float32 range, got {radius}"),
            ));
        }
        self.radius = Some(r);
        Ok(())
    }

    pub fn strategy(&self) -> PickStrategy {
        self.strategy
    }

    pub fn set_strategy(&mut self, strategy: PickStrategy) {
        self.strategy = strategy;
    }

    /// Work done on the picking trees so far.
    pub fn stats(&self) -> BvhStats {
        self.stats
    }

    /// The live particle whose box the ray enters first, one of `queries` on this state.
    pub fn particle(
        &mut self,
        model: &Model,
        state: &State,
        ray: &Ray,
        queries: Queries,
    ) -> Option<ParticleHit> {
        let radius = self.radius(model);
        if !self.use_particle_tree(model, state, queries) {
            self.stats.particle_scans += 1;
            return pick_particle_scan(ray, &state.kin.pos, &model.particles.alive, radius);
        }
        self.sync_particle_tree(model, state);
        self.particles.as_ref()?.tree.cast(ray, &state.kin.pos)
    }

    /// The live triangle the ray hits first, its `index` the position in the triangle list.
    pub fn triangle(&mut self, model: &Model, state: &State, ray: &Ray) -> Option<TriangleHit> {
        let mut hit = if self.use_triangle_tree(model, state) {
            self.sync_triangle_tree(model, state);
            self.triangles.as_ref()?.tree.cast(ray, &state.kin.pos)?
        } else {
            self.stats.triangle_scans += 1;
            match model.mesh_topology() {
                None => pick_triangle_scan_where(ray, model.grid, &state.kin.pos, |id| {
                    model.triangle_drawn(id)
                })?,
                // A mesh has no rows to bound in strips: every triangle is tested.
                Some(topology) => pick_triangle_brute_force_where(
                    ray,
                    &state.kin.pos,
                    &topology.triangles,
                    |id| model.triangle_drawn(id),
                )?,
            }
        };
        hit.index = self.triangle_rank(model, hit.index);
        Some(hit)
    }

    /// For each of `rays`, the nearest of the triangles whose corners are all alive, severed
    /// or not (a ray over a slit still names the material under it), `index` its stable id (a
    /// mesh's position in its list, a grid cell's [`cell_triangle`]): the same answer as
    /// testing each of them ([`pick_triangle_brute_force_where`] with that filter on a mesh,
    /// [`pick_triangle_scan`] on the grid), bit for bit: the tree's leaves are those
    /// triangles, its search the one [`Picker::triangle`] uses.
    ///
    /// Under [`PickStrategy::Auto`] a batch of [`STROKE_TREE_MIN_RAYS`] rays or more, or one on
    /// the state the tree was last fitted to, uses the tree (kept between calls: refitted
    /// once when the cloth moved, `O(n)`, and stripped of the triangles whose corners died);
    /// fewer rays test the triangles, cheaper than a refit.
    pub fn material_triangles(
        &mut self,
        model: &Model,
        state: &State,
        rays: &[Ray],
    ) -> Vec<Option<TriangleHit>> {
        let (grid, pos, alive) = (model.grid, &state.kin.pos, &model.particles.alive);
        let topology = model.mesh_topology();
        let material = |t: usize| match topology {
            Some(topology) => topology.triangles[t].iter().all(|&v| alive[v as usize]),
            None => triangle_alive(grid, alive, t),
        };
        let now = versions(model, state);
        let tree = match self.strategy {
            PickStrategy::Bvh => true,
            PickStrategy::Scan => false,
            PickStrategy::Auto => {
                rays.len() >= STROKE_TREE_MIN_RAYS
                    || self.material.as_ref().is_some_and(|c| c.versions == now)
            }
        };
        if !tree {
            self.stats.triangle_scans += rays.len() as u64;
            return (rays.iter())
                .map(|ray| match topology {
                    Some(topology) => {
                        pick_triangle_brute_force_where(ray, pos, &topology.triangles, material)
                    }
                    None => pick_triangle_scan(ray, grid, pos, alive),
                })
                .collect();
        }
        let cache = match &mut self.material {
            None => {
                self.stats.triangle_builds += 1;
                let tree = TriangleBvh::build_where(model.triangle_ids(), pos, material);
                self.material.insert(Cached {
                    tree,
                    versions: now,
                })
            }
            Some(cache) => {
                if cache.versions.1 != now.1 {
                    // Particles only ever leave: a dead corner's triangles leave the tree.
                    self.stats.triangle_removals += cache.tree.remove_undrawn(material) as u64;
                }
                if cache.versions.0 != now.0 {
                    cache.tree.refit(pos);
                    self.stats.triangle_refits += 1;
                }
                cache.versions = now;
                cache
            }
        };
        rays.iter().map(|ray| cache.tree.cast(ray, pos)).collect()
    }

    /// After particle `p` was cut by a query: its leaves leave the trees that were up to date
    /// (`before`), which stay valid without a refit since a cut moves nothing.
    pub fn after_cut(&mut self, model: &Model, state: &State, p: usize, before: (u64, u64)) {
        let after = versions(model, state);
        if let Some(cache) = &mut self.particles {
            if cache.versions == before {
                self.stats.particle_removals += cache.tree.remove(p) as u64;
                cache.versions = after;
            }
        }
        if let Some(cache) = &mut self.triangles {
            if cache.versions == before {
                self.stats.triangle_removals += cache.tree.remove_around(p) as u64;
                cache.versions = after;
            }
        }
    }

    /// The versions a cut's [`Picker::after_cut`] compares with.
    pub fn versions(model: &Model, state: &State) -> (u64, u64) {
        versions(model, state)
    }

    /// Drops the trees and scan stamps (after a panic, when they may be half-built); the next
    /// query builds them again. Settings and statistics stay.
    pub fn drop_caches(&mut self) {
        self.particles = None;
        self.triangles = None;
        self.material = None;
        self.triangle_rank = None;
        self.particle_scanned_at = None;
        self.triangle_scanned_at = None;
    }

    /// Heap memory of the trees and the triangle ranks, in bytes.
    pub fn heap_bytes(&self) -> usize {
        self.particles.as_ref().map_or(0, |c| c.tree.heap_bytes())
            + self.triangles.as_ref().map_or(0, |c| c.tree.heap_bytes())
            + self.material.as_ref().map_or(0, |c| c.tree.heap_bytes())
            + self
                .triangle_rank
                .as_ref()
                .map_or(0, |(_, rank)| rank.capacity() * size_of::<u32>())
    }

    fn use_particle_tree(&mut self, model: &Model, state: &State, queries: Queries) -> bool {
        let now = versions(model, state);
        let radius = self.radius(model);
        match self.strategy {
            PickStrategy::Bvh => true,
            PickStrategy::Scan => false,
            PickStrategy::Auto => {
                let synced = self
                    .particles
                    .as_ref()
                    .is_some_and(|c| c.versions == now && c.tree.radius() == radius);
                let again = self.particle_scanned_at == Some(now);
                self.particle_scanned_at = Some(now);
                synced || again || queries == Queries::Many
            }
        }
    }

    fn use_triangle_tree(&mut self, model: &Model, state: &State) -> bool {
        let now = versions(model, state);
        match self.strategy {
            PickStrategy::Bvh => true,
            PickStrategy::Scan => false,
            PickStrategy::Auto => {
                let synced = self.triangles.as_ref().is_some_and(|c| c.versions == now);
                let again = self.triangle_scanned_at == Some(now);
                self.triangle_scanned_at = Some(now);
                synced || again
            }
        }
    }

    fn sync_particle_tree(&mut self, model: &Model, state: &State) {
        let radius = self.radius(model);
        let (sv, tv) = versions(model, state);
        let (pos, alive) = (&state.kin.pos, &model.particles.alive);
        match &mut self.particles {
            None => {
                self.particles = Some(Cached {
                    tree: ParticleBvh::build(pos, alive, radius),
                    versions: (sv, tv),
                });
                self.stats.particle_builds += 1;
            }
            Some(cache) => {
                if cache.versions.1 != tv {
                    self.stats.particle_removals += cache.tree.remove_dead(alive) as u64;
                    cache.versions.1 = tv;
                }
                if cache.versions.0 != sv || cache.tree.radius() != radius {
                    cache.tree.refit(pos, radius);
                    self.stats.particle_refits += 1;
                    cache.versions.0 = sv;
                }
            }
        }
    }

    fn sync_triangle_tree(&mut self, model: &Model, state: &State) {
        let (sv, tv) = versions(model, state);
        let pos = &state.kin.pos;
        let drawn = |id: usize| model.triangle_drawn(id);
        match &mut self.triangles {
            None => {
                self.triangles = Some(Cached {
                    tree: TriangleBvh::build_where(model.triangle_ids(), pos, drawn),
                    versions: (sv, tv),
                });
                self.stats.triangle_builds += 1;
            }
            Some(cache) => {
                if cache.versions.1 != tv {
                    self.stats.triangle_removals += cache.tree.remove_undrawn(drawn) as u64;
                    cache.versions.1 = tv;
                }
                if cache.versions.0 != sv {
                    cache.tree.refit(pos);
                    self.stats.triangle_refits += 1;
                    cache.versions.0 = sv;
                }
            }
        }
    }

    /// Position of live triangle `id` in the triangle list: the number of live ids before it
    /// (the list is built in id order). The table is rebuilt once per topology change.
    fn triangle_rank(&mut self, model: &Model, id: usize) -> usize {
        let tv = model.topology_version;
        if self.triangle_rank.as_ref().is_none_or(|(v, _)| *v != tv) {
            let mut next = 0u32;
            let rank = (0..model.triangle_ids().slots())
                .map(|t| {
                    let r = next;
                    if model.triangle_drawn(t) {
                        next += 1;
                    }
                    r
                })
                .collect();
            self.triangle_rank = Some((tv, rank));
        }
        self.triangle_rank.as_ref().expect("just built").1[id] as usize
    }
}
