//! A simulation's whole state as plain data: what `Simulation::snapshot` returns and
//! `Simulation::restore` builds a simulation from, so that a run can be saved, sent to another
//! process (pickling) and resumed bitwise.
//!
//! It holds what a step reads and what the calls between steps remember: positions,
//! velocities, masses, pins and kinematic targets, cuts (as particles and as live springs), the
//! step count and clock, the `advance` remainder, the integrator's history and the watchdog's
//! state, and the interaction settings. Caches (picking trees, normals, scratch buffers) and
//! timings are not state: a restored simulation rebuilds them on request.

use glam::Vec3;

use crate::integrators::History;
use crate::interaction::{GrabRecord, PickStrategy};
use crate::scene::Scene;
use crate::soa::Vec3s;
use crate::watchdog::WatchdogStats;

/// Everything `Simulation::restore` needs to continue a run bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// The scene, with the run-time settings (integrator, dt, substeps) as they are now.
    pub scene: Scene,
    /// Positions in m and velocities in m/s, one per particle.
    pub positions: Vec3s,
    pub velocities: Vec3s,
    /// Masses in kg.
    pub masses: Vec<f32>,
    pub pinned: Vec<bool>,
    pub alive: Vec<bool>,
    /// Per spring kind (in [`crate::grid::SpringKind::ALL`] order), whether the spring anchored at each
    /// particle is live.
    pub springs: [Vec<bool>; 6],
    /// Kinematic pins: `(particle, target in m)`, in the order they were set.
    pub targets: Vec<(usize, Vec3)>,
    pub grab: Option<GrabRecord>,
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
    pub state_version: u64,
    pub topology_version: u64,
}

/// The watchdog's memory between steps.
#[derive(Clone, Debug, PartialEq)]
pub struct WatchdogSnapshot {
    /// The start of the last step and the integrator's history then, while that step can
    /// still be undone (only with a stretch limit).
    pub previous: Option<(Vec3s, Vec3s, History)>,
    /// The newest state has not been judged against the stretch limit yet.
    pub unjudged: bool,
    pub last_substeps: u32,
    /// After a rescue: `(substeps, until)`.
    pub hold: Option<(u32, u64)>,
    pub stats: WatchdogStats,
}
