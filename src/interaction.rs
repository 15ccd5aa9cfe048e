//! Interaction with the cloth: picking particles and triangles with a ray, dragging a
//! particle, cutting the cloth along a mouse stroke.
//!
//! Everything here is built on request and cached: a step never pays for it. The caches
//! compare [`Simulation::state_version`] and [`Simulation::topology_version`] with the versions
//! they were last brought up to date with:
//!
//! - no tree yet: the first query builds it (`O(n log n)`);
//! - the cloth moved: the next query moves every leaf box and refits the tree (`O(n)`, no
//!   rebuild);
//! - particles were cut: their leaves are removed from the tree (`O(log n)` each; the tree is
//!   not rebuilt). A cut made here (`cut_ray`, `cut_stroke`) removes the leaves at once and,
//!   since a cut moves nothing, spares the next query a refit; after a cut made elsewhere
//!   (`Simulation::cut`) the next query finds the dead particles in an `O(n)` scan.
//!
//! The particle tree and the triangle tree are kept separately, so picking particles never
//! pays for the triangles and the other way round.
//!
//! A refit reads every position and rewrites the tree, so one query after the cloth moved is
//! cheaper without the tree: a straight scan of the positions gives the same answer (bit for
//! bit). [`PickStrategy::Auto`], the default, therefore scans for the first query on a new
//! state and refits only when a second query comes on the same state (a cut stroke of five
//! rays or more refits at once). docs/picking.md has the measurements.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::picking::{
    cell_triangle, pick_particle_scan, pick_triangle_scan, triangle_slots, ParticleBvh,
    ParticleHit, Ray, TriangleBvh, TriangleHit,
};
use crate::Simulation;

/// Under [`PickStrategy::Auto`], a cut stroke of at least this many rays refits the particle
/// tree and queries it; a shorter one scans for each ray. A refit costs about 4.5 scans
/// (docs/picking.md), a tree query almost nothing.
pub const STROKE_TREE_MIN_RAYS: usize = 5;

/// How `pick`, `pick_triangle` and the cuts find what a ray hits. All three give the same
/// answer; they differ in cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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
    pub const NAMES: [&'static str; 3] = ["auto", "bvh", "scan"];

    pub fn name(self) -> &'static str {
        match self {
            PickStrategy::Auto => "auto",
            PickStrategy::Bvh => "bvh",
            PickStrategy::Scan => "scan",
        }
    }

    pub fn by_name(name: &str) -> Result<PickStrategy> {
        match name {
            "auto" => Ok(PickStrategy::Auto),
            "bvh" => Ok(PickStrategy::Bvh),
            "scan" => Ok(PickStrategy::Scan),
            _ => Err(Error::value(
                "pick_strategy",
                format!("must be one of {:?}, got {name:?}", Self::NAMES),
            )),
        }
    }
}

/// A tree and the versions of the simulation it was last brought up to date with.
struct Cached<T> {
    tree: T,
    state_version: u64,
    topology_version: u64,
}

/// A grabbed particle and the pin state to restore on release.
#[derive(Clone, Copy, Debug)]
struct Grab {
    index: usize,
    was_pinned: bool,
    /// The kinematic target it had before, if any.
    previous_target: Option<Vec3>,
}

/// Counts of the work done on the picking trees, to check that they are lazy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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

/// Cached picking structures and the current grab; empty until a query asks for them.
#[derive(Default)]
pub struct InteractionState {
    /// `None`: half the smaller grid spacing.
    pick_radius: Option<f32>,
    particles: Option<Cached<ParticleBvh>>,
    triangles: Option<Cached<TriangleBvh>>,
    /// Stable triangle id -> position in `Simulation::triangles()`, for `topology_version`.
    triangle_rank: Option<(u64, Vec<u32>)>,
    grab: Option<Grab>,
    strategy: PickStrategy,
    /// `(state_version, topology_version)` of the last particle / triangle scan.
    particle_scanned_at: Option<(u64, u64)>,
    triangle_scanned_at: Option<(u64, u64)>,
    stats: BvhStats,
}

/// What a grab remembers, for a saved state: the particle, whether it was pinned before, and
/// the kinematic target it had.
pub type GrabRecord = (usize, bool, Option<Vec3>);

impl InteractionState {
    pub(crate) fn grab_record(&self) -> Option<GrabRecord> {
        self.grab
            .map(|g| (g.index, g.was_pinned, g.previous_target))
    }

    pub(crate) fn set_grab_record(&mut self, record: Option<GrabRecord>) {
        self.grab = record.map(|(index, was_pinned, previous_target)| Grab {
            index,
            was_pinned,
            previous_target,
        });
    }

    /// The pick radius if one was set (None: the default, half the grid spacing).
    pub(crate) fn pick_radius_setting(&self) -> Option<f32> {
        self.pick_radius
    }

    /// Heap memory of the picking trees and the triangle ranks, in bytes.
    pub(crate) fn heap_bytes(&self) -> usize {
        self.particles.as_ref().map_or(0, |c| c.tree.heap_bytes())
            + self.triangles.as_ref().map_or(0, |c| c.tree.heap_bytes())
            + self
                .triangle_rank
                .as_ref()
                .map_or(0, |(_, rank)| rank.capacity() * size_of::<u32>())
    }

    /// Drops the picking trees and scan stamps (after a panic, when they may be half-built);
    /// the next query builds them again. Settings, the grab and the statistics stay.
    pub(crate) fn drop_caches(&mut self) {
        self.particles = None;
        self.triangles = None;
        self.triangle_rank = None;
        self.particle_scanned_at = None;
        self.triangle_scanned_at = None;
    }
}

impl Simulation {
    // ----- picking --------------------------------------------------------------------------

    /// Half-size in m of the box around each particle that `pick` tests the ray against.
    /// Defaults to half the smaller grid spacing, so that neighbouring boxes just touch.
    pub fn pick_radius(&self) -> f32 {
        self.interaction
            .pick_radius
            .unwrap_or_else(|| self.default_pick_radius())
    }

    fn default_pick_radius(&self) -> f32 {
        let size = self.scene.cloth.size;
        let dx = size[0] / (self.grid.nx - 1) as f64;
        let dy = size[1] / (self.grid.ny - 1) as f64;
        (0.5 * dx.min(dy)) as f32
    }

    /// Sets the pick radius (m, finite and > 0). The particle tree is refitted at the next
    /// query, not rebuilt.
    pub fn set_pick_radius(&mut self, radius: f64) -> Result<()> {
        let r = radius as f32;
        if !(radius.is_finite() && r.is_finite() && r > 0.0) {
            return Err(Error::value(
                "pick_radius",
                format!("must be a finite number > 0 within float32 range, got {radius}"),
            ));
        }
        self.interaction.pick_radius = Some(r);
        Ok(())
    }

    /// The live particle whose box the ray `origin + t direction` (t >= 0) enters first, as
    /// `(index, distance along the ray in m)`; ties go to the particle nearer the ray. `None`
    /// if the ray misses every particle. Errors (changing nothing) on a non-finite origin or
    /// a zero or non-finite direction.
    pub fn pick(&mut self, origin: Vec3, direction: Vec3) -> Result<Option<(usize, f32)>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self.pick_hit(&ray).map(|h| (h.index, h.distance)))
    }

    /// [`Simulation::pick`] with the full hit (including the distance from the ray).
    pub fn pick_hit(&mut self, ray: &Ray) -> Option<ParticleHit> {
        self.pick_particle(ray, false)
    }

    /// `many`: more queries on this state follow (a cut stroke), so the tree pays off.
    fn pick_particle(&mut self, ray: &Ray, many: bool) -> Option<ParticleHit> {
        if !self.use_particle_tree(many) {
            self.interaction.stats.particle_scans += 1;
            let r = self.pick_radius();
            return pick_particle_scan(ray, &self.state.pos, &self.particles.alive, r);
        }
        self.sync_particle_tree();
        let cache = self.interaction.particles.as_ref()?;
        cache.tree.cast(ray, &self.state.pos)
    }

    fn versions(&self) -> (u64, u64) {
        (self.state_version(), self.topology_version())
    }

    fn use_particle_tree(&mut self, many: bool) -> bool {
        let now = self.versions();
        let radius = self.pick_radius();
        let interaction = &mut self.interaction;
        match interaction.strategy {
            PickStrategy::Bvh => true,
            PickStrategy::Scan => false,
            PickStrategy::Auto => {
                let synced = interaction.particles.as_ref().is_some_and(|c| {
                    (c.state_version, c.topology_version) == now && c.tree.radius() == radius
                });
                let again = interaction.particle_scanned_at == Some(now);
                interaction.particle_scanned_at = Some(now);
                synced || again || many
            }
        }
    }

    fn use_triangle_tree(&mut self) -> bool {
        let now = self.versions();
        let interaction = &mut self.interaction;
        match interaction.strategy {
            PickStrategy::Bvh => true,
            PickStrategy::Scan => false,
            PickStrategy::Auto => {
                let synced = interaction
                    .triangles
                    .as_ref()
                    .is_some_and(|c| (c.state_version, c.topology_version) == now);
                let again = interaction.triangle_scanned_at == Some(now);
                interaction.triangle_scanned_at = Some(now);
                synced || again
            }
        }
    }

    /// How queries are answered (see [`PickStrategy`]).
    pub fn pick_strategy(&self) -> PickStrategy {
        self.interaction.strategy
    }

    pub fn set_pick_strategy(&mut self, strategy: PickStrategy) {
        self.interaction.strategy = strategy;
    }

    /// The live triangle (an entry of [`Simulation::triangles`]) the ray hits first, as
    /// `(triangle index, distance in m, barycentric weights of its three vertices)`.
    pub fn pick_triangle(
        &mut self,
        origin: Vec3,
        direction: Vec3,
    ) -> Result<Option<(usize, f32, [f32; 3])>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self
            .pick_triangle_hit(&ray)
            .map(|h| (h.index, h.distance, h.barycentric)))
    }

    /// [`Simulation::pick_triangle`] as a [`TriangleHit`] whose `index` is the position in
    /// [`Simulation::triangles`].
    pub fn pick_triangle_hit(&mut self, ray: &Ray) -> Option<TriangleHit> {
        let mut hit = if self.use_triangle_tree() {
            self.sync_triangle_tree();
            let cache = self.interaction.triangles.as_ref()?;
            cache.tree.cast(ray, &self.state.pos)?
        } else {
            self.interaction.stats.triangle_scans += 1;
            pick_triangle_scan(ray, self.grid, &self.state.pos, &self.particles.alive)?
        };
        hit.index = self.triangle_rank(hit.index);
        Some(hit)
    }

    /// Work done on the picking trees so far.
    pub fn bvh_stats(&self) -> BvhStats {
        self.interaction.stats
    }

    fn sync_particle_tree(&mut self) {
        let radius = self.pick_radius();
        let (sv, tv) = (self.state_version(), self.topology_version());
        let (pos, alive) = (&self.state.pos, &self.particles.alive);
        let stats = &mut self.interaction.stats;
        match &mut self.interaction.particles {
            None => {
                self.interaction.particles = Some(Cached {
                    tree: ParticleBvh::build(pos, alive, radius),
                    state_version: sv,
                    topology_version: tv,
                });
                stats.particle_builds += 1;
            }
            Some(cache) => {
                if cache.topology_version != tv {
                    stats.particle_removals += cache.tree.remove_dead(alive) as u64;
                    cache.topology_version = tv;
                }
                if cache.state_version != sv || cache.tree.radius() != radius {
                    cache.tree.refit(pos, radius);
                    stats.particle_refits += 1;
                    cache.state_version = sv;
                }
            }
        }
    }

    fn sync_triangle_tree(&mut self) {
        let (sv, tv) = (self.state_version(), self.topology_version());
        let (grid, pos, alive) = (self.grid, &self.state.pos, &self.particles.alive);
        let stats = &mut self.interaction.stats;
        match &mut self.interaction.triangles {
            None => {
                self.interaction.triangles = Some(Cached {
                    tree: TriangleBvh::build(grid, pos, alive),
                    state_version: sv,
                    topology_version: tv,
                });
                stats.triangle_builds += 1;
            }
            Some(cache) => {
                if cache.topology_version != tv {
                    stats.triangle_removals += cache.tree.remove_dead(alive) as u64;
                    cache.topology_version = tv;
                }
                if cache.state_version != sv {
                    cache.tree.refit(pos);
                    stats.triangle_refits += 1;
                    cache.state_version = sv;
                }
            }
        }
    }

    /// Position of live triangle `id` in `triangles()`: the number of live ids before it
    /// (the list is built in id order). The table is rebuilt once per topology change.
    fn triangle_rank(&mut self, id: usize) -> usize {
        let tv = self.topology_version();
        let stale = self
            .interaction
            .triangle_rank
            .as_ref()
            .is_none_or(|(v, _)| *v != tv);
        if stale {
            let alive = &self.particles.alive;
            let mut next = 0u32;
            let rank = (0..triangle_slots(self.grid))
                .map(|t| {
                    let r = next;
                    if cell_triangle(self.grid, t).iter().all(|&q| alive[q]) {
                        next += 1;
                    }
                    r
                })
                .collect();
            self.interaction.triangle_rank = Some((tv, rank));
        }
        self.interaction.triangle_rank.as_ref().unwrap().1[id] as usize
    }

    // ----- dragging -------------------------------------------------------------------------

    /// Grabs particle `index`: it becomes a kinematic pin at its current position, which
    /// [`Simulation::drag_to`] moves. Grabbing while holding another particle releases that
    /// one first. Errors on an index out of range or a cut particle.
    pub fn grab(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        if !self.particles.alive[p] {
            return Err(Error::value(
                "index",
                format!("particle {p} was cut and cannot be grabbed"),
            ));
        }
        self.release();
        let grab = Grab {
            index: p,
            was_pinned: self.particles.pinned[p],
            previous_target: self.pins.target(p),
        };
        self.pin(index, Some(self.state.pos.get(p)))?;
        self.interaction.grab = Some(grab);
        Ok(())
    }

    /// Moves the grabbed particle's target to `target` (m): over the next step the particle
    /// moves there, and the cloth follows through its springs. Without a grab (or once the
    /// grabbed particle was cut) this does nothing. Errors on a non-finite target.
    pub fn drag_to(&mut self, target: Vec3) -> Result<()> {
        if !target.is_finite() {
            return Err(Error::value(
                "target",
                format!("must be finite, got {:?}", target.to_array()),
            ));
        }
        if let Some(p) = self.grabbed() {
            // Pinned again in case `unpin` was called during the drag.
            self.particles.pinned[p] = true;
            self.particles.refresh(p);
            self.pins.set(p, target);
        }
        Ok(())
    }

    /// Lets go of the grabbed particle, restoring the pin state it had before the grab: a
    /// free particle keeps the velocity of the drag; a statically pinned one stays pinned where
    /// it is now; one that had a kinematic target gets it back. Without a grab this does
    /// nothing.
    pub fn release(&mut self) {
        let Some(grab) = self.interaction.grab.take() else {
            return;
        };
        let p = grab.index;
        if !self.particles.alive[p] {
            return; // cut while grabbed: the cut already removed the pin
        }
        match (grab.was_pinned, grab.previous_target) {
            (false, _) => {
                self.particles.pinned[p] = false;
                self.particles.refresh(p);
                self.pins.remove(p);
            }
            (true, previous) => {
                self.particles.pinned[p] = true;
                self.particles.refresh(p);
                match previous {
                    Some(target) => self.pins.set(p, target),
                    None => {
                        self.pins.remove(p);
                        self.state.vel.set(p, Vec3::ZERO);
                        self.invalidate_state();
                    }
                }
            }
        }
    }

    /// The particle being dragged, if any (a grabbed particle that was cut is let go).
    pub fn grabbed(&self) -> Option<usize> {
        self.interaction
            .grab
            .map(|g| g.index)
            .filter(|&p| self.particles.alive[p])
    }

    // ----- cutting --------------------------------------------------------------------------

    /// Cuts the particle [`Simulation::pick`] finds along the ray; returns it, or `None` if the
    /// ray hits nothing.
    pub fn cut_ray(&mut self, origin: Vec3, direction: Vec3) -> Result<Option<usize>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self.cut_along(&ray, false))
    }

    /// Cuts, ray after ray, the particle each ray of a mouse stroke picks (a later ray sees
    /// the cloth without the particles cut before it); returns the particles cut, in order.
    /// Every ray is checked before anything is cut, so bad input changes nothing. Sample the
    /// stroke densely enough (about one ray per grid spacing on screen) to leave no gaps.
    pub fn cut_stroke(&mut self, rays: &[(Vec3, Vec3)]) -> Result<Vec<usize>> {
        let rays = rays
            .iter()
            .enumerate()
            .map(|(k, &(o, d))| {
                Ray::named(
                    o,
                    d,
                    &format!("rays[{k}].origin"),
                    &format!("rays[{k}].direction"),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let many = rays.len() >= STROKE_TREE_MIN_RAYS;
        Ok(rays
            .iter()
            .filter_map(|ray| self.cut_along(ray, many))
            .collect())
    }

    fn cut_along(&mut self, ray: &Ray, many: bool) -> Option<usize> {
        let p = self.pick_particle(ray, many)?.index;
        self.cut_keeping_caches(p);
        Some(p)
    }

    /// [`Simulation::cut`] for a live particle, removing its leaves from the trees that were
    /// up to date: a cut moves nothing, so they stay valid without a refit.
    fn cut_keeping_caches(&mut self, p: usize) {
        let before = (self.state_version(), self.topology_version());
        self.cut(p as i64).expect("a picked particle is in range");
        let after = (self.state_version(), self.topology_version());
        let stats = &mut self.interaction.stats;
        if let Some(cache) = &mut self.interaction.particles {
            if (cache.state_version, cache.topology_version) == before {
                stats.particle_removals += cache.tree.remove(p) as u64;
                (cache.state_version, cache.topology_version) = after;
            }
        }
        if let Some(cache) = &mut self.interaction.triangles {
            if (cache.state_version, cache.topology_version) == before {
                stats.triangle_removals += cache.tree.remove_around(p) as u64;
                (cache.state_version, cache.topology_version) = after;
            }
        }
    }
}
