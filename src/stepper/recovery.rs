//! What a step does when it goes wrong: find the step to blame, put back the good state before
//! it, and retry it with more substeps or report it, as the scene's watchdog asks. The noticing
//! and the watchdog's memory are described in `watchdog.rs`.

use super::watchdog::{any_overstretched, find_overstretched, Failure};
use super::Stepper;
use crate::error::{Error, Result, Trouble};
use crate::integrators::History;
use crate::model::Model;
use crate::snapshot::WatchdogSnapshot;
use crate::state::{Kinematics, State};

impl Stepper {
    /// Checks the newest state against the stretch limit before a call hands it back. Inside a
    /// run of steps each state is judged for free by the force loop of the step that continues
    /// from it; the last one of a call has no such step, and an unstable mode can grow tenfold
    /// in a step, so it gets this one scan (per call, not per step; only with a limit set).
    pub(super) fn judge_newest_state(&mut self, model: &Model, state: &mut State) -> Result<()> {
        // Without a limit, or with nothing stepped since the last judgement, nothing to do.
        if !std::mem::take(&mut self.watchdog.unjudged) {
            return Ok(());
        }
        let last = self.watchdog.last_substeps;
        match self.overstretched_in(model, &state.kin, true, last) {
            Some(failure) => self.recover(model, state, failure),
            None => Ok(()),
        }
    }

    /// The first spring of `kin` beyond the watchdog's stretch limit, as a failure of a step of
    /// `substeps` substeps. A full pass over the springs: for the newest state of a call, the
    /// end of a retried step and the trouble path.
    pub(super) fn overstretched_in(
        &self,
        model: &Model,
        kin: &Kinematics,
        in_start_state: bool,
        substeps: u32,
    ) -> Option<Failure> {
        let limit = self.watchdog.stretch_limit()?;
        let kinds = self.pipeline.forces.spring_kinds();
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

    /// Puts back the good state before the step to blame, then retries that step or reports
    /// it, as the scene asks.
    pub(super) fn recover(
        &mut self,
        model: &Model,
        state: &mut State,
        mut failure: Failure,
    ) -> Result<()> {
        if failure.reason == Trouble::Panicked {
            return Err(self.recover_from_panic(state, failure.substeps));
        }
        self.watchdog.stats.caught += 1;
        if failure.in_start_state {
            // The last completed step produced a state beyond the limit: undo it, and the
            // integrator's history with it. It ran with the substeps it ran with.
            failure.substeps = self.watchdog.last_substeps;
            match self.watchdog.previous.as_ref() {
                Some(previous) if self.watchdog.previous_valid => {
                    state.kin.copy_from(previous);
                    self.pipeline
                        .integrator
                        .set_history(self.watchdog.previous_history);
                    self.watchdog.previous_valid = false;
                    state.clock.steps -= 1;
                }
                // The state came from the user or the scene, not from a step: nothing to undo
                // or retry, and the state stays as it is.
                _ => return Err(diverged(state.clock.steps + 1, failure)),
            }
        } else {
            self.back_to_step_start(state, failure.substeps);
        }
        state.version += 1;
        // The restored state was judged good; a call that takes no step must not judge again.
        self.watchdog.unjudged = false;
        let step = state.clock.steps + 1;
        if self.watchdog.retries() {
            self.retry_step(model, state, step, failure)
        } else {
            Err(diverged(step, failure))
        }
    }

    /// Reruns step `step` from the current state with 2, 4, ... times the failed attempt's
    /// substeps, up to the watchdog's `max_substeps`, judging each attempt's end state too: a
    /// retried step must not hand on a state the next step would reject. On failure the state
    /// is back where it started.
    fn retry_step(
        &mut self,
        model: &Model,
        state: &mut State,
        step: u64,
        failure: Failure,
    ) -> Result<()> {
        let n = model.grid.len();
        let mut start = self
            .watchdog
            .retry_start
            .take()
            .unwrap_or_else(|| Kinematics::zeros(n));
        start.copy_from(&state.kin);
        let mut last = failure;
        let mut substeps = failure.substeps.saturating_mul(2);
        let mut rescued = false;
        // The history the step starts from, for a failed retry to hand back.
        let start_history = self.pipeline.integrator.history();
        let mut history = History::default();
        while substeps <= self.watchdog.spec.max_substeps {
            self.pipeline.integrator.reset_history();
            history = self.pipeline.integrator.history();
            self.watchdog.stats.retry_substeps += substeps as u64;
            let attempt = self.run_substeps(model, state, substeps).and_then(|()| {
                match self.overstretched_in(model, &state.kin, false, substeps) {
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
                    state.kin.copy_from(&start);
                    self.watchdog.retry_start = Some(start);
                    self.step_start_history = History::default();
                    self.pipeline.integrator.reset_history();
                    return Err(self.recover_from_panic(state, 1));
                }
                Err(f) => {
                    last = f;
                    state.kin.copy_from(&start);
                }
            }
            substeps = substeps.saturating_mul(2);
        }
        // The substep length changes again after a rescue; a step that could not be saved
        // leaves the integrator as it found it.
        if rescued {
            self.pipeline.integrator.reset_history();
        } else {
            self.pipeline.integrator.set_history(start_history);
        }
        state.version += 1;
        let result = if rescued {
            let stats = &mut self.watchdog.stats;
            stats.retried += 1;
            stats.max_substeps_used = stats.max_substeps_used.max(substeps);
            let hold = self.watchdog.spec.hold_steps as u64;
            self.watchdog.hold = (hold > 0).then_some((substeps, step + 1 + hold));
            self.watchdog.step_completed(&mut start, history, substeps);
            state.clock.steps = step;
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
    fn back_to_step_start(&mut self, state: &mut State, substeps: u32) {
        if substeps > 1 {
            if let Some(start) = &self.step_start {
                state.kin.copy_from(start);
            }
        }
        self.pipeline
            .integrator
            .set_history(self.step_start_history);
        (self.watchdog.hold, self.watchdog.stats.held_steps) = self.step_start_hold;
    }

    /// A step of `substeps` substeps panicked: back to its start, the force model's leftovers
    /// dropped, and the panic reported as [`Error::Internal`].
    fn recover_from_panic(&mut self, state: &mut State, substeps: u32) -> Error {
        // Back where the step started, which the watchdog still judges as it did: its memory
        // of the last step stays.
        self.back_to_step_start(state, substeps);
        self.pipeline.forces.reset_after_panic();
        state.version += 1;
        Error::Internal {
            message: self
                .panic_message
                .take()
                .unwrap_or_else(|| "a pass panicked".into()),
        }
    }

    /// The watchdog's memory, for a saved state.
    pub fn watchdog_snapshot(&self) -> WatchdogSnapshot {
        let w = &self.watchdog;
        WatchdogSnapshot {
            previous: w
                .previous
                .as_ref()
                .filter(|_| w.previous_valid)
                .map(|k| (k.pos.clone(), k.vel.clone(), w.previous_history)),
            unjudged: w.unjudged,
            last_substeps: w.last_substeps,
            hold: w.hold,
            stats: w.stats,
        }
    }

    /// Puts back the watchdog's memory from a saved state; the error names what does not fit.
    ///
    /// Only what a simulation of `substeps` substeps per step can have written is taken: a
    /// step's substeps between 1 and the most the watchdog retries with, and a hold that ends
    /// within `hold_steps` of `steps`, the clock of the state restored, so that no crafted
    /// state makes the next step run for hours.
    pub fn restore_watchdog(
        &mut self,
        saved: WatchdogSnapshot,
        n: usize,
        steps: u64,
        substeps: u32,
    ) -> Result<()> {
        let most = self.watchdog.spec.max_substeps.max(substeps);
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
            let latest = steps.saturating_add(2 + self.watchdog.spec.hold_steps as u64);
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
        let w = &mut self.watchdog;
        match (saved.previous, w.previous.as_mut()) {
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
                w.previous_history = history;
                w.previous_valid = true;
            }
        }
        w.unjudged = saved.unjudged;
        w.last_substeps = saved.last_substeps;
        w.hold = saved.hold;
        w.stats = saved.stats;
        Ok(())
    }
}

fn diverged(step: u64, failure: Failure) -> Error {
    Error::Diverged {
        step,
        particle: failure.particle,
        reason: failure.reason,
        substeps: failure.substeps,
    }
}
