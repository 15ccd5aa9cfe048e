//! A simulation's whole state as plain data: what `Simulation::snapshot` returns and
//! `Simulation::restore` builds a simulation from, so that a run can be saved, sent to another
//! process (pickling) and resumed bitwise.
//!
//! It holds what a step reads and what the calls between steps remember: positions,
//! velocities, masses, pins and kinematic targets, cuts (as particles and as live springs, a
//! mesh cloth's included), the
//! step count and clock, the `advance` remainder, the integrator's history and the watchdog's
//! state, and the interaction settings. Caches (picking trees, normals, scratch buffers) and
//! timings are not state: a restored simulation rebuilds them on request.

use glam::Vec3;

use crate::collisions::{Pose, PoseKey};
use crate::error::{check_scalar, check_vec3s, Bound, Error, Result};
use crate::grid::SpringKind;
use crate::integrators::History;
use crate::interaction::{Grab, Held};
use crate::model::Model;
use crate::picking::{PickStrategy, Picker};
use crate::scene::Scene;
use crate::soa::Vec3s;
use crate::state::{Clock, State};
pub use crate::stepper::WatchdogSnapshot;
use crate::stepper::{Stepper, MAX_ADVANCE_STEPS};

/// What a grab remembers of the particle it was taken at: the particle, whether it was pinned
/// before, and the kinematic target it had.
pub type GrabRecord = (usize, bool, Option<Vec3>);

/// What a grip remembers of each other particle it holds: as [`GrabRecord`], and its position
/// in m when grabbed.
pub type HeldRecord = (usize, bool, Option<Vec3>, Vec3);

/// Everything `Simulation::restore` needs to continue a run bit for bit.
///
/// Serde covers the plain values only: the scene has its own validated format, and the
/// per-particle arrays are the bulk of a snapshot, which a binding sends as arrays of its own
/// (numpy) rather than as one serde value per element.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    /// The scene, with the run-time settings (integrator, dt, substeps) as they are now.
    #[serde(skip)]
    pub scene: Scene,
    /// Positions in m and velocities in m/s, one per particle.
    #[serde(skip)]
    pub positions: Vec3s,
    #[serde(skip)]
    pub velocities: Vec3s,
    /// Masses in kg.
    #[serde(skip)]
    pub masses: Vec<f32>,
    #[serde(skip)]
    pub pinned: Vec<bool>,
    #[serde(skip)]
    pub alive: Vec<bool>,
    /// Per spring kind (in [`crate::grid::SpringKind::ALL`] order), whether the spring anchored at each
    /// particle is live.
    #[serde(skip)]
    pub springs: [Vec<bool>; 6],
    /// A mesh cloth's springs, whether each (in the mesh's spring list) is live; empty on the
    /// grid, and on a mesh for "none severed".
    #[serde(skip)]
    pub mesh_springs: Vec<bool>,
    /// Kinematic pins: `(particle, target in m)`, in the order they were set.
    pub targets: Vec<(usize, Vec3)>,
    pub grab: Option<GrabRecord>,
    /// The grip's other particles (none in a state saved before grips, or with radius 0).
    #[serde(default)]
    pub grip: Vec<HeldRecord>,
    /// The grabbed particle's position in m when grabbed (None without a grab, or from a
    /// state saved before grips).
    #[serde(default)]
    pub grip_origin: Option<Vec3>,
    /// The grip radius if one was set (None: the default).
    #[serde(default)]
    pub grip_radius: Option<f32>,
    /// The drag time in s if one was set (None: the default).
    #[serde(default)]
    pub drag_time: Option<f64>,
    /// A drag's glide in progress: `(shift in m, from, until in s, the particles it moves)`
    /// (see [`crate::pins::Glide`]; None when the grip is on its targets, or from a state saved
    /// before glides).
    #[serde(default)]
    pub drag_glide: Option<(Vec3, f64, f64, Vec<usize>)>,
    /// The particles whose targets a drag set (a grip held back by self-collision catches up
    /// at [`crate::pins::CATCH_UP`]; other targets are reached in one substep). Empty from a
    /// state saved before.
    #[serde(default)]
    pub drag_targets: Vec<usize>,
    pub pick_radius: Option<f32>,
    pub pick_strategy: PickStrategy,
    pub steps: u64,
    /// The clock: `time = time_base + (steps - steps_base) dt`.
    pub time_base: f64,
    pub steps_base: u64,
    /// Requested time not yet simulated by `advance`, in s.
    pub accumulator: f64,
    pub history: History,
    pub watchdog: WatchdogSnapshot,
    /// Per collider of the scene, the pose set between steps (`set_collider_pose`), if any.
    pub collider_keys: Vec<Option<PoseKey>>,
    pub state_version: u64,
    pub topology_version: u64,
}

impl Snapshot {
    /// The snapshot of a simulation's parts.
    pub(crate) fn capture(
        model: &Model,
        state: &State,
        stepper: &Stepper,
        picker: &Picker,
        grab: Option<&Grab>,
        (grip_radius, drag_time): (Option<f32>, Option<f64>),
    ) -> Snapshot {
        Snapshot {
            scene: model.scene.clone(),
            positions: state.kin.pos.clone(),
            velocities: state.kin.vel.clone(),
            masses: model.particles.mass.clone(),
            pinned: model.particles.pinned.clone(),
            alive: model.particles.alive.clone(),
            springs: SpringKind::ALL.map(|kind| {
                model.springs.active[kind.index()]
                    .iter()
                    .map(|&a| a != 0.0)
                    .collect()
            }),
            mesh_springs: model
                .mesh()
                .map_or_else(Vec::new, |m| m.springs.active.clone()),
            targets: state.targets.targets().to_vec(),
            grab: grab.map(|g| {
                let h = g.held[0];
                (h.index, h.was_pinned, h.previous_target)
            }),
            grip: grab.map_or_else(Vec::new, |g| {
                g.held[1..]
                    .iter()
                    .map(|h| (h.index, h.was_pinned, h.previous_target, h.start))
                    .collect()
            }),
            grip_origin: grab.map(|g| g.held[0].start),
            grip_radius,
            drag_time,
            drag_glide: state
                .targets
                .glide()
                .map(|(g, moved)| (g.shift, g.from, g.until, moved)),
            drag_targets: state.targets.gliding(),
            pick_radius: picker.radius_setting(),
            pick_strategy: picker.strategy(),
            steps: state.clock.steps,
            time_base: state.clock.time_base,
            steps_base: state.clock.steps_base,
            accumulator: state.clock.accumulator,
            history: stepper.history(),
            watchdog: stepper.watchdog_snapshot(),
            collider_keys: stepper
                .shapes()
                .map_or_else(Vec::new, |s| s.keys().to_vec()),
            state_version: state.version,
            topology_version: model.topology_version,
        }
    }

    /// Puts the snapshot into the parts of a simulation freshly built from its scene, checking
    /// every part against the scene first; returns the grab. On error the parts may be half
    /// set: the caller drops them.
    pub(crate) fn apply(
        self,
        model: &mut Model,
        state: &mut State,
        stepper: &mut Stepper,
        picker: &mut Picker,
    ) -> Result<Option<Grab>> {
        let n = model.grid.len();
        for (name, values) in [
            ("positions", &self.positions),
            ("velocities", &self.velocities),
        ] {
            check_vec3s(name, values, n)?;
        }
        if self.masses.len() != n {
            return Err(Error::value(
                "masses",
                format!("must hold {n} values, got {}", self.masses.len()),
            ));
        }
        for (p, &m) in self.masses.iter().enumerate() {
            if !(m.is_finite() && m > 0.0 && (1.0 / m).is_finite()) {
                return Err(Error::value(
                    format!("masses[{p}]"),
                    format!("must be finite and > 0 with a finite inverse, got {m}"),
                ));
            }
        }
        for (name, flags) in [("pinned", &self.pinned), ("alive", &self.alive)] {
            if flags.len() != n {
                return Err(Error::value(
                    name,
                    format!("must hold {n} flags, got {}", flags.len()),
                ));
            }
        }
        for kind in SpringKind::ALL {
            let flags = &self.springs[kind.index()];
            let name = format!("springs[{}]", kind.index());
            if flags.len() != n {
                return Err(Error::value(
                    name,
                    format!("must hold {n} flags, got {}", flags.len()),
                ));
            }
            if let Some(p) = (0..n).find(|&p| flags[p] && model.grid.partner(p, kind).is_none()) {
                return Err(Error::value(
                    name,
                    format!("particle {p} has no partner for a live spring of {kind:?}"),
                ));
            }
        }
        let mesh_springs = model.mesh().map_or(0, |m| m.springs.len());
        if !self.mesh_springs.is_empty() && self.mesh_springs.len() != mesh_springs {
            return Err(Error::value(
                "mesh_springs",
                format!(
                    "must hold one flag per spring of the mesh cloth ({mesh_springs}), or none, \
                     got {}",
                    self.mesh_springs.len()
                ),
            ));
        }
        for &(p, target) in &self.targets {
            if p >= n || !self.pinned[p] || !target.is_finite() {
                return Err(Error::value(
                    "targets",
                    format!("({p}, {target}) must be a pinned particle and a finite target"),
                ));
            }
        }
        if let Some((p, _, previous)) = self.grab {
            if p >= n || !self.alive[p] || previous.is_some_and(|t| !t.is_finite()) {
                return Err(Error::value(
                    "grab",
                    format!("particle {p} must be a live particle"),
                ));
            }
        } else if !self.grip.is_empty() {
            return Err(Error::value("grip", "must be empty without a grab"));
        }
        if !self
            .grip_origin
            .is_none_or(|o| o.is_finite() && self.grab.is_some())
        {
            return Err(Error::value(
                "grip_origin",
                "must be finite, and only with a grab",
            ));
        }
        if !self.grip.is_empty() && self.grip_origin.is_none() {
            return Err(Error::value("grip_origin", "must be set with a grip"));
        }
        for (k, &(p, _, previous, start)) in self.grip.iter().enumerate() {
            let finite = previous.is_none_or(|t| t.is_finite()) && start.is_finite();
            if p >= n || !finite || self.grab.is_some_and(|g| g.0 == p) {
                return Err(Error::value(
                    format!("grip[{k}]"),
                    format!(
                        "particle {p} must be a particle other than the grabbed one, with a \
                         finite start and target"
                    ),
                ));
            }
        }
        if let Some(r) = self.grip_radius {
            crate::interaction::checked_grip_radius(r as f64)?;
        }
        if let Some(t) = self.drag_time {
            crate::interaction::checked_drag_time(t)?;
        }
        if let Some((shift, from, until, moved)) = &self.drag_glide {
            let has_target = |p: &usize| self.targets.iter().any(|(q, _)| q == p);
            let finite = shift.is_finite() && from.is_finite() && until.is_finite();
            if !(finite && until >= from && moved.iter().all(has_target)) {
                return Err(Error::value(
                    "drag_glide",
                    "must be finite, end no earlier than it starts, and move particles with \
                     targets",
                ));
            }
        }
        let has_target = |p: &usize| self.targets.iter().any(|(q, _)| q == p);
        if !self.drag_targets.iter().all(has_target) {
            return Err(Error::value(
                "drag_targets",
                "must list particles with targets",
            ));
        }
        if let Some(r) = self.pick_radius {
            picker.set_radius(r as f64)?;
        }
        for (name, x) in [
            ("time_base", self.time_base),
            ("accumulator", self.accumulator),
        ] {
            check_scalar(name, x, Bound::NonNegative)?;
        }
        // What an `advance` can leave owed: less than a step, or the steps of a refused call.
        let owed = (MAX_ADVANCE_STEPS + 1) as f64 * model.scene.dt;
        if self.accumulator > owed {
            return Err(Error::value(
                "accumulator",
                format!(
                    "must be at most {owed} s (the time of {MAX_ADVANCE_STEPS} steps of dt = {} \
                     s, the most one advance can owe), got {}",
                    model.scene.dt, self.accumulator
                ),
            ));
        }
        if self.steps_base > self.steps {
            return Err(Error::value(
                "steps_base",
                format!(
                    "must be at most steps ({}), got {}: the clock would run backwards",
                    self.steps, self.steps_base
                ),
            ));
        }
        stepper.restore_watchdog(self.watchdog, model, self.steps)?;
        let colliders = model.scene.colliders.len();
        if self.collider_keys.len() != colliders {
            return Err(Error::value(
                "collider_keys",
                format!(
                    "must hold one entry per collider ({colliders}), got {}",
                    self.collider_keys.len()
                ),
            ));
        }
        for (c, key) in self.collider_keys.iter().enumerate() {
            if let Some(key) = key {
                check_pose_key(&format!("collider_keys[{c}]"), key)?;
            }
        }
        if let Some(shapes) = stepper.shapes_mut() {
            shapes.set_keys(self.collider_keys);
        }

        state.kin.pos.copy_from(&self.positions);
        state.kin.vel.copy_from(&self.velocities);
        let particles = &mut model.particles;
        particles.mass = self.masses;
        particles.pinned = self.pinned;
        particles.alive = self.alive;
        for p in 0..n {
            particles.refresh(p);
        }
        for kind in SpringKind::ALL {
            let active = &mut model.springs.active[kind.index()];
            for (slot, &live) in self.springs[kind.index()].iter().enumerate() {
                active[slot] = if live { 1.0 } else { 0.0 };
            }
        }
        if let crate::model::Topology::Mesh(topology) = &mut model.topology {
            topology.sever_as_saved(&self.mesh_springs);
        }
        for (p, target) in self.targets {
            state.targets.set(p, target);
        }
        if let Some((shift, from, until, moved)) = self.drag_glide {
            let glide = crate::pins::Glide { shift, from, until };
            state.targets.restore_glide(glide, &moved);
        }
        state.targets.restore_gliding(&self.drag_targets);
        picker.set_strategy(self.pick_strategy);
        state.clock = Clock {
            steps: self.steps,
            time_base: self.time_base,
            steps_base: self.steps_base,
            accumulator: self.accumulator,
        };
        stepper.set_history(self.history);
        state.version = self.state_version;
        model.topology_version = self.topology_version;
        let grip = self
            .grip
            .iter()
            .map(|&(index, was_pinned, previous_target, start)| Held {
                index,
                was_pinned,
                previous_target,
                start,
            });
        Ok(self.grab.map(|(index, was_pinned, previous_target)| {
            let grabbed = Held {
                index,
                was_pinned,
                previous_target,
                start: self.grip_origin.unwrap_or(Vec3::ZERO),
            };
            Grab {
                held: std::iter::once(grabbed).chain(grip).collect(),
            }
        }))
    }
}

/// A pose key's poses pass [`Pose::checked`] unchanged, and it spans a positive time.
fn check_pose_key(name: &str, key: &PoseKey) -> Result<()> {
    for (part, pose) in [("from", key.from), ("to", key.to)] {
        let (position, rotation) = (
            format!("{name}.{part}.position"),
            format!("{name}.{part}.rotation"),
        );
        Pose::checked(
            (&position, &rotation),
            pose.position.to_array(),
            pose.rotation.to_array(),
        )?;
    }
    if !(key.start.is_finite() && key.end.is_finite() && key.end > key.start) {
        return Err(Error::value(
            format!("{name}.end"),
            format!(
                "must be finite and after start, got start {} and end {}",
                key.start, key.end
            ),
        ));
    }
    Ok(())
}
