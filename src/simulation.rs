//! The simulation: a scene compiled into a pipeline of passes, and the state it steps.
//!
//! One step of `dt` is `substeps` substeps of `h = dt / substeps`, each running these passes in
//! order, only those the scene needs:
//!
//! 1. forces (gravity, air drag, each spring family), evaluated by the integrator as often as
//!    its scheme needs;
//! 2. the integrator, writing the end-of-step state into a second buffer;
//! 3. kinematic pins (while the user drags a pinned particle);
//! 4. strain limiting (when the scene asks for it, `src/strain_limit.rs`);
//! 5. colliders (spheres, then the floor).
//!
//! The buffers are swapped only when the integrator reports a finite result, so a step that
//! diverges leaves the previous state in place.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::collisions::{Collider, Floor, FloorLevel, Spheres};
use crate::error::{check_scalar, Bound, Error, Result, Trouble};
use crate::forces::{AirDrag, ForceModel, ForceTerm, Gravity, SpringForce, Springs, StateRef};
use crate::grid::{Family, Grid, SpringKind};
use crate::integrators::{self, History, Integrator, StepContext};
use crate::interaction::InteractionState;
use crate::pins::KinematicPins;
use crate::profile::Profile;
use crate::scene::{check_substep, Plane, Scene};
use crate::snapshot::{Snapshot, WatchdogSnapshot};
use crate::soa::Vec3s;
use crate::state::{Kinematics, Particles};
use crate::strain_limit::StrainLimit;
use crate::watchdog::{any_overstretched, find_overstretched, Failure, Watchdog, WatchdogStats};

/// Fewest particles per parallel work item: below this, scheduling costs more than it saves.
const MIN_CHUNK: usize = 2048;

/// Requested time within this fraction of a step of the next step boundary counts as reaching
/// it, so that `advance` sums of frame times (1/60 s sixty times) land on the same whole number
/// of steps as one call with their exact total. Far above f64 rounding, far below any real
/// frame-time difference.
const ADVANCE_TOLERANCE: f64 = 1e-6;

/// Most steps one `advance` call may take: a larger request is a mistake (a frame time in ms
/// taken for s), and would hold the caller for days.
pub const MAX_ADVANCE_STEPS: u64 = u32::MAX as u64;

/// How long a run of steps goes between two asks whether to stop (`step_with`, `advance_with`):
/// short enough that Ctrl-C answers at once, long enough that asking costs nothing.
const INTERRUPT_SLICE: Duration = Duration::from_millis(20);

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

/// The passes a scene compiles into.
struct Pipeline {
    forces: ForceModel,
    integrator: Box<dyn Integrator>,
    /// Only when the scene asks for strain limiting.
    strain_limit: Option<StrainLimit>,
    colliders: Vec<Box<dyn Collider>>,
}

impl Pipeline {
    fn compile(scene: &Scene) -> Result<Pipeline> {
        let mut terms: Vec<Box<dyn ForceTerm>> = Vec::new();
        let g = DVec3::from(scene.gravity).as_vec3();
        if g != Vec3::ZERO {
            terms.push(Box::new(Gravity { g }));
        }
        if scene.air_drag > 0.0 {
            terms.push(Box::new(AirDrag {
                c: scene.air_drag as f32,
            }));
        }
        let cloth = &scene.cloth;
        for (family, k) in [
            (Family::Structural, cloth.k_structural),
            (Family::Shear, cloth.k_shear),
            (Family::Bend, cloth.k_bend),
        ] {
            if k > 0.0 {
                terms.push(Box::new(SpringForce {
                    family,
                    k: k as f32,
                    c: cloth.damping as f32,
                }));
            }
        }
        let mut colliders: Vec<Box<dyn Collider>> = Vec::new();
        if !scene.spheres.is_empty() {
            let floor = scene
                .floor
                .as_ref()
                .map(|f| FloorLevel((f.height + f.thickness) as f32));
            colliders.push(Box::new(Spheres::new(&scene.spheres, floor)));
        }
        if let Some(floor) = &scene.floor {
            colliders.push(Box::new(Floor {
                height: floor.height as f32,
                friction: floor.friction as f32,
                thickness: floor.thickness as f32,
            }));
        }
        Ok(Pipeline {
            forces: ForceModel::new(terms),
            integrator: integrators::by_name(&scene.integrator, scene.solver_settings())?,
            strain_limit: scene
                .strain_limit
                .as_ref()
                .map(|s| StrainLimit::new(s.max_strain as f32, s.iterations)),
            colliders,
        })
    }
}

/// Data derived from the state on request and kept until the state changes.
#[derive(Default)]
struct Derived {
    normals: Vec3s,
    normals_valid: bool,
    triangles: Vec<[u32; 3]>,
    triangles_valid: bool,
}

/// A running cloth simulation.
pub struct Simulation {
    pub(crate) scene: Scene,
    pub(crate) grid: Grid,
    pub(crate) particles: Particles,
    pub(crate) springs: Springs,
    /// The state at the current time.
    pub(crate) state: Kinematics,
    /// Where each substep writes its result; swapped with `state` when it is finite.
    scratch: Kinematics,
    /// Copy of the state at the start of a step, kept only with several substeps.
    step_start: Option<Kinematics>,
    force: Vec3s,
    pipeline: Pipeline,
    pub(crate) pins: KinematicPins,
    steps: u64,
    /// Simulated time at step `steps_base`: `time = time_base + (steps - steps_base) dt`, so
    /// that a change of `dt` changes the future, not the past, while a fixed `dt` gives times
    /// exact in the step count.
    time_base: f64,
    steps_base: u64,
    /// Requested but not yet simulated time, in s.
    accumulator: f64,
    /// What the last panic caught in a step said (see [`Error::Internal`]).
    panic_message: Option<String>,
    /// The integrator's history when the current step started, for a failed step to restore.
    step_start_history: History,
    profile: Profile,
    derived: Derived,
    topology_version: u64,
    /// Increments whenever positions change (a step, `set_positions`, a reset): caches of
    /// derived data (normals, picking structures) compare against it.
    state_version: u64,
    /// Picking trees and the grab (src/interaction.rs); built on request, never in a step.
    pub(crate) interaction: InteractionState,
    /// Trouble detection and recovery (src/watchdog.rs).
    watchdog: Watchdog,
}

impl Simulation {
    /// Builds the cloth the scene describes, at rest.
    pub fn new(scene: Scene) -> Result<Simulation> {
        scene.validate()?;
        let grid = scene.grid();
        let n = grid.len();
        let state = Kinematics {
            pos: initial_positions(&scene),
            vel: Vec3s::zeros(n),
        };
        let springs = Springs::new(grid, &state.pos);
        let mut particles = Particles::new(n, scene.particle_mass() as f32);
        for p in scene.cloth.pinned_indices() {
            particles.pinned[p] = true;
            particles.refresh(p);
        }
        let mut pipeline = Pipeline::compile(&scene)?;
        let watchdog = Watchdog::new(&scene.watchdog, n);
        pipeline.forces.set_stretch_limit(watchdog.stretch_limit());
        // A step with several substeps keeps its start; so may any step the watchdog retries
        // or holds at more substeps, and a retry keeps its own start too. Made here, so that a
        // step never allocates, retried or not.
        let retries = watchdog.retries();
        let step_start = (scene.substeps > 1 || retries).then(|| Kinematics::zeros(n));
        let mut watchdog = watchdog;
        if retries {
            watchdog.retry_start = Some(Kinematics::zeros(n));
        }
        Ok(Simulation {
            grid,
            particles,
            springs,
            scratch: Kinematics::zeros(n),
            step_start,
            state,
            force: Vec3s::zeros(n),
            pipeline,
            pins: KinematicPins::default(),
            steps: 0,
            time_base: 0.0,
            steps_base: 0,
            accumulator: 0.0,
            panic_message: None,
            step_start_history: History::default(),
            profile: Profile::default(),
            derived: Derived::default(),
            topology_version: 0,
            state_version: 0,
            interaction: InteractionState::default(),
            watchdog,
            scene,
        })
    }

    // ----- stepping -------------------------------------------------------------------------

    /// Advances exactly `n` steps of `dt`. If a step produces a non-finite state, the state
    /// from before that step is kept and [`Error::Diverged`] names the step and the particle.
    pub fn step(&mut self, n: u64) -> Result<()> {
        self.step_with(n, &mut || false)
    }

    /// [`Simulation::step`], asking `interrupted` every few milliseconds (between whole steps)
    /// whether to stop; when it says so, returns [`Error::Interrupted`] with the state at that
    /// step boundary. The answer to `interrupted` never changes the steps taken before it.
    pub fn step_with(&mut self, n: u64, interrupted: &mut dyn FnMut() -> bool) -> Result<()> {
        let mut done = 0;
        while done < n {
            done += self.run_slice(n - done)?;
            if done < n && interrupted() {
                self.judge_newest_state()?;
                return Err(Error::Interrupted { steps: done });
            }
        }
        self.judge_newest_state()
    }

    /// Up to `n` steps, stopping after the first step that ends past [`INTERRUPT_SLICE`] of
    /// wall time; returns the steps taken.
    fn run_slice(&mut self, n: u64) -> Result<u64> {
        let until = Instant::now() + INTERRUPT_SLICE;
        on_pool(|| {
            let mut taken = 0;
            while taken < n {
                self.step_once()?;
                taken += 1;
                if Instant::now() >= until {
                    break;
                }
            }
            Ok(taken)
        })
    }

    /// Adds `seconds` of requested time and runs the whole steps it covers, carrying the
    /// remainder to the next call; returns the steps taken. The result depends only on the total
    /// time requested, not on how it was split into calls. After a failed step the time not
    /// simulated stays owed, so the next call tries those steps again. At most
    /// [`MAX_ADVANCE_STEPS`] steps per call.
    pub fn advance(&mut self, seconds: f64) -> Result<u64> {
        self.advance_with(seconds, &mut || false)
    }

    /// [`Simulation::advance`], asking `interrupted` between steps as [`Simulation::step_with`]
    /// does. An interrupted call abandons the rest of its request: the steps it did not take
    /// are not owed to the next call.
    pub fn advance_with(
        &mut self,
        seconds: f64,
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<u64> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(Error::value(
                "seconds",
                format!("must be a finite number >= 0, got {seconds}"),
            ));
        }
        let dt = self.scene.dt;
        let pending = self.accumulator + seconds;
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
        let before = self.steps;
        let outcome = self.step_with(n, interrupted);
        // Counted from `steps`, not from the calls: a failed step can also roll back the step
        // before it (see src/watchdog.rs).
        let taken = match outcome {
            Err(Error::Interrupted { .. }) => n as f64,
            _ => self.steps as f64 - before as f64,
        };
        self.accumulator = pending - taken * dt;
        outcome.map(|()| n)
    }

    /// One step of `dt`, with the watchdog's recovery when it goes wrong.
    fn step_once(&mut self) -> Result<()> {
        let started = Instant::now();
        let target = self.steps + 1;
        // Recovering from trouble found one step late reruns the previous step, moving `steps`
        // back by one; the loop then runs this step again.
        while self.steps < target {
            if let Err(failure) = self.attempt_step() {
                self.recover(failure)?;
            }
        }
        self.profile.total += started.elapsed();
        Ok(())
    }

    /// Checks the newest state against the stretch limit before a call hands it back. Inside a
    /// run of steps each state is judged for free by the force loop of the step that continues
    /// from it; the last one of a call has no such step, and an unstable mode can grow tenfold
    /// in a step, so it gets this one scan (per call, not per step; only with a limit set).
    fn judge_newest_state(&mut self) -> Result<()> {
        // Without a limit, or with nothing stepped since the last judgement, nothing to do.
        if !std::mem::take(&mut self.watchdog.unjudged) {
            return Ok(());
        }
        match self.overstretched_in(&self.state, true, self.watchdog.last_substeps) {
            Some(failure) => self.recover(failure),
            None => Ok(()),
        }
    }

    /// Substeps for the next step: the scene's, or more while the watchdog holds a rescued
    /// step's count.
    fn step_substeps(&mut self) -> u32 {
        match self.watchdog.hold {
            Some((substeps, until)) if self.steps + 1 < until => {
                self.watchdog.stats.held_steps += 1;
                substeps
            }
            Some(_) => {
                self.watchdog.hold = None;
                self.pipeline.integrator.reset_history(); // the substep length changes
                self.scene.substeps
            }
            None => self.scene.substeps,
        }
    }

    /// One step. On failure nothing of the failed substep is kept: the state is where that
    /// substep started, and with several substeps the step's start is in `step_start`.
    fn attempt_step(&mut self) -> std::result::Result<(), Failure> {
        let substeps = self.step_substeps();
        self.step_start_history = self.pipeline.integrator.history();
        if substeps > 1 {
            let n = self.grid.len();
            self.step_start
                .get_or_insert_with(|| Kinematics::zeros(n))
                .copy_from(&self.state);
        }
        self.run_substeps(substeps)?;
        // The step's start state is in `step_start`, or with one substep in `scratch`, which
        // the substep's swap left holding it.
        let history = self.step_start_history;
        match self.step_start.as_mut().filter(|_| substeps > 1) {
            Some(start) => self.watchdog.step_completed(start, history, substeps),
            None => self
                .watchdog
                .step_completed(&mut self.scratch, history, substeps),
        }
        self.steps += 1;
        self.profile.steps += 1;
        self.state_stepped();
        Ok(())
    }

    /// `substeps` substeps of `dt / substeps` from the current state. Trouble in the state the
    /// first one starts from is the previous step's (`in_start_state`).
    ///
    /// A panic in a pass (a bug) is caught here and becomes a [`Trouble::Panicked`] failure,
    /// with the state where the failed substep started, as for any failure: a substep changes
    /// `state` only by its last act, the swap with a finished result.
    fn run_substeps(&mut self, substeps: u32) -> std::result::Result<(), Failure> {
        let h = (self.scene.dt / substeps as f64) as f32;
        for j in 0..substeps {
            let outcome = catch_unwind(AssertUnwindSafe(|| self.substep(h, substeps)))
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

    /// One substep of length `h`, one of `substeps`. On success its result becomes `state`; on
    /// failure `state` is untouched. Trouble in the state the substep starts from (a spring over
    /// the watchdog's limit) is reported with `in_start_state`.
    fn substep(&mut self, h: f32, substeps: u32) -> std::result::Result<(), Failure> {
        let chunk = chunk_len(self.grid.len());
        let pipeline = &mut self.pipeline;
        let started = Instant::now();
        let forces_before = self.profile.force_time;
        pipeline.forces.arm_stretch_watch();
        let mut ctx = StepContext {
            grid: self.grid,
            current: &self.state,
            next: &mut self.scratch,
            particles: &self.particles,
            springs: &self.springs,
            forces: &mut pipeline.forces,
            force: &mut self.force,
            chunk,
            profile: &mut self.profile,
        };
        let finite = pipeline.integrator.step(h, &mut ctx);
        let own_time = started
            .elapsed()
            .saturating_sub(self.profile.force_time - forces_before);
        self.profile.add(pipeline.integrator.name(), own_time);
        if pipeline.forces.overstretched() {
            // The force loop and this scan run the same arithmetic, so the scan finds the spring.
            let found = self.overstretched_in(&self.state, true, substeps);
            debug_assert!(found.is_some(), "stretch watch and scan disagree");
            return Err(found.unwrap_or(Failure {
                reason: Trouble::Overstretched {
                    stretch: f32::NAN,
                    limit: self.watchdog.stretch_limit().unwrap_or(f32::NAN),
                },
                particle: 0,
                in_start_state: true,
                substeps,
            }));
        }
        if !(finite && self.after_integration(h, chunk)) {
            return Err(Failure {
                reason: Trouble::NonFinite,
                particle: first_non_finite(&self.scratch).unwrap_or(0),
                in_start_state: false,
                substeps,
            });
        }
        std::mem::swap(&mut self.state, &mut self.scratch);
        self.pipeline.integrator.accept();
        Ok(())
    }

    /// The passes after the integrator, on `scratch`: kinematic pins, strain limiting,
    /// colliders. Returns whether what they wrote is finite; they write few values (a drag,
    /// contacts, limited springs), so checking costs next to nothing.
    fn after_integration(&mut self, h: f32, chunk: usize) -> bool {
        let mut finite = true;
        if !self.pins.is_empty() {
            let t = Instant::now();
            finite &= self.pins.apply(h, &self.state, &mut self.scratch);
            self.profile.add(KinematicPins::NAME, t.elapsed());
        }
        // After the pins, so that the limit pulls the cloth after a dragged particle rather
        // than back to where it was; before the colliders, so that contacts have the last word.
        if let Some(limit) = &mut self.pipeline.strain_limit {
            let t = Instant::now();
            let (grid, springs, particles) = (self.grid, &self.springs, &self.particles);
            finite &= limit
                .apply(grid, springs, particles, &mut self.scratch, chunk)
                .finite;
            self.profile.add(StrainLimit::NAME, t.elapsed());
        }
        for collider in &self.pipeline.colliders {
            let t = Instant::now();
            finite &= collider.resolve(&self.state, &mut self.scratch, &self.particles, chunk);
            self.profile.add(collider.name(), t.elapsed());
        }
        finite
    }

    /// The first spring of `state` beyond the watchdog's stretch limit, as a failure of a step
    /// of `substeps` substeps. A full pass over the springs: for the newest state of a call,
    /// the end of a retried step and the trouble path.
    fn overstretched_in(
        &self,
        state: &Kinematics,
        in_start_state: bool,
        substeps: u32,
    ) -> Option<Failure> {
        let limit = self.watchdog.stretch_limit()?;
        let kinds = self.pipeline.forces.spring_kinds();
        if !any_overstretched(self.grid, &self.springs, &state.pos, kinds, limit) {
            return None;
        }
        let (particle, stretch) =
            find_overstretched(self.grid, &self.springs, &state.pos, kinds, limit)?;
        Some(Failure {
            reason: Trouble::Overstretched { stretch, limit },
            particle,
            in_start_state,
            substeps,
        })
    }

    /// Puts back the good state before the step to blame, then retries that step or reports
    /// it, as the scene asks.
    fn recover(&mut self, mut failure: Failure) -> Result<()> {
        if failure.reason == Trouble::Panicked {
            return Err(self.recover_from_panic(failure.substeps));
        }
        self.watchdog.stats.caught += 1;
        if failure.in_start_state {
            // The last completed step produced a state beyond the limit: undo it, and the
            // integrator's history with it. It ran with the substeps it ran with.
            failure.substeps = self.watchdog.last_substeps;
            match self.watchdog.previous.as_ref() {
                Some(previous) if self.watchdog.previous_valid => {
                    self.state.copy_from(previous);
                    self.pipeline
                        .integrator
                        .set_history(self.watchdog.previous_history);
                    self.watchdog.previous_valid = false;
                    self.steps -= 1;
                }
                // The state came from the user or the scene, not from a step: nothing to undo
                // or retry, and the state stays as it is.
                _ => return Err(diverged(self.steps + 1, failure)),
            }
        } else {
            self.back_to_step_start(failure.substeps);
        }
        self.state_stepped();
        // The restored state was judged good; a call that takes no step must not judge again.
        self.watchdog.unjudged = false;
        let step = self.steps + 1;
        if self.watchdog.retries() {
            self.retry_step(step, failure)
        } else {
            Err(diverged(step, failure))
        }
    }

    /// Reruns step `step` from the current state with 2, 4, ... times the failed attempt's
    /// substeps, up to the watchdog's `max_substeps`, judging each attempt's end state too: a
    /// retried step must not hand on a state the next step would reject. On failure the state
    /// is back where it started.
    fn retry_step(&mut self, step: u64, failure: Failure) -> Result<()> {
        let n = self.grid.len();
        let mut start = self
            .watchdog
            .retry_start
            .take()
            .unwrap_or_else(|| Kinematics::zeros(n));
        start.copy_from(&self.state);
        let mut last = failure;
        let mut substeps = failure.substeps.saturating_mul(2);
        let mut rescued = false;
        let mut history = History::default();
        while substeps <= self.watchdog.spec.max_substeps {
            self.pipeline.integrator.reset_history();
            history = self.pipeline.integrator.history();
            self.watchdog.stats.retry_substeps += substeps as u64;
            let attempt = self.run_substeps(substeps).and_then(|()| {
                match self.overstretched_in(&self.state, false, substeps) {
                    Some(failure) => Err(failure),
                    None => Ok(()),
                }
            });
            match attempt {
                Ok(()) => {
                    rescued = true;
                    break;
                }
                Err(f) if f.reason == Trouble::Panicked => {
                    self.state.copy_from(&start);
                    self.watchdog.retry_start = Some(start);
                    self.step_start_history = History::default();
                    self.pipeline.integrator.reset_history();
                    return Err(self.recover_from_panic(1));
                }
                Err(f) => {
                    last = f;
                    self.state.copy_from(&start);
                }
            }
            substeps = substeps.saturating_mul(2);
        }
        // The substep length changes again after the retry.
        self.pipeline.integrator.reset_history();
        self.state_stepped();
        let result = if rescued {
            let stats = &mut self.watchdog.stats;
            stats.retried += 1;
            stats.max_substeps_used = stats.max_substeps_used.max(substeps);
            let hold = self.watchdog.spec.hold_steps as u64;
            self.watchdog.hold = (hold > 0).then_some((substeps, step + 1 + hold));
            self.watchdog.step_completed(&mut start, history, substeps);
            self.steps = step;
            self.profile.steps += 1;
            Ok(())
        } else {
            Err(diverged(step, last))
        };
        self.watchdog.retry_start = Some(start);
        result
    }

    /// After a failed attempt at the current step with `substeps` substeps: the state and the
    /// integrator's history as they were when the step started. With one substep the state is
    /// already there (the failed substep never swapped its result in).
    fn back_to_step_start(&mut self, substeps: u32) {
        if substeps > 1 {
            if let Some(start) = &self.step_start {
                self.state.copy_from(start);
            }
        }
        self.pipeline
            .integrator
            .set_history(self.step_start_history);
    }

    /// A step of `substeps` substeps panicked: back to its start, every cache that the step
    /// may have left half-written dropped, and the panic reported as [`Error::Internal`].
    fn recover_from_panic(&mut self, substeps: u32) -> Error {
        self.back_to_step_start(substeps);
        self.after_panic();
        Error::Internal {
            message: self
                .panic_message
                .take()
                .unwrap_or_else(|| "a pass panicked".into()),
        }
    }

    /// Makes the next force evaluation panic on a worker thread: a stand-in for a bug, to test
    /// that a panic is caught, rolled back and reported as [`Error::Internal`].
    #[doc(hidden)]
    pub fn inject_panic(&mut self) {
        self.pipeline.forces.inject_panic();
    }

    /// Makes the simulation usable again after a panic caught anywhere in it (the Python
    /// binding's last resort): derived data and picking trees are dropped and rebuilt on
    /// request, the watchdog forgets the last step, and the force model starts its next
    /// evaluation afresh. The state itself is whatever the interrupted call left, which every
    /// call keeps consistent by checking its input before changing anything.
    pub fn after_panic(&mut self) {
        self.pipeline.forces.reset_after_panic();
        self.interaction.drop_caches();
        self.invalidate_state();
        self.invalidate_topology();
        self.derived = Derived::default();
    }

    /// A step changed the state: caches of derived data are stale.
    fn state_stepped(&mut self) {
        self.derived.normals_valid = false;
        self.state_version += 1;
    }

    /// Something other than a step changed the state: caches are stale, and the watchdog must
    /// not blame (and undo) the last step for trouble in this state.
    pub(crate) fn invalidate_state(&mut self) {
        self.state_stepped();
        self.watchdog.previous_valid = false;
        // A state the user set is judged when a step starts from it, not at the end of a call
        // that took no step.
        self.watchdog.unjudged = false;
    }

    pub(crate) fn invalidate_topology(&mut self) {
        self.derived.triangles_valid = false;
        self.topology_version += 1;
    }

    // ----- reading the state ----------------------------------------------------------------

    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The scene, with the run-time settings (integrator, substeps) as they are now.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn positions(&self) -> &Vec3s {
        &self.state.pos
    }

    pub fn velocities(&self) -> &Vec3s {
        &self.state.vel
    }

    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    pub fn springs(&self) -> &Springs {
        &self.springs
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Simulated time in s: the time of every step taken, each with the `dt` it was taken
    /// with; exactly `steps * dt` while `dt` has not changed.
    pub fn time(&self) -> f64 {
        self.time_base + (self.steps as f64 - self.steps_base as f64) * self.scene.dt
    }

    pub fn dt(&self) -> f64 {
        self.scene.dt
    }

    /// The passes a step runs, in order.
    pub fn effects(&self) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = self.pipeline.forces.names().collect();
        out.push(self.pipeline.integrator.name());
        if !self.pins.is_empty() {
            out.push(KinematicPins::NAME);
        }
        if self.pipeline.strain_limit.is_some() {
            out.push(StrainLimit::NAME);
        }
        out.extend(self.pipeline.colliders.iter().map(|c| c.name()));
        out
    }

    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The largest step `dt` (s) at which the current integrator is estimated to stay stable
    /// with the current substeps, or None when any step is (implicit Euler, or no springs).
    /// [`Scene::stable_dt`] with the lightest moving particle's mass, which bounds the stiffest
    /// mode also when masses differ (`set_masses`).
    pub fn stable_dt(&self) -> Option<f64> {
        let m = (0..self.grid.len())
            .filter(|&p| self.particles.is_dynamic(p))
            .map(|p| self.particles.mass[p] as f64)
            .fold(f64::INFINITY, f64::min);
        if !m.is_finite() {
            return None;
        }
        crate::scene::stable_substep(&self.scene, self.pipeline.integrator.name(), m)
            .map(|h| h * self.scene.substeps as f64)
    }

    /// What the watchdog caught and retried so far.
    pub fn watchdog_stats(&self) -> WatchdogStats {
        self.watchdog.stats
    }

    /// Statistics of the linear solver, when the integrator solves one (`implicit_euler`).
    pub fn solver_stats(&self) -> Option<crate::integrators::SolverStats> {
        self.pipeline.integrator.solver_stats()
    }

    /// Increments whenever positions change.
    pub fn state_version(&self) -> u64 {
        self.state_version
    }

    /// Increments whenever the triangle list changes (a cut).
    pub fn topology_version(&self) -> u64 {
        self.topology_version
    }

    /// Energy of the current state.
    pub fn energy(&self) -> Energy {
        let g = DVec3::from(self.scene.gravity);
        let (pos, vel, particles) = (&self.state.pos, &self.state.vel, &self.particles);
        let [kinetic, gravitational] = fixed_sum(self.grid.len(), |p| {
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
        let mut elastic = 0.0;
        for family in Family::ALL {
            let k = self.family_stiffness(family);
            if k == 0.0 {
                continue;
            }
            for kind in family.kinds() {
                self.springs.for_each(self.grid, kind, |a, b, rest| {
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

    fn family_stiffness(&self, family: Family) -> f64 {
        let cloth = &self.scene.cloth;
        match family {
            Family::Structural => cloth.k_structural,
            Family::Shear => cloth.k_shear,
            Family::Bend => cloth.k_bend,
        }
    }

    /// Per particle, the largest relative stretch `l / L - 1` of the live springs of the active
    /// families that touch it (0 for a particle with none).
    pub fn spring_strain(&self) -> Vec<f32> {
        let mut strain = vec![0.0f32; self.grid.len()];
        let pos = &self.state.pos;
        for family in Family::ALL
            .into_iter()
            .filter(|&f| self.family_stiffness(f) > 0.0)
        {
            for kind in family.kinds() {
                self.springs.for_each(self.grid, kind, |a, b, rest| {
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

    /// The largest relative stretch `l / L - 1` over all live springs.
    pub fn max_stretch(&self) -> f32 {
        self.spring_strain().into_iter().fold(0.0, f32::max)
    }

    /// The triangles of the live cloth, two per grid cell, computed on first request after a
    /// change of topology.
    pub fn triangles(&mut self) -> &[[u32; 3]] {
        if !self.derived.triangles_valid {
            self.derived.triangles = self.grid.triangles(&self.particles.alive);
            self.derived.triangles_valid = true;
        }
        &self.derived.triangles
    }

    /// Unit vertex normals (area-weighted average of the incident live triangles), computed on
    /// first request after the state changed. A particle with no live triangle gets `e_i x e_j`
    /// of the starting plane.
    pub fn normals(&mut self) -> &Vec3s {
        if !self.derived.normals_valid {
            let fallback = plane_axes(self.scene.cloth.plane);
            let fallback = fallback.0.cross(fallback.1);
            let (grid, pos, alive) = (self.grid, &self.state.pos, &self.particles.alive);
            let normals = &mut self.derived.normals;
            if normals.len() != grid.len() {
                *normals = Vec3s::zeros(grid.len());
            }
            let chunk = chunk_len(grid.len());
            normals
                .par_chunks_mut(chunk)
                .enumerate()
                .for_each(|(c, mut out)| {
                    for i in 0..out.len() {
                        let n = vertex_normal(grid, pos, alive, c * chunk + i);
                        out.set(i, n.try_normalize().unwrap_or(fallback));
                    }
                });
            self.derived.normals_valid = true;
        }
        &self.derived.normals
    }

    /// Heap memory held by the simulation, in bytes: state, scratch, springs, force tables,
    /// derived data and the picking trees once built.
    pub fn memory_bytes(&self) -> usize {
        self.state.heap_bytes()
            + self.scratch.heap_bytes()
            + self.step_start.as_ref().map_or(0, Kinematics::heap_bytes)
            + self.watchdog.heap_bytes()
            + self
                .pipeline
                .strain_limit
                .as_ref()
                .map_or(0, StrainLimit::heap_bytes)
            + self.force.heap_bytes()
            + self.pipeline.forces.heap_bytes()
            + self.particles.heap_bytes()
            + self.springs.heap_bytes()
            + self.derived.normals.heap_bytes()
            + self.derived.triangles.capacity() * size_of::<[u32; 3]>()
            + self.interaction.heap_bytes()
    }

    // ----- changing the state ---------------------------------------------------------------

    /// Replaces every position (m). Rejects non-finite values, changing nothing.
    pub fn set_positions(&mut self, pos: &Vec3s) -> Result<()> {
        self.check_state_array("positions", pos)?;
        self.state.pos.copy_from(pos);
        self.invalidate_state();
        self.pipeline.integrator.reset_history();
        Ok(())
    }

    /// Replaces every velocity (m/s). Rejects non-finite values, changing nothing. Particles
    /// that cannot move (pinned, cut) keep zero velocity.
    pub fn set_velocities(&mut self, vel: &Vec3s) -> Result<()> {
        self.check_state_array("velocities", vel)?;
        self.state.vel.copy_from(vel);
        for p in 0..self.grid.len() {
            if !self.particles.is_dynamic(p) {
                self.state.vel.set(p, Vec3::ZERO);
            }
        }
        self.invalidate_state();
        self.pipeline.integrator.reset_history();
        Ok(())
    }

    /// Replaces every particle's mass (kg, each finite and > 0, within float32), for cloths of
    /// uneven weight: a weighted hem, a heavy patch. Rejects a bad value, changing nothing.
    /// Pinned and cut particles keep their new mass for when they move again. The explicit
    /// integrators' stable step follows the lightest particle (`stable_dt`).
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
            self.particles.mass[p] = m as f32;
            self.particles.refresh(p);
        }
        self.pipeline.integrator.reset_history();
        Ok(())
    }

    fn check_state_array(&self, name: &str, values: &Vec3s) -> Result<()> {
        let n = self.grid.len();
        if values.len() != n || values.y.len() != n || values.z.len() != n {
            return Err(Error::value(
                name,
                format!("must hold {n} vectors, got {}", values.len()),
            ));
        }
        if let Some(p) = (0..n).find(|&p| !values.get(p).is_finite()) {
            return Err(Error::value(
                name,
                format!("row {p} is not finite: {:?}", values.get(p).to_array()),
            ));
        }
        Ok(())
    }

    pub(crate) fn check_index(&self, name: &str, index: i64) -> Result<usize> {
        let n = self.grid.len();
        if (0..n as i64).contains(&index) {
            Ok(index as usize)
        } else {
            Err(Error::index(name, index, n))
        }
    }

    /// Pins particle `index`: it stops and integration no longer moves it. With a `target`
    /// (m), the particle moves there over the next step and stays (a kinematic pin); calling
    /// again with a new target drags it.
    pub fn pin(&mut self, index: i64, target: Option<Vec3>) -> Result<()> {
        let p = self.check_index("index", index)?;
        if let Some(t) = target {
            if !t.is_finite() {
                return Err(Error::value(
                    "target",
                    format!("must be finite, got {:?}", t.to_array()),
                ));
            }
        }
        if !self.particles.alive[p] {
            return Err(Error::value(
                "index",
                format!("particle {p} was cut and cannot be pinned"),
            ));
        }
        self.particles.pinned[p] = true;
        self.particles.refresh(p);
        match target {
            Some(t) => self.pins.set(p, t),
            None => {
                self.pins.remove(p);
                self.state.vel.set(p, Vec3::ZERO);
                self.invalidate_state();
            }
        }
        Ok(())
    }

    /// Releases particle `index`; it keeps its current velocity. Unpinning a particle that is
    /// not pinned does nothing.
    pub fn unpin(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        self.particles.pinned[p] = false;
        self.particles.refresh(p);
        self.pins.remove(p);
        Ok(())
    }

    /// Removes particle `index` and every spring touching it from the cloth; its triangles
    /// leave the mesh. Cutting a particle twice does nothing the second time.
    pub fn cut(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        if !self.particles.alive[p] {
            return Ok(());
        }
        self.particles.alive[p] = false;
        self.particles.pinned[p] = false;
        self.particles.refresh(p);
        self.pins.remove(p);
        self.state.vel.set(p, Vec3::ZERO);
        self.springs.remove_particle(self.grid, p);
        self.invalidate_topology();
        self.invalidate_state();
        Ok(())
    }

    // ----- saving and restoring ---------------------------------------------------------------

    /// The whole state, to save or send elsewhere; [`Simulation::restore`] continues it bit for
    /// bit.
    pub fn snapshot(&self) -> Snapshot {
        let watchdog = &self.watchdog;
        let previous = watchdog
            .previous
            .as_ref()
            .filter(|_| watchdog.previous_valid)
            .map(|k| (k.pos.clone(), k.vel.clone(), watchdog.previous_history));
        Snapshot {
            scene: self.scene.clone(),
            positions: self.state.pos.clone(),
            velocities: self.state.vel.clone(),
            masses: self.particles.mass.clone(),
            pinned: self.particles.pinned.clone(),
            alive: self.particles.alive.clone(),
            springs: SpringKind::ALL.map(|kind| {
                self.springs.active[kind.index()]
                    .iter()
                    .map(|&a| a != 0.0)
                    .collect()
            }),
            targets: self.pins.targets().to_vec(),
            grab: self.interaction.grab_record(),
            pick_radius: self.interaction.pick_radius_setting(),
            pick_strategy: self.pick_strategy(),
            steps: self.steps,
            time_base: self.time_base,
            steps_base: self.steps_base,
            accumulator: self.accumulator,
            history: self.pipeline.integrator.history(),
            watchdog: WatchdogSnapshot {
                previous,
                unjudged: watchdog.unjudged,
                last_substeps: watchdog.last_substeps,
                hold: watchdog.hold,
                stats: watchdog.stats,
            },
            state_version: self.state_version,
            topology_version: self.topology_version,
        }
    }

    /// A simulation continuing `snapshot` exactly. Every part is checked against the scene
    /// (lengths, finite values, masses, indices, springs the grid has); a bad one is named.
    pub fn restore(snapshot: Snapshot) -> Result<Simulation> {
        let mut sim = Simulation::new(snapshot.scene)?;
        let n = sim.grid.len();
        sim.check_state_array("positions", &snapshot.positions)?;
        sim.check_state_array("velocities", &snapshot.velocities)?;
        let masses: Vec<f64> = snapshot.masses.iter().map(|&m| m as f64).collect();
        sim.set_masses(&masses)?;
        for (name, flags) in [("pinned", &snapshot.pinned), ("alive", &snapshot.alive)] {
            if flags.len() != n {
                return Err(Error::value(
                    name,
                    format!("must hold {n} flags, got {}", flags.len()),
                ));
            }
        }
        for kind in SpringKind::ALL {
            let flags = &snapshot.springs[kind.index()];
            let name = format!("springs[{}]", kind.index());
            if flags.len() != n {
                return Err(Error::value(
                    name,
                    format!("must hold {n} flags, got {}", flags.len()),
                ));
            }
            if let Some(p) = (0..n).find(|&p| flags[p] && sim.grid.partner(p, kind).is_none()) {
                return Err(Error::value(
                    name,
                    format!("particle {p} has no partner for a live spring of {kind:?}"),
                ));
            }
        }
        for &(p, target) in &snapshot.targets {
            if p >= n || !snapshot.pinned[p] || !target.is_finite() {
                return Err(Error::value(
                    "targets",
                    format!("({p}, {target}) must be a pinned particle and a finite target"),
                ));
            }
        }
        if let Some((p, _, previous)) = snapshot.grab {
            if p >= n || !snapshot.alive[p] || previous.is_some_and(|t| !t.is_finite()) {
                return Err(Error::value(
                    "grab",
                    format!("particle {p} must be a live particle"),
                ));
            }
        }
        if let Some(r) = snapshot.pick_radius {
            sim.set_pick_radius(r as f64)?;
        }
        for (name, x) in [
            ("time_base", snapshot.time_base),
            ("accumulator", snapshot.accumulator),
        ] {
            check_scalar(name, x, Bound::NonNegative)?;
        }
        let previous = snapshot.watchdog.previous;
        if previous.is_some() && sim.watchdog.previous.is_none() {
            return Err(Error::value(
                "watchdog",
                "a saved previous state needs a scene with watchdog.max_stretch",
            ));
        }
        if snapshot.watchdog.last_substeps == 0 {
            return Err(Error::value(
                "watchdog",
                "last_substeps must be an integer >= 1, got 0",
            ));
        }

        sim.state.pos.copy_from(&snapshot.positions);
        sim.state.vel.copy_from(&snapshot.velocities);
        sim.particles.pinned = snapshot.pinned;
        sim.particles.alive = snapshot.alive;
        for p in 0..n {
            sim.particles.refresh(p);
        }
        for kind in SpringKind::ALL {
            let active = &mut sim.springs.active[kind.index()];
            for (slot, &live) in snapshot.springs[kind.index()].iter().enumerate() {
                active[slot] = if live { 1.0 } else { 0.0 };
            }
        }
        for (p, target) in snapshot.targets {
            sim.pins.set(p, target);
        }
        sim.interaction.set_grab_record(snapshot.grab);
        sim.set_pick_strategy(snapshot.pick_strategy);
        sim.steps = snapshot.steps;
        sim.time_base = snapshot.time_base;
        sim.steps_base = snapshot.steps_base;
        sim.accumulator = snapshot.accumulator;
        sim.pipeline.integrator.set_history(snapshot.history);
        let watchdog = &mut sim.watchdog;
        if let (Some((pos, vel, history)), Some(buffer)) = (previous, watchdog.previous.as_mut()) {
            let saved = Kinematics { pos, vel };
            if saved.pos.len() != n || saved.vel.len() != n || first_non_finite(&saved).is_some() {
                return Err(Error::value(
                    "watchdog",
                    format!("the previous state must hold {n} finite positions and velocities"),
                ));
            }
            buffer.copy_from(&saved);
            watchdog.previous_history = history;
            watchdog.previous_valid = true;
        }
        watchdog.unjudged = snapshot.watchdog.unjudged;
        watchdog.last_substeps = snapshot.watchdog.last_substeps;
        watchdog.hold = snapshot.watchdog.hold;
        watchdog.stats = snapshot.watchdog.stats;
        sim.state_version = snapshot.state_version;
        sim.topology_version = snapshot.topology_version;
        Ok(sim)
    }

    /// Switches the integrator at run time; the state carries over.
    pub fn set_integrator(&mut self, name: &str) -> Result<()> {
        self.pipeline.integrator = integrators::by_name(name, self.scene.solver_settings())?;
        self.scene.integrator = name.to_string();
        Ok(())
    }

    /// Changes the number of substeps per step (>= 1).
    pub fn set_substeps(&mut self, substeps: i64) -> Result<()> {
        if !(1..=u32::MAX as i64).contains(&substeps) {
            return Err(Error::value(
                "substeps",
                format!("must be an integer >= 1, got {substeps}"),
            ));
        }
        check_substep("substeps", self.scene.dt, substeps as u32)?;
        self.scene.substeps = substeps as u32;
        self.pipeline.integrator.reset_history();
        if substeps > 1 && self.step_start.is_none() {
            self.step_start = Some(Kinematics::zeros(self.grid.len()));
        }
        Ok(())
    }

    /// Changes the time step (s, > 0); the carried remainder of `advance` is kept in seconds.
    pub fn set_dt(&mut self, dt: f64) -> Result<()> {
        check_scalar("dt", dt, Bound::Positive)?;
        check_substep("dt", dt, self.scene.substeps)?;
        // The steps so far keep the time they took; a step taken with the old dt cannot be
        // undone and retried with the new one, so the watchdog stops blaming it.
        (self.time_base, self.steps_base) = (self.time(), self.steps);
        self.watchdog.previous_valid = false;
        self.scene.dt = dt;
        self.pipeline.integrator.reset_history();
        Ok(())
    }

    /// Back to the scene's starting state (keeping the run-time integrator and substeps).
    pub fn reset(&mut self) -> Result<()> {
        // The versions keep counting up, so a cache stamped before the reset never matches.
        let (topology, state) = (self.topology_version + 1, self.state_version + 1);
        *self = Simulation::new(self.scene.clone())?;
        self.topology_version = topology;
        self.state_version = state;
        Ok(())
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

fn diverged(step: u64, failure: Failure) -> Error {
    Error::Diverged {
        step,
        particle: failure.particle,
        reason: failure.reason,
        substeps: failure.substeps,
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

/// Runs `f` on a thread of rayon's pool, so that the parallel loops of every pass inside it
/// fork from a worker (cheap) instead of each being injected into the pool from outside (a
/// cross-thread wake-up per pass, which dominates the step of a small cloth).
fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// Particles per parallel work item for `n` particles: about four items per thread, so the
/// load balances, but never so small that scheduling dominates.
fn chunk_len(n: usize) -> usize {
    let per_thread = n.div_ceil(4 * rayon::current_num_threads());
    per_thread.max(MIN_CHUNK)
}

fn plane_axes(plane: Plane) -> (Vec3, Vec3) {
    match plane {
        Plane::Xz => (Vec3::X, Vec3::Z),
        Plane::Xy => (Vec3::X, Vec3::Y),
    }
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

/// Sum of the area-weighted normals of the live triangles around particle `p`; see
/// [`Grid::triangles`] for the split of each cell into `(a, b, d)` and `(a, d, c)`.
fn vertex_normal(grid: Grid, pos: &Vec3s, alive: &[bool], p: usize) -> Vec3 {
    let (i, j) = grid.coords(p);
    let mut sum = Vec3::ZERO;
    let mut add = |tri: [usize; 3]| {
        if tri.iter().all(|&q| alive[q]) {
            let (a, b, c) = (pos.get(tri[0]), pos.get(tri[1]), pos.get(tri[2]));
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
        let d = c + 1;
        if p != c {
            add([a, b, d]); // p is a, b or d
        }
        if p != b {
            add([a, d, c]); // p is a, d or c
        }
    }
    sum
}

/// The first particle whose position or velocity is not finite.
fn first_non_finite(state: &Kinematics) -> Option<usize> {
    (0..state.pos.len()).find(|&p| !(state.pos.get(p).is_finite() && state.vel.get(p).is_finite()))
}

/// Total force on each particle of the current state, for tests and diagnostics.
pub fn total_force(sim: &mut Simulation) -> Vec3s {
    let mut out = Vec3s::zeros(sim.grid.len());
    let state = StateRef {
        grid: sim.grid,
        pos: &sim.state.pos,
        vel: &sim.state.vel,
        mass: &sim.particles.mass,
        springs: &sim.springs,
    };
    let mut scratch = Profile::default();
    let chunk = chunk_len(sim.grid.len());
    sim.pipeline
        .forces
        .evaluate(state, &mut out, chunk, &mut scratch);
    out
}
