//! The watchdog: how a step notices it went wrong, and what it does then.
//!
//! **Noticing** costs nothing extra when nothing is wrong. A non-finite value is caught by the
//! integrator's update loop as it writes the value ([`crate::integrators::FiniteCheck`]). A
//! spring stretched beyond the scene's `max_stretch` is caught by the force evaluation at the
//! start of the next substep, in the loop that computes that spring's force anyway
//! ([`crate::forces::ForceModel::arm_stretch_watch`]): a state is judged when the simulation
//! tries to continue from it. So stretch trouble in the last substep of step `n` shows up at
//! the start of step `n + 1`, and the step to blame is `n`.
//!
//! **Recovering** needs the state before the step to blame. The state at the start of the
//! current step is always at hand (the integrator writes into a second buffer). For trouble
//! found one step late, the watchdog also keeps the start of the last completed step in
//! `previous`, filled by swapping buffers rather than copying: a step's start state ends up in
//! a spare buffer anyway, and the swap moves it into `previous`. This buffer exists only in
//! scenes with a `max_stretch`.
//!
//! Then, by `watchdog.on_trouble`: `"raise"` restores that state and returns
//! [`Error::Diverged`](crate::Error::Diverged); `"substep"` reruns the step from it with twice
//! the substeps, four times, ... up to `max_substeps`, checking each attempt including its end
//! state, and raises only if every attempt fails; the substeps that saved the step are then held
//! for `hold_steps` steps, since what made one step fail usually persists. [`WatchdogStats`]
//! counts what happened.

use rayon::prelude::*;

use crate::error::Trouble;
use crate::grid::{Grid, SpringKind};
use crate::integrators::History;
use crate::scene::{OnTrouble, WatchdogSpec};
use crate::soa::Vec3s;
use crate::springs::{neighbour_runs, overstretched, Springs};
use crate::state::Kinematics;

/// What the watchdog did since the simulation was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WatchdogStats {
    /// Steps that went wrong, whether then saved by a retry or raised.
    pub caught: u64,
    /// Steps saved by rerunning them with more substeps.
    pub retried: u64,
    /// Substeps of every retry attempt, failed ones counted in full: the cost of the safety net.
    pub retry_substeps: u64,
    /// Most substeps a saved step needed.
    pub max_substeps_used: u32,
    /// Steps run with a rescued step's substeps held (`hold_steps`).
    pub held_steps: u64,
}

/// A step that went wrong, before recovery.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Failure {
    pub(super) reason: Trouble,
    pub(super) particle: usize,
    /// The trouble was in the state the step started from: the previous step is to blame.
    pub(super) in_start_state: bool,
    /// Substeps of the failed attempt.
    pub(super) substeps: u32,
}

pub(super) struct Watchdog {
    pub(super) spec: WatchdogSpec,
    /// The start of the last completed step, while `previous_valid`; only with `max_stretch`.
    pub(super) previous: Option<Kinematics>,
    /// The integrator's history at the start of that step.
    pub(super) previous_history: History,
    /// False after anything but a step changed the state: then the current state is the
    /// user's, and trouble found in it is not a step's fault.
    pub(super) previous_valid: bool,
    /// The newest state came from a step and has not been checked yet.
    pub(super) unjudged: bool,
    /// Substeps the last completed step ran with.
    pub(super) last_substeps: u32,
    /// After a rescue: `(substeps, until)`, the substeps steps before number `until` use.
    pub(super) hold: Option<(u32, u64)>,
    /// The start of a step being retried.
    pub(super) retry_start: Option<Kinematics>,
    pub(super) stats: WatchdogStats,
}

impl Watchdog {
    pub fn new(spec: &WatchdogSpec, particles: usize) -> Self {
        Watchdog {
            previous: spec.max_stretch.map(|_| Kinematics::zeros(particles)),
            previous_history: History::default(),
            spec: spec.clone(),
            previous_valid: false,
            unjudged: false,
            hold: None,
            last_substeps: 1,
            retry_start: None,
            stats: WatchdogStats::default(),
        }
    }

    /// The stretch limit as the force loop compares it.
    pub fn stretch_limit(&self) -> Option<f32> {
        self.spec.max_stretch.map(|r| r as f32)
    }

    pub fn retries(&self) -> bool {
        self.spec.on_trouble == OnTrouble::Substep
    }

    /// Records that a step starting from the state in `start` and the integrator `history`
    /// completed with `substeps` substeps: that buffer becomes
    /// `previous` (by a swap; `start` receives the old `previous`, which its owner overwrites
    /// before reading it again).
    pub fn step_completed(&mut self, start: &mut Kinematics, history: History, substeps: u32) {
        self.last_substeps = substeps;
        if let Some(previous) = &mut self.previous {
            std::mem::swap(previous, start);
            self.previous_history = history;
            self.previous_valid = true;
            self.unjudged = true;
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.previous.as_ref().map_or(0, Kinematics::heap_bytes)
            + self.retry_start.as_ref().map_or(0, Kinematics::heap_bytes)
    }
}

/// Particles per parallel work item of [`any_overstretched`].
const SCAN_CHUNK: usize = 8192;

/// Whether a live spring of `kinds` is longer than `limit` times its rest length: the check of
/// the force loop as a read-only pass of its own, for the newest state of a call. Parallel and
/// vectorised like the force loop (an integer OR of compares), since with one step per call it
/// runs once per step.
pub(super) fn any_overstretched(
    grid: Grid,
    springs: &Springs,
    pos: &Vec3s,
    kinds: &[SpringKind],
    limit: f32,
) -> bool {
    // One parallel loop over chunks of anchors, every kind inside: a parallel loop per kind
    // cost more in thread wake-ups than the scan itself at 128 x 128.
    let n = grid.len();
    (0..n.div_ceil(SCAN_CHUNK)).into_par_iter().any(|c| {
        let chunk = c * SCAN_CHUNK..((c + 1) * SCAN_CHUNK).min(n);
        kinds.iter().any(|&kind| {
            let [anchors, _] = neighbour_runs(n, grid.offset(kind), chunk.clone());
            anchors.is_some_and(|run| {
                let view = springs.view(kind, pos, run);
                crate::simd::dispatch!(scan(&view, limit))
            })
        })
    })
}

/// Whether a spring of the run is beyond `limit`: one straight loop over equal-length slices,
/// which the compiler vectorises.
#[inline(always)]
fn scan(view: &crate::springs::RunView, limit: f32) -> bool {
    let mut over = 0u32;
    for i in 0..view.len {
        let [dx, dy, dz] = view.delta(i);
        let l = (dx * dx + dy * dy + dz * dz).sqrt();
        over |= overstretched(l, view.rest[i], view.active[i], limit) as u32;
    }
    over != 0
}

/// The first live spring of `kinds` longer than `limit` times its rest length, as `(anchor
/// particle, l / L)`. The same arithmetic as the check in the force loop, so the two agree on
/// every spring; a serial pass, run only on the trouble path.
pub(super) fn find_overstretched(
    grid: Grid,
    springs: &Springs,
    pos: &Vec3s,
    kinds: &[SpringKind],
    limit: f32,
) -> Option<(usize, f32)> {
    kinds.iter().find_map(|&kind| {
        let (k, o) = (kind.index(), grid.offset(kind));
        (0..grid.len().saturating_sub(o)).find_map(|a| {
            let b = a + o;
            let (dx, dy, dz) = (
                pos.x[b] - pos.x[a],
                pos.y[b] - pos.y[a],
                pos.z[b] - pos.z[a],
            );
            let l = (dx * dx + dy * dy + dz * dz).sqrt();
            let (rest, active) = (springs.rest[k][a], springs.active[k][a]);
            overstretched(l, rest, active, limit).then(|| (a, l / rest))
        })
    })
}
