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
//!
//! One trouble is retried whatever `on_trouble` says: a [`Trouble::Cascade`], the
//! self-collision cap stopping a whole cluster of contacts in one substep. It is no divergence
//! but motion the cap cannot pass in one substep, and at most [`CASCADE_MOST`] times the
//! scene's substeps it is accepted as the cap left it, so it never raises; the steps after
//! it hold at most [`CASCADE_HELD`] times the scene's substeps, for a hold that adapts: short
//! ([`CASCADE_HOLD_FIRST`] steps) after a lone cascade, twice as long each time the cluster
//! cascades again while held, up to `hold_steps`.

use rayon::prelude::*;

use crate::error::{Error, Result, Trouble};
use crate::grid::{Grid, SpringKind};
use crate::integrators::History;
use crate::model::Model;
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
    /// Most vertices the self-collision cap stopped in one substep of a step saved from a
    /// cascade: what chose its hold ([`CASCADE_LARGE`]); 0 without a cascade (absent in a state
    /// saved without it: 0).
    #[serde(default)]
    pub largest_cascade: u64,
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

/// The watchdog's memory between steps, for a saved state.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WatchdogSnapshot {
    /// The start of the last step and the integrator's history then, while that step can
    /// still be undone (only with a stretch limit). Per-particle arrays: outside serde, as in
    /// [`crate::snapshot::Snapshot`].
    #[serde(skip)]
    pub previous: Option<(Vec3s, Vec3s, History)>,
    /// The newest state has not been judged against the stretch limit yet.
    pub unjudged: bool,
    pub last_substeps: u32,
    /// After a rescue: `(substeps, until)`.
    pub hold: Option<(u32, u64)>,
    /// Steps the hold lasts when a cascade set it, 0 otherwise (absent in a state saved
    /// without it: 0).
    #[serde(default)]
    pub cascade_hold: u64,
    pub stats: WatchdogStats,
}

/// What a failed attempt at a step puts back of the watchdog: its hold as the attempt found it.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct HoldMark {
    hold: Option<(u32, u64)>,
    cascade_hold: u64,
    held_steps: u64,
}

pub(super) struct Watchdog {
    spec: WatchdogSpec,
    /// The start of the last completed step, while `previous_valid`; only with `max_stretch`.
    previous: Option<Kinematics>,
    /// The integrator's history at the start of that step.
    previous_history: History,
    /// False after anything but a step changed the state: then the current state is the
    /// user's, and trouble found in it is not a step's fault.
    previous_valid: bool,
    /// The newest state came from a step and has not been checked yet.
    unjudged: bool,
    /// Substeps the last completed step ran with.
    last_substeps: u32,
    /// After a rescue: `(substeps, until)`, the substeps steps before number `until` use.
    hold: Option<(u32, u64)>,
    /// Steps the hold lasts when a cascade set it, 0 otherwise: what a cascade while held
    /// doubles.
    cascade_hold: u64,
    /// The start of a step being retried (made once, so that a retry never allocates).
    retry_start: Option<Kinematics>,
    stats: WatchdogStats,
}

impl Watchdog {
    pub fn new(spec: &WatchdogSpec, particles: usize) -> Self {
        let retries = spec.on_trouble == OnTrouble::Substep;
        Watchdog {
            previous: spec.max_stretch.map(|_| Kinematics::zeros(particles)),
            previous_history: History::default(),
            spec: spec.clone(),
            previous_valid: false,
            unjudged: false,
            hold: None,
            cascade_hold: 0,
            last_substeps: 1,
            retry_start: retries.then(|| Kinematics::zeros(particles)),
            stats: WatchdogStats::default(),
        }
    }

    /// The stretch limit as the force loop compares it.
    pub fn stretch_limit(&self) -> Option<f32> {
        self.spec.max_stretch.map(|r| r as f32)
    }

    /// Whether a step that went wrong is retried with more substeps (else it is reported).
    pub fn retries(&self) -> bool {
        self.spec.on_trouble == OnTrouble::Substep
    }

    pub fn stats(&self) -> WatchdogStats {
        self.stats
    }

    // ----- a step's course --------------------------------------------------------------------

    /// The substeps step number `step` runs with: `scene_substeps`, or more while a rescued
    /// step's count is held; and whether a hold ended here (the substep length changes back).
    pub fn substeps_for(&mut self, step: u64, scene_substeps: u32) -> (u32, bool) {
        match self.hold {
            Some((substeps, until)) if step < until => {
                self.stats.held_steps += 1;
                (substeps, false)
            }
            Some(_) => {
                self.hold = None;
                (scene_substeps, true)
            }
            None => (scene_substeps, false),
        }
    }

    /// The hold as it is, for a failed attempt to put back ([`Watchdog::rewind`]).
    pub fn mark(&self) -> HoldMark {
        HoldMark {
            hold: self.hold,
            cascade_hold: self.cascade_hold,
            held_steps: self.stats.held_steps,
        }
    }

    pub fn rewind(&mut self, mark: HoldMark) {
        (self.hold, self.cascade_hold) = (mark.hold, mark.cascade_hold);
        self.stats.held_steps = mark.held_steps;
    }

    /// Records that a step starting from the state in `start` and the integrator `history`
    /// completed with `substeps` substeps: that buffer becomes `previous` (by a swap; `start`
    /// receives the old `previous`, which its owner overwrites before reading it again).
    pub fn step_completed(&mut self, start: &mut Kinematics, history: History, substeps: u32) {
        self.last_substeps = substeps;
        if let Some(previous) = &mut self.previous {
            std::mem::swap(previous, start);
            self.previous_history = history;
            self.previous_valid = true;
            self.unjudged = true;
        }
    }

    /// Something other than a step set the state: trouble in it is not the last step's fault,
    /// and a call that takes no step has nothing to judge.
    pub fn state_replaced(&mut self) {
        self.previous_valid = false;
        self.unjudged = false;
    }

    /// The last step can no longer be undone and retried (it ran with another `dt`).
    pub fn forget_last_step(&mut self) {
        self.previous_valid = false;
    }

    /// The substeps of the last completed step when the newest state has not been judged yet;
    /// it counts as judged from now on.
    pub fn take_unjudged(&mut self) -> Option<u32> {
        std::mem::take(&mut self.unjudged).then_some(self.last_substeps)
    }

    /// The state now was judged good (it was just restored).
    pub fn judged(&mut self) {
        self.unjudged = false;
    }

    // ----- recovering ---------------------------------------------------------------------------

    /// Whether a substep of a step of `substeps` substeps, in which the self-collision cap
    /// stopped `stopped` vertices, fails as a [`Trouble::Cascade`]: more than
    /// [`CASCADE_STOPPED`], and the retry with twice the substeps within both `max_substeps`
    /// and [`CASCADE_MOST`] times the scene's `scene_substeps`. Past those the substep is kept
    /// as the cap left it (safe, only held back), so that a cascade never raises.
    pub fn cascade(&self, stopped: u64, substeps: u32, scene_substeps: u32) -> bool {
        let doubled = substeps.saturating_mul(2);
        stopped > CASCADE_STOPPED
            && doubled <= self.spec.max_substeps
            && doubled <= scene_substeps.saturating_mul(CASCADE_MOST)
    }

    pub fn count_caught(&mut self) {
        self.stats.caught += 1;
    }

    pub fn last_substeps(&self) -> u32 {
        self.last_substeps
    }

    /// Puts the start of the last completed step into `kin` and returns the integrator's history
    /// then; None when that step cannot be undone (the state came from the user or the scene).
    pub fn undo_last_step(&mut self, kin: &mut Kinematics) -> Option<History> {
        let previous = self.previous.as_ref().filter(|_| self.previous_valid)?;
        kin.copy_from(previous);
        self.previous_valid = false;
        Some(self.previous_history)
    }

    /// The substeps a step that failed with `failed` substeps is retried with, in turn: 2, 4,
    /// ... times as many, up to `max_substeps`. Each one is counted as the retry's cost.
    pub fn retry_substeps(&self, failed: u32) -> impl Iterator<Item = u32> {
        let most = self.spec.max_substeps;
        std::iter::successors(failed.checked_mul(2), |s| s.checked_mul(2))
            .take_while(move |&s| s <= most)
    }

    pub fn count_retry_attempt(&mut self, substeps: u32) {
        self.stats.retry_substeps += substeps as u64;
    }

    /// The buffer a retried step keeps its start in.
    pub fn take_retry_start(&mut self, particles: usize) -> Kinematics {
        self.retry_start
            .take()
            .unwrap_or_else(|| Kinematics::zeros(particles))
    }

    pub fn put_retry_start(&mut self, start: Kinematics) {
        self.retry_start = Some(start);
    }

    /// Step number `step` of a scene of `scene_substeps`, started from `start` with the
    /// integrator's `history`, was saved from a failure for `reason` by a retry with `substeps`
    /// substeps: those are held for the next `hold_steps` steps, since what made it fail
    /// usually persists. After a [`Trouble::Cascade`] (its `stopped` the most vertices any
    /// attempt's cap stopped in a substep) the hold is chosen by the cascade's size: one that
    /// stopped more than [`CASCADE_LARGE`] holds at most [`CASCADE_MOST`] times the scene's
    /// substeps for `hold_steps`; a smaller one at most [`CASCADE_HELD`] times, for as long as
    /// [`Watchdog::cascade_hold_after`] says.
    pub fn rescued(
        &mut self,
        step: u64,
        substeps: u32,
        scene_substeps: u32,
        reason: Trouble,
        start: &mut Kinematics,
        history: History,
    ) {
        self.stats.retried += 1;
        self.stats.max_substeps_used = self.stats.max_substeps_used.max(substeps);
        let (held, hold) = match reason {
            Trouble::Cascade { stopped } => {
                self.stats.largest_cascade = self.stats.largest_cascade.max(stopped);
                let (most, hold) = if stopped > CASCADE_LARGE {
                    (CASCADE_MOST, self.spec.hold_steps as u64)
                } else {
                    (CASCADE_HELD, self.cascade_hold_after(step))
                };
                self.cascade_hold = hold;
                (substeps.min(scene_substeps.saturating_mul(most)), hold)
            }
            _ => {
                self.cascade_hold = 0;
                (substeps, self.spec.hold_steps as u64)
            }
        };
        self.hold = (hold > 0).then_some((held, step + 1 + hold));
        self.step_completed(start, history, substeps);
    }

    /// Steps the hold after a cascade in step number `step` lasts: [`CASCADE_HOLD_FIRST`], or,
    /// when the step was held after an earlier cascade (the cluster cascaded again within its
    /// hold), twice that hold; never more than `hold_steps`.
    fn cascade_hold_after(&self, step: u64) -> u64 {
        let most = self.spec.hold_steps as u64;
        let within = self.hold.is_some_and(|(_, until)| step < until);
        let hold = match self.cascade_hold {
            last if within && last > 0 => last.saturating_mul(2),
            _ => CASCADE_HOLD_FIRST,
        };
        hold.min(most)
    }

    // ----- saving and restoring -----------------------------------------------------------------

    pub fn snapshot(&self) -> WatchdogSnapshot {
        WatchdogSnapshot {
            previous: self
                .previous
                .as_ref()
                .filter(|_| self.previous_valid)
                .map(|k| (k.pos.clone(), k.vel.clone(), self.previous_history)),
            unjudged: self.unjudged,
            last_substeps: self.last_substeps,
            hold: self.hold,
            cascade_hold: self.cascade_hold,
            stats: self.stats,
        }
    }

    /// Puts back the memory of a saved state of `n` particles at step `steps`, in a scene of
    /// `substeps` substeps; the error names what does not fit.
    ///
    /// Only what such a simulation can have written is taken: a step's substeps between 1 and
    /// the most the watchdog retries with, and a hold that ends within `hold_steps` of `steps`
    /// and, after a cascade, lasts at most `hold_steps`, so that no crafted state makes the next
    /// step run for hours.
    pub fn restore(
        &mut self,
        saved: WatchdogSnapshot,
        n: usize,
        steps: u64,
        substeps: u32,
    ) -> Result<()> {
        let most = self.spec.max_substeps.max(substeps);
        if !(1..=most).contains(&saved.last_substeps) {
            return Err(Error::value(
                "watchdog",
                format!(
                    "last_substeps must be an integer from 1 to {most}, got {}",
                    saved.last_substeps
                ),
            ));
        }
        if let Some((held, until)) = saved.hold {
            let latest = steps.saturating_add(2 + self.spec.hold_steps as u64);
            if !(1..=most).contains(&held) || until > latest {
                return Err(Error::value(
                    "watchdog.hold",
                    format!(
                        "must be (substeps from 1 to {most}, a step no later than {latest}), \
                         got ({held}, {until})"
                    ),
                ));
            }
        }
        if saved.cascade_hold > self.spec.hold_steps as u64 {
            return Err(Error::value(
                "watchdog.cascade_hold",
                format!(
                    "must be a number of steps from 0 to hold_steps ({}), got {}",
                    self.spec.hold_steps, saved.cascade_hold
                ),
            ));
        }
        match (saved.previous, self.previous.as_mut()) {
            (None, _) => {}
            (Some(_), None) => {
                return Err(Error::value(
                    "watchdog",
                    "a saved previous state needs a scene with watchdog.max_stretch",
                ))
            }
            (Some((pos, vel, history)), Some(buffer)) => {
                let saved = Kinematics { pos, vel };
                if saved.pos.len() != n
                    || saved.vel.len() != n
                    || saved.first_non_finite().is_some()
                {
                    return Err(Error::value(
                        "watchdog",
                        format!("the previous state must hold {n} finite positions and velocities"),
                    ));
                }
                buffer.copy_from(&saved);
                self.previous_history = history;
                self.previous_valid = true;
            }
        }
        self.unjudged = saved.unjudged;
        self.last_substeps = saved.last_substeps;
        self.hold = saved.hold;
        self.cascade_hold = saved.cascade_hold;
        self.stats = saved.stats;
        Ok(())
    }

    pub fn heap_bytes(&self) -> usize {
        self.previous.as_ref().map_or(0, Kinematics::heap_bytes)
            + self.retry_start.as_ref().map_or(0, Kinematics::heap_bytes)
    }

    /// The first spring of `kin` beyond the stretch limit, among the spring `kinds` the force
    /// model has, as a failure of a step of `substeps` substeps. A full pass over the springs:
    /// for the newest state of a call, the end of a retried step and the trouble path.
    pub fn overstretched_in(
        &self,
        model: &Model,
        kin: &Kinematics,
        kinds: &[SpringKind],
        in_start_state: bool,
        substeps: u32,
    ) -> Option<Failure> {
        let limit = self.stretch_limit()?;
        if let Some(mesh) = model.mesh() {
            let (particle, stretch) = mesh.first_overstretched(&kin.pos, limit)?;
            return Some(Failure {
                reason: Trouble::Overstretched { stretch, limit },
                particle,
                in_start_state,
                substeps,
            });
        }
        let (grid, springs) = (model.grid, &model.springs);
        if !any_overstretched(grid, springs, &kin.pos, kinds, limit) {
            return None;
        }
        let (particle, stretch) = find_overstretched(grid, springs, &kin.pos, kinds, limit)?;
        Some(Failure {
            reason: Trouble::Overstretched { stretch, limit },
            particle,
            in_start_state,
            substeps,
        })
    }
}

/// Vertices the self-collision cap may stop in one substep before the substep fails as a
/// [`Trouble::Cascade`]. The cap stops a pair's vertices at the substep's start when its
/// proportional rounds do not settle it; in a wound cloth moving together faster than the cap
/// lets a pair close, every pair touching a stopped vertex is then too fast as well, and the stop
/// spreads through the contacts (9,926 vertices of the 256 x 256 twist in one substep) while the
/// pins and the cloth around move on, tearing it. The shipped scenes stop at most a few at a
/// time (docs/notes/contact.md, "The cascade retried with more substeps"): more, and the step is
/// retried with more substeps, each moving the cloth half as far.
pub const CASCADE_STOPPED: u64 = 32;

/// Most substeps a step retried for a cascade may take, as a multiple of the scene's: each
/// doubling halves the motion a substep, and a cloth that still cascades at four times is held
/// back as the cap leaves it rather than frozen at 64 substeps (an interactive scene's frame
/// would take 16 times as long for `hold_steps` steps).
pub const CASCADE_MOST: u32 = 4;

/// Most substeps the steps after a step saved from a cascade are held at, as a multiple of the
/// scene's, whatever the retry needed. The hold is what a cascade costs: newton's 50 x 50 twist
/// (2 steps a frame, `solve_stiffness` 30) cascades twice near 1.9 s, the second time saved
/// only at 4 times its substeps, and its wound window from 2.0 s, where no substep stops a
/// vertex, takes about a quarter less CPU a frame held at 2 than at 4. The hold itself stays:
/// retried step by step without one, the thin 64 x 64 twist, whose cap at one substep stops up
/// to 32 vertices a substep uncaught every few steps, stretches past 1.5 by frame 60
/// (`a_thin_twist_never_stretches_its_cloth_past_one_and_a_half_with_self_collision`; the
/// contact notebook, "2026-12-07 (twistwound)").
pub const CASCADE_HELD: u32 = 2;

/// Steps the hold after a lone cascade lasts; each cascade in a held step (the cluster
/// cascading again within its hold) doubles the hold, up to the scene's `hold_steps`. A
/// cluster that cascades once, as newton's 50 x 50 twist (2 steps a frame, `solve_stiffness`
/// 30) does in its wound window, pays a few held steps instead of `hold_steps`. The thin 64 x
/// 64 twist cascades again within every hold, so its
/// holds grow and it stays held as with a fixed 100-step hold. The length is a measured choice,
/// not a bound: a fixed hold of 2 or 8 steps lets the thin twist stretch past 1.5; starting at
/// 4, newton's twist cascades again within the short holds and pays more than with the fixed
/// 100 steps; starting at 16 covers its second cascade and holds as long as that (the contact
/// notebook, "2026-12-07 (twisthold)").
pub const CASCADE_HOLD_FIRST: u64 = 8;

/// Vertices a cascade must stop in one substep (the most of any attempt at the step) for the
/// long hold: at most [`CASCADE_MOST`] times the scene's substeps for the scene's whole
/// `hold_steps`, instead of the short hold ([`CASCADE_HELD`], [`CASCADE_HOLD_FIRST`]). A count
/// of vertices rather than a share of the cloth: what tears is the stopped region lagging the
/// cloth and pins around it, and its size in spacings, not the cloth's, sets how far that
/// stretches; a share small enough for the 256 x 256 twist (65,536 vertices) would be under
/// [`CASCADE_STOPPED`] on newton's 50 x 50 twist. Measured: newton's twist's cascades stop
/// 33-184 vertices over the windows of `benches/twist50_ensemble.py`, the thin 64 x 64 twist's
/// 33-215, and both are as cheap or as calm with the short hold; the 256 x 256 twist's first
/// two stop 4,294 and 7,605, and on it only a long hold at four times (for every cascade)
/// kept the largest stretch under 1.5 to frame 60 (the contact notebook, "2026-12-07
/// (twistsize)"). 512 lies more than twice above the small ones and eight times under the
/// large.
pub const CASCADE_LARGE: u64 = 512;

/// Particles per parallel work item of [`any_overstretched`].
const SCAN_CHUNK: usize = 8192;

/// Whether a live spring of `kinds` is longer than `limit` times its rest length: the check of
/// the force loop as a read-only pass of its own, for the newest state of a call. Parallel and
/// vectorised like the force loop (an integer OR of compares), since with one step per call it
/// runs once per step.
fn any_overstretched(
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
fn find_overstretched(
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

/// How far an edge's length may change within one substep, as a fraction of the cloth's
/// spacing, before the substep counts as not resolving the cloth's motion. Physical motion
/// changes an edge by well under a tenth of the spacing in an explicit integrator's substep
/// (0.22 at most in a whole step of the built-in scenes, the pile at two implicit steps a
/// frame); an explicit integrator past its stable step swings most edges by their whole
/// length.
const UNRESOLVED_SWING: f32 = 0.5;

/// The share of the edges that must swing that far at once. The runaway grows from round-off
/// to a quarter of the cloth's edges within a few steps; a fast drag swings the edges round
/// the grip, 1.1 to 1.4 % of a 16 x 16 or 32 x 32 cloth under an 18 m/s flick at a stable step,
/// which is why the test runs only past the stable step.
const UNRESOLVED_SHARE: f32 = 0.01;

/// Edges per parallel work item of [`unresolved_motion`].
const EDGE_CHUNK: usize = 4096;

/// Whether the substep from `x0` to `x1` resolved the cloth's motion: `None`, or the first
/// particle of the first edge that swung and the share of the edges that did (more than
/// [`UNRESOLVED_SHARE`] swung by more than [`UNRESOLVED_SWING`] of `spacing`). An edge with a
/// pinned end (`inv_mass` 0: a pin, a grip, a kinematic target) moves as the user moves it,
/// not as the integrator does, and is not counted.
///
/// Only a scene with self-collision needs this: without it an unstable integrator runs to a
/// non-finite value, which the update loop catches; with it, the pass caps every vertex's
/// motion to what keeps the cloth apart and damps the capped velocities, so the runaway cloth
/// settles into a bounded boil with no value ever infinite.
pub fn unresolved_motion(
    edges: &[[u32; 2]],
    inv_mass: &[f32],
    x0: &Vec3s,
    x1: &Vec3s,
    spacing: f32,
) -> Option<(usize, f32)> {
    let swing = UNRESOLVED_SWING * spacing;
    // No edge changes length by more than the diagonal of the box round the displacements: a
    // cloth that moves together (resting, falling, carried) costs one pass over its particles.
    if displacement_diagonal(x0, x1) <= swing {
        return None;
    }
    let swung = |&[a, b]: &[u32; 2]| {
        let (a, b) = (a as usize, b as usize);
        if inv_mass[a] == 0.0 || inv_mass[b] == 0.0 {
            return false;
        }
        let l0 = (x0.get(b) - x0.get(a)).length();
        let l1 = (x1.get(b) - x1.get(a)).length();
        (l1 - l0).abs() > swing
    };
    let count: usize = edges
        .par_chunks(EDGE_CHUNK)
        .map(|chunk| chunk.iter().filter(|e| swung(e)).count())
        .sum();
    let share = count as f32 / edges.len().max(1) as f32;
    if share <= UNRESOLVED_SHARE {
        return None;
    }
    let first = edges.iter().find(|e| swung(e)).map_or(0, |e| e[0] as usize);
    Some((first, share))
}

/// The diagonal of the bounding box of the displacements `x1 - x0`: a bound on how much any
/// distance between two particles changed.
fn displacement_diagonal(x0: &Vec3s, x1: &Vec3s) -> f32 {
    let axis = |a: &[f32], b: &[f32]| {
        let (lo, hi) = a
            .par_chunks(EDGE_CHUNK)
            .zip(b.par_chunks(EDGE_CHUNK))
            .map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (a, b)| {
                        let d = b - a;
                        (lo.min(d), hi.max(d))
                    })
            })
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |p, q| (p.0.min(q.0), p.1.max(q.1)),
            );
        (hi - lo).max(0.0)
    };
    let (dx, dy, dz) = (axis(&x0.x, &x1.x), axis(&x0.y, &x1.y), axis(&x0.z, &x1.z));
    (dx * dx + dy * dy + dz * dz).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn retrying_watchdog() -> Watchdog {
        let spec = WatchdogSpec {
            on_trouble: OnTrouble::Substep,
            ..WatchdogSpec::default()
        };
        Watchdog::new(&spec, 4)
    }

    /// After step 10 of a scene of `scene` substeps is saved by a retry at `substeps` from
    /// `reason`: the substeps steps 11 and 18 run with (held by every hold).
    fn substeps_after_rescue(reason: Trouble, substeps: u32, scene: u32) -> [u32; 2] {
        let mut watchdog = retrying_watchdog();
        let mut start = Kinematics::zeros(4);
        watchdog.rescued(10, substeps, scene, reason, &mut start, History::default());
        [11, 18].map(|step| watchdog.substeps_for(step, scene).0)
    }

    /// Steps a one-substep scene from step `from` to `to` (both included), saving the steps in
    /// `cascades` from a cascade at 4 substeps: for each step, whether it ran held.
    fn held_steps(watchdog: &mut Watchdog, from: u64, to: u64, cascades: &[u64]) -> Vec<bool> {
        let mut start = Kinematics::zeros(4);
        (from..=to)
            .map(|step| {
                let held = watchdog.substeps_for(step, 1).0 > 1;
                if cascades.contains(&step) {
                    let cascade = Trouble::Cascade { stopped: 40 };
                    watchdog.rescued(step, 4, 1, cascade, &mut start, History::default());
                }
                held
            })
            .collect()
    }

    /// The steps among `held` (numbered from `from`) that ran held, as runs `(first, last)`.
    fn runs(from: u64, held: &[bool]) -> Vec<(u64, u64)> {
        let mut runs: Vec<(u64, u64)> = Vec::new();
        for (step, _) in (from..).zip(held).filter(|(_, &h)| h) {
            match runs.last_mut() {
                Some((_, last)) if *last + 1 == step => *last = step,
                _ => runs.push((step, step)),
            }
        }
        runs
    }

    /// A cluster that cascades once is held for `CASCADE_HOLD_FIRST` steps, not for the scene's
    /// whole `hold_steps` (100); one that cascades again within its hold is held twice as long
    /// each time, up to `hold_steps`; once a hold ran out, the next cascade starts short again.
    #[test]
    fn a_lone_cascades_hold_ends_early_and_a_recurring_one_holds_longer() {
        let mut watchdog = retrying_watchdog();
        let lone = held_steps(&mut watchdog, 10, 200, &[10]);
        assert_eq!(runs(10, &lone), [(11, 18)]);
        // Cascades again in held steps 15, 30 and 60, and in each hold after: 16, 32, 64,
        // then 100 steps (the scene's hold_steps) held.
        let mut watchdog = retrying_watchdog();
        let again = [10, 15, 30, 60, 120];
        let recurring = held_steps(&mut watchdog, 10, 400, &again);
        assert_eq!(runs(10, &recurring), [(11, 220)]);
        assert_eq!(watchdog.cascade_hold, 100);
        // The hold after 120 ended at 220: a cascade after it is held short again.
        assert_eq!(
            runs(300, &held_steps(&mut watchdog, 300, 320, &[300])),
            [(301, 308)]
        );
    }

    /// A failed attempt puts the cascade's hold back as it found it, and a restored watchdog
    /// doubles the hold it was saved with.
    #[test]
    fn the_cascades_hold_is_rewound_with_a_failed_attempt_and_kept_in_a_snapshot() {
        let mut watchdog = retrying_watchdog();
        held_steps(&mut watchdog, 10, 12, &[10]);
        let mark = watchdog.mark();
        held_steps(&mut watchdog, 13, 13, &[13]);
        assert_eq!(watchdog.cascade_hold, 2 * CASCADE_HOLD_FIRST);
        watchdog.rewind(mark);
        assert_eq!(watchdog.cascade_hold, CASCADE_HOLD_FIRST);
        let mut restored = retrying_watchdog();
        restored.restore(watchdog.snapshot(), 4, 13, 1).unwrap();
        let mut longer = watchdog.snapshot();
        longer.cascade_hold = 101;
        let refused = retrying_watchdog().restore(longer, 4, 13, 1);
        assert!(
            matches!(&refused, Err(Error::InvalidValue { name, .. }) if name == "watchdog.cascade_hold"),
            "{refused:?}"
        );
        // Held from 10 to 18, cascading again in held step 13: held to 13 + 16.
        let after = |w: &mut Watchdog| runs(13, &held_steps(w, 13, 60, &[13]));
        assert_eq!(after(&mut restored), [(13, 29)]);
        assert_eq!(after(&mut watchdog), [(13, 29)]);
    }

    /// A step saved from a cascade at more than twice the scene's substeps holds twice the
    /// scene's (what a wound cloth that cascades a few steps in a hundred needs, not what one
    /// cluster's retry needed); a rescue at twice, and any other trouble's, holds what saved
    /// it.
    #[test]
    fn a_step_saved_from_a_cascade_holds_at_most_twice_the_scenes_substeps() {
        let cascade = Trouble::Cascade { stopped: 40 };
        assert_eq!(substeps_after_rescue(cascade, 4, 1), [2, 2]);
        assert_eq!(substeps_after_rescue(cascade, 8, 2), [4, 4]);
        assert_eq!(substeps_after_rescue(cascade, 2, 1), [2, 2]);
        assert_eq!(substeps_after_rescue(Trouble::NonFinite, 4, 1), [4, 4]);
    }

    /// A cascade that stopped more than `CASCADE_LARGE` vertices in a substep (the 256 x 256
    /// twist's stop thousands) holds up to `CASCADE_MOST` times the scene's substeps for the
    /// scene's whole `hold_steps`; one that stopped fewer (newton's 50 x 50 twist's stop tens)
    /// holds at most `CASCADE_HELD` times for `CASCADE_HOLD_FIRST` steps. A snapshot in the
    /// long hold restores it.
    #[test]
    fn a_large_cascade_is_held_long_at_four_times_and_a_small_one_short_at_twice() {
        // Step 10 of a 2-substep scene saved at 8 substeps from a cascade that stopped
        // `stopped`: the substeps of steps 11 to 120, and the watchdog after step 60.
        let held_after = |stopped: u64| {
            let mut watchdog = retrying_watchdog();
            let mut start = Kinematics::zeros(4);
            let cascade = Trouble::Cascade { stopped };
            watchdog.rescued(10, 8, 2, cascade, &mut start, History::default());
            let mut saved = None;
            let substeps: Vec<u32> = (11..=120)
                .map(|step| {
                    if step == 60 {
                        saved = Some(watchdog.snapshot());
                    }
                    watchdog.substeps_for(step, 2).0
                })
                .collect();
            assert_eq!(watchdog.stats().largest_cascade, stopped);
            (substeps, saved.unwrap())
        };
        // Steps 11 to 120 as runs: `(substeps, steps)`.
        let runs = |substeps: &[u32]| {
            let mut runs: Vec<(u32, usize)> = Vec::new();
            for &s in substeps {
                match runs.last_mut() {
                    Some((last, count)) if *last == s => *count += 1,
                    _ => runs.push((s, 1)),
                }
            }
            runs
        };
        let (large, saved) = held_after(CASCADE_LARGE + 1);
        assert_eq!(runs(&large), [(8, 100), (2, 10)]);
        let (small, _) = held_after(CASCADE_LARGE);
        assert_eq!(runs(&small), [(4, CASCADE_HOLD_FIRST as usize), (2, 102)]);
        // Restored at step 59 (the snapshot was taken before step 60 ran), the long hold goes
        // on at 8 substeps to step 110.
        let mut restored = retrying_watchdog();
        restored.restore(saved, 4, 59, 2).unwrap();
        let rest: Vec<u32> = (60..=120).map(|s| restored.substeps_for(s, 2).0).collect();
        assert_eq!(runs(&rest), [(8, 51), (2, 10)]);
    }
}
