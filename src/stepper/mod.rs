//! The stepper: the compiled passes, the scratch buffers and the watchdog, and the loop that
//! advances a [`State`] of a [`Model`] by whole steps.
//!
//! One step of `dt` ([`Stepper::step`]) is `substeps` substeps of `h = dt / substeps`, each
//! running the passes of `pipeline/` in the order [`Stepper::substep`] calls them. The passes
//! write into a scratch buffer, swapped with the state only when the result is finite and
//! within the watchdog's limits, so a step that goes wrong leaves the previous state in place;
//! what then happens (a retry, a rollback, an error) is in `recovery.rs`, the watchdog's memory
//! in `watchdog.rs`. A step allocates nothing, except in the self-collision pass (its candidate
//! lists are built afresh each substep).

mod pipeline;
mod recovery;
mod watchdog;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

use glam::Vec3;

pub use watchdog::{WatchdogSnapshot, WatchdogStats};

use crate::collisions::Shapes;
use crate::error::{Error, Result, Trouble};
use crate::forces::StateRef;
use crate::integrators::{History, Integrator, IntegratorKind, SolverStats};
use crate::model::Model;
use crate::parallel::{chunk_len, on_pool};
use crate::profile::Profile;
use crate::self_collision::SelfCollisionStats;
use crate::soa::Vec3s;
use crate::state::{Kinematics, State};
use pipeline::{Pipeline, Substep};
use watchdog::{Failure, HoldMark, Watchdog};

/// Requested time within this fraction of a step of the next step boundary counts as reaching
/// it, so that `advance` sums of frame times (1/60 s sixty times) land on the same whole number
/// of steps as one call with their exact total. Far above f64 rounding, far below any real
/// frame-time difference.
const ADVANCE_TOLERANCE: f64 = 1e-6;

/// Most steps one `advance` call may take: a larger request is a mistake (a frame time in ms
/// taken for s), and would hold the caller for days.
pub const MAX_ADVANCE_STEPS: u64 = u32::MAX as u64;

/// How long a run of steps goes between two asks whether to stop (`run`, `advance`):
/// short enough that Ctrl-C answers at once, long enough that asking costs nothing.
const INTERRUPT_SLICE: Duration = Duration::from_millis(20);

/// The compiled passes of a scene and the workspace to run them.
pub struct Stepper {
    pipeline: Pipeline,
    /// Where each substep writes its result; swapped with the state when it is good.
    scratch: Kinematics,
    /// Copy of the state at the start of a step, kept with several substeps (or retries).
    step_start: Option<Kinematics>,
    /// The integrator's history when the current step started, for a failed step to restore.
    start_history: History,
    /// The watchdog's hold then, likewise.
    start_hold: HoldMark,
    force: Vec3s,
    watchdog: Watchdog,
    profile: Profile,
    /// What the last panic caught in a step said (see [`Error::Internal`]).
    panic_message: Option<String>,
}

impl Stepper {
    pub fn new(model: &Model) -> Stepper {
        let scene = &model.scene;
        let n = model.grid.len();
        let mut pipeline = Pipeline::compile(scene, n);
        let watchdog = Watchdog::new(&scene.watchdog, n);
        pipeline.forces.set_stretch_limit(watchdog.stretch_limit());
        // A step with several substeps keeps its start; so may any step the watchdog retries
        // or holds at more substeps. Made here, so that a step never allocates, retried or not.
        let keeps_start = scene.substeps > 1 || watchdog.retries();
        Stepper {
            pipeline,
            scratch: Kinematics::zeros(n),
            step_start: keeps_start.then(|| Kinematics::zeros(n)),
            start_history: History::default(),
            start_hold: HoldMark::default(),
            force: Vec3s::zeros(n),
            watchdog,
            profile: Profile::default(),
            panic_message: None,
        }
    }

    // ----- stepping -------------------------------------------------------------------------

    /// Advances `state` exactly `n` steps, asking `interrupted` every few milliseconds (between
    /// whole steps) whether to stop; when it says so, returns [`Error::Interrupted`] with the
    /// state at that step boundary. The answer never changes the steps taken before it.
    pub fn run(
        &mut self,
        model: &mut Model,
        state: &mut State,
        n: u64,
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<()> {
        let mut done = 0;
        while done < n {
            // Whole steps on the thread pool for up to INTERRUPT_SLICE of wall time.
            let until = Instant::now() + INTERRUPT_SLICE;
            on_pool(|| -> Result<()> {
                loop {
                    self.step(model, state)?;
                    done += 1;
                    if done == n || Instant::now() >= until {
                        return Ok(());
                    }
                }
            })?;
            if done < n && interrupted() {
                self.judge_newest_state(model, state)?;
                return Err(Error::Interrupted { steps: done });
            }
        }
        self.judge_newest_state(model, state)
    }

    /// Adds `seconds` of requested time and runs the whole steps it covers, carrying the
    /// remainder to the next call; returns the steps taken. The result depends only on the total
    /// time requested, not on how it was split into calls. After a failed step the time not
    /// simulated stays owed, so the next call tries those steps again; an interrupted call
    /// abandons the rest of its request. At most [`MAX_ADVANCE_STEPS`] steps per call.
    pub fn advance(
        &mut self,
        model: &mut Model,
        state: &mut State,
        seconds: f64,
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<u64> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(Error::value(
                "seconds",
                format!("must be a finite number >= 0, got {seconds}"),
            ));
        }
        let dt = model.scene.dt;
        let pending = state.clock.accumulator + seconds;
        let steps = (pending / dt + ADVANCE_TOLERANCE).floor().max(0.0);
        if steps > MAX_ADVANCE_STEPS as f64 {
            return Err(Error::value(
                "seconds",
                format!(
                    "{seconds} s would take {steps:e} steps of dt = {dt} s; one call takes at \
                     most {MAX_ADVANCE_STEPS} (call it in pieces, or raise dt)"
                ),
            ));
        }
        let n = steps as u64;
        let before = state.clock.steps;
        let outcome = self.run(model, state, n, interrupted);
        // Counted from `steps`, not from the calls: a failed step can also roll back the step
        // before it (see watchdog.rs).
        let taken = match outcome {
            Err(Error::Interrupted { .. }) => n as f64,
            _ => state.clock.steps as f64 - before as f64,
        };
        // Never below zero: a request that rounded up to a whole step within the tolerance
        // leaves a remainder of minus a few ulps, which is no time owed.
        state.clock.accumulator = (pending - taken * dt).max(0.0);
        outcome.map(|()| n)
    }

    /// One step of `dt`. A step the watchdog finds wrong is put right by `recover` (a retry
    /// with more substeps, or an error); trouble found one step late rolls the previous step
    /// back too, and the loop then runs this one again.
    fn step(&mut self, model: &mut Model, state: &mut State) -> Result<()> {
        let started = Instant::now();
        let target = state.clock.steps + 1;
        while state.clock.steps < target {
            let substeps = self.begin_step(model, state);
            match self.run_substeps(model, state, substeps) {
                Ok(()) => self.end_step(state, substeps),
                Err(failure) => self.recover(model, state, failure)?,
            }
        }
        // Not undone by a later rollback: the watchdog restores states, not springs.
        self.pipeline.tear(model, state, &mut self.profile);
        self.profile.total += started.elapsed();
        Ok(())
    }

    /// One substep of length `h`, one of `substeps`, ending at `time`: the scene's passes in
    /// order. On success its result becomes the state; on failure the state is untouched.
    /// Trouble in the state the substep starts from (a spring over the watchdog's limit) is
    /// reported with `in_start_state`.
    fn substep(
        &mut self,
        model: &Model,
        state: &mut State,
        h: f32,
        time: f64,
        substeps: u32,
    ) -> std::result::Result<(), Failure> {
        let mut s = Substep::new(
            model,
            state,
            &mut self.scratch,
            (h, time),
            &mut self.profile,
        );
        let passes = &mut self.pipeline;
        passes.predict_contacts(&mut s);
        passes.judge_work(&s);
        let mut round = 0;
        let finite = loop {
            let mut finite = passes.integrate(&mut s, &mut self.force, round);
            if passes.forces.overstretched() {
                return Err(self.overstretched_start(model, &state.kin, substeps));
            }
            finite &= passes.blow_wind(&mut s);
            finite &= passes.pin_targets(&mut s);
            finite &= passes.limit_strain(&mut s);
            finite &= passes.collide(&mut s);
            finite &= passes.separate_self_contacts(&mut s);
            if !finite || !passes.hold_self_contacts(&s, round) {
                break finite;
            }
            round += 1;
        };
        if finite {
            let stopped = passes
                .self_collision
                .as_ref()
                .map_or(0, |c| c.stopped_last());
            if self
                .watchdog
                .cascade(stopped, substeps, model.scene.substeps)
            {
                return Err(Failure {
                    reason: Trouble::Cascade { stopped },
                    // No one particle is to blame: the stop spread through a cluster.
                    particle: 0,
                    in_start_state: false,
                    substeps,
                });
            }
            passes.keep_contact_passive(&mut s);
            if let Some((particle, share)) = passes.unresolved_motion(&s) {
                return Err(Failure {
                    reason: Trouble::Unresolved { share },
                    particle,
                    in_start_state: false,
                    substeps,
                });
            }
        }
        self.accept(state, finite, substeps)
    }

    /// Readies the next step and returns its substeps: the scene's, or more while the watchdog
    /// holds a rescued step's count. Keeps what a failed attempt puts back: the state (with
    /// several substeps), the integrator's history and the watchdog's hold, as they were before
    /// the attempt looked at them.
    fn begin_step(&mut self, model: &Model, state: &State) -> u32 {
        self.start_history = self.pipeline.integrator.history();
        self.start_hold = self.watchdog.mark();
        let step = state.clock.steps + 1;
        let (substeps, hold_ended) = self.watchdog.substeps_for(step, model.scene.substeps);
        if hold_ended {
            self.pipeline.integrator.reset_history(); // the substep length changes
        }
        if substeps > 1 {
            let n = model.grid.len();
            self.step_start
                .get_or_insert_with(|| Kinematics::zeros(n))
                .copy_from(&state.kin);
        }
        substeps
    }

    /// A step of `substeps` substeps went well: the watchdog keeps its start, the clock moves.
    fn end_step(&mut self, state: &mut State, substeps: u32) {
        // The step's start is in `step_start`, or with one substep in `scratch`, which the
        // substep's swap left holding it.
        let start = match self.step_start.as_mut().filter(|_| substeps > 1) {
            Some(start) => start,
            None => &mut self.scratch,
        };
        self.watchdog
            .step_completed(start, self.start_history, substeps);
        state.clock.steps += 1;
        self.profile.steps += 1;
        state.version += 1;
    }

    /// `substeps` substeps of `dt / substeps` from the current state. Trouble in the state the
    /// first one starts from is the previous step's (`in_start_state`).
    ///
    /// A panic in a pass (a bug) is caught here and becomes a [`Trouble::Panicked`] failure,
    /// with the state where the failed substep started, as for any failure: a substep changes
    /// the state only by its last act, the swap with a finished result.
    fn run_substeps(
        &mut self,
        model: &Model,
        state: &mut State,
        substeps: u32,
    ) -> std::result::Result<(), Failure> {
        let dt = model.scene.dt;
        let h = (dt / substeps as f64) as f32;
        let start = state.clock.time(dt);
        for j in 0..substeps {
            // Where moving colliders are posed: the substep's end, from the clock, so that a
            // retried or restored step sees the same poses.
            let time = start + dt * (j + 1) as f64 / substeps as f64;
            let outcome = catch_unwind(AssertUnwindSafe(|| {
                self.substep(model, state, h, time, substeps)
            }))
            .unwrap_or_else(|payload| {
                self.panic_message = Some(panic_text(payload.as_ref()));
                Err(Failure {
                    reason: Trouble::Panicked,
                    particle: 0,
                    in_start_state: false,
                    substeps,
                })
            });
            outcome.map_err(|failure| Failure {
                in_start_state: failure.in_start_state && j == 0,
                ..failure
            })?;
        }
        Ok(())
    }

    /// The spring the force loop found beyond the watchdog's limit in the state a substep of
    /// `substeps` started from, `kin`, as a failure of the step that made that state.
    fn overstretched_start(&self, model: &Model, kin: &Kinematics, substeps: u32) -> Failure {
        // The force loop and this scan run the same arithmetic, so the scan finds the spring.
        let found = self.overstretched_in(model, kin, true, substeps);
        debug_assert!(found.is_some(), "stretch watch and scan disagree");
        found.unwrap_or(Failure {
            reason: Trouble::Overstretched {
                stretch: f32::NAN,
                limit: self.watchdog.stretch_limit().unwrap_or(f32::NAN),
            },
            particle: 0,
            in_start_state: true,
            substeps,
        })
    }

    /// Swaps a good substep's result into the state; a non-finite one is a failure.
    fn accept(
        &mut self,
        state: &mut State,
        finite: bool,
        substeps: u32,
    ) -> std::result::Result<(), Failure> {
        if !finite {
            return Err(Failure {
                reason: Trouble::NonFinite,
                particle: self.scratch.first_non_finite().unwrap_or(0),
                in_start_state: false,
                substeps,
            });
        }
        std::mem::swap(&mut state.kin, &mut self.scratch);
        self.pipeline.integrator.accept();
        Ok(())
    }

    // ----- settings, reports ----------------------------------------------------------------

    pub fn integrator(&self) -> IntegratorKind {
        self.pipeline.integrator.kind()
    }

    /// Switches the integrator; the state carries over (a fresh integrator has no history).
    pub fn set_integrator(&mut self, model: &Model) {
        self.pipeline.integrator =
            Integrator::new(model.scene.integrator, model.scene.solver_settings());
        self.pipeline.stable_substep = None;
    }

    /// After a change of the substeps: history restarts, and a step keeps its start.
    pub fn substeps_changed(&mut self, model: &Model) {
        self.pipeline.integrator.reset_history();
        if model.scene.substeps > 1 && self.step_start.is_none() {
            self.step_start = Some(Kinematics::zeros(model.grid.len()));
        }
    }

    /// After a change of `dt`: history restarts, and the watchdog stops blaming the last step
    /// (taken with the old `dt`, it cannot be undone and retried with the new one).
    pub fn dt_changed(&mut self) {
        self.watchdog.forget_last_step();
        self.pipeline.integrator.reset_history();
    }

    /// After the masses changed: history restarts.
    pub fn masses_changed(&mut self) {
        self.pipeline.integrator.reset_history();
        self.pipeline.stable_substep = None;
    }

    /// Something other than a step changed the state: the watchdog must not blame (and undo)
    /// the last step for trouble in this state, nor judge it at the end of a call that takes no
    /// step.
    pub fn state_replaced(&mut self) {
        self.watchdog.state_replaced();
    }

    /// Something other than a step set positions or velocities: as [`Stepper::state_replaced`],
    /// and an integrator with history forgets it.
    pub fn motion_replaced(&mut self) {
        self.watchdog.state_replaced();
        self.pipeline.integrator.reset_history();
    }

    /// The passes a step runs, in order.
    pub fn effects(&self, model: &Model, state: &State) -> Vec<&'static str> {
        self.pipeline.effects(model, state)
    }

    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    pub fn watchdog_stats(&self) -> WatchdogStats {
        self.watchdog.stats()
    }

    pub fn solver_stats(&self) -> Option<SolverStats> {
        let halved = self.pipeline.halved;
        (self.pipeline.integrator.solver_stats()).map(|s| SolverStats { halved, ..s })
    }

    /// What the self-collision pass did, when the scene has one.
    pub fn self_collision_stats(&self) -> Option<SelfCollisionStats> {
        self.pipeline.self_collision.as_ref().map(|s| s.stats())
    }

    /// The total force on each particle of `state`, for tests and diagnostics.
    pub fn total_force(&mut self, model: &Model, state: &State) -> Vec3s {
        let mut out = Vec3s::zeros(model.grid.len());
        let at = StateRef {
            grid: model.grid,
            pos: &state.kin.pos,
            vel: &state.kin.vel,
            mass: &model.particles.mass,
            springs: &model.springs,
            mesh: model.mesh(),
        };
        let chunk = chunk_len(model.grid.len());
        self.pipeline
            .forces
            .evaluate(at, &mut out, chunk, &mut Profile::default());
        out
    }

    /// Makes the next force evaluation panic on a worker thread: a stand-in for a bug.
    #[doc(hidden)]
    pub fn inject_panic(&mut self) {
        self.pipeline.forces.inject_panic();
    }

    /// Forgets what a call interrupted by a panic may have left half-done, outside a step (a
    /// panic in a step is rolled back by `recovery.rs`): the force model's leftovers, and the
    /// watchdog's claim on the last step, since the state may no longer be the one it judged.
    pub fn after_panic(&mut self) {
        self.pipeline.forces.reset_after_panic();
        self.state_replaced();
    }

    pub fn heap_bytes(&self) -> usize {
        self.scratch.heap_bytes()
            + self.step_start.as_ref().map_or(0, Kinematics::heap_bytes)
            + self.watchdog.heap_bytes()
            + self.force.heap_bytes()
            + self.pipeline.heap_bytes()
    }

    // ----- saving and restoring -------------------------------------------------------------

    /// Where the colliders posed at `time` (s) put a particle that moved from `from` to `to` and
    /// stays.
    pub fn push_out(&self, from: Vec3, to: Vec3, time: f64) -> Vec3 {
        self.pipeline.push_out(from, to, time)
    }

    /// The deepest contact the colliders posed at `time` (s) make with a particle that moved
    /// from `from` to `to`: the outward normal and where that collider puts it.
    pub fn contact(&self, from: Vec3, to: Vec3, time: f64) -> Option<(Vec3, Vec3)> {
        self.pipeline.contact(from, to, time)
    }

    /// The scene's `[[colliders]]` (None without any), with the poses set between steps.
    pub fn shapes(&self) -> Option<&Shapes> {
        self.pipeline.shapes()
    }

    pub fn shapes_mut(&mut self) -> Option<&mut Shapes> {
        self.pipeline.shapes_mut()
    }

    /// The watchdog's memory, for a saved state.
    pub fn watchdog_snapshot(&self) -> WatchdogSnapshot {
        self.watchdog.snapshot()
    }

    /// Puts back the watchdog's memory from a saved state of `model` at step `steps`; the error
    /// names what does not fit.
    pub fn restore_watchdog(
        &mut self,
        saved: WatchdogSnapshot,
        model: &Model,
        steps: u64,
    ) -> Result<()> {
        let (n, substeps) = (model.grid.len(), model.scene.substeps);
        self.watchdog.restore(saved, n, steps, substeps)
    }

    pub fn history(&self) -> History {
        self.pipeline.integrator.history()
    }

    pub fn set_history(&mut self, history: History) {
        self.pipeline.integrator.set_history(history);
    }

    /// The integrator itself, for its kind-specific statistics.
    pub fn integrator_scheme(&self) -> &Integrator {
        &self.pipeline.integrator
    }
}

/// The message of a caught panic.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a pass panicked".into())
}
