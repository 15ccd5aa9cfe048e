//! What a step does when it goes wrong: find the step to blame, put back the good state before
//! it, and retry it with more substeps or report it, as the scene's watchdog asks. The noticing
//! and the watchdog's memory are described in `watchdog.rs`.

use super::watchdog::Failure;
use super::Stepper;
use crate::error::{Error, Result, Trouble};
use crate::integrators::History;
use crate::model::Model;
use crate::state::{Kinematics, State};

impl Stepper {
    /// Checks the newest state against the stretch limit before a call hands it back. Inside a
    /// run of steps each state is judged for free by the force loop of the step that continues
    /// from it; the last one of a call has no such step, and an unstable mode can grow tenfold
    /// in a step, so it gets this one scan (per call, not per step; only with a limit set).
    pub(super) fn judge_newest_state(&mut self, model: &Model, state: &mut State) -> Result<()> {
        // Without a limit, or with nothing stepped since the last judgement, nothing to do.
        let Some(last) = self.watchdog.take_unjudged() else {
            return Ok(());
        };
        match self.overstretched_in(model, &state.kin, true, last) {
            Some(failure) => self.recover(model, state, failure),
            None => Ok(()),
        }
    }

    /// The first spring of `kin` beyond the watchdog's stretch limit, as a failure of a step of
    /// `substeps` substeps.
    pub(super) fn overstretched_in(
        &self,
        model: &Model,
        kin: &Kinematics,
        in_start_state: bool,
        substeps: u32,
    ) -> Option<Failure> {
        let kinds = self.pipeline.forces.spring_kinds();
        self.watchdog
            .overstretched_in(model, kin, kinds, in_start_state, substeps)
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
        self.watchdog.count_caught();
        if failure.in_start_state {
            // The last completed step produced a state beyond the limit: undo it, and the
            // integrator's history with it. It ran with the substeps it ran with.
            failure.substeps = self.watchdog.last_substeps();
            match self.watchdog.undo_last_step(&mut state.kin) {
                Some(history) => {
                    self.pipeline.integrator.set_history(history);
                    state.clock.steps -= 1;
                }
                // The state came from the user or the scene, not from a step: nothing to undo
                // or retry, and the state stays as it is.
                None => return Err(diverged(state.clock.steps + 1, failure)),
            }
        } else {
            self.back_to_step_start(state, failure.substeps);
        }
        state.version += 1;
        // The restored state was judged good; a call that takes no step must not judge again.
        self.watchdog.judged();
        let step = state.clock.steps + 1;
        // A cascade is the cap's limit, not a divergence: more substeps are its remedy in
        // every scene.
        if self.watchdog.retries() || failure.reason.is_cascade() {
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
        let mut start = self.watchdog.take_retry_start(model.grid.len());
        start.copy_from(&state.kin);
        let mut last = failure;
        // The failure a rescue is saved from, a cascade's with the most vertices any attempt's
        // cap stopped: its hold is chosen by that size.
        let mut reason = failure.reason;
        let mut rescued = None;
        // The history the step starts from, for a failed retry to hand back.
        let start_history = self.pipeline.integrator.history();
        for substeps in self.watchdog.retry_substeps(failure.substeps) {
            self.pipeline.integrator.reset_history();
            self.watchdog.count_retry_attempt(substeps);
            let attempt = self.run_substeps(model, state, substeps).and_then(|()| {
                match self.overstretched_in(model, &state.kin, false, substeps) {
                    Some(failure) => Err(failure),
                    None => Ok(()),
                }
            });
            match attempt {
                Ok(()) => {
                    rescued = Some(substeps);
                    break;
                }
                Err(f) if f.reason == Trouble::Panicked => {
                    state.kin.copy_from(&start);
                    self.watchdog.put_retry_start(start);
                    self.start_history = History::default();
                    self.pipeline.integrator.reset_history();
                    return Err(self.recover_from_panic(state, 1));
                }
                Err(f) => {
                    last = f;
                    if let (Trouble::Cascade { stopped }, Trouble::Cascade { stopped: again }) =
                        (reason, f.reason)
                    {
                        reason = Trouble::Cascade {
                            stopped: stopped.max(again),
                        };
                    }
                    state.kin.copy_from(&start);
                    // A scene that raises on trouble retries a cascade, and nothing else.
                    if !self.watchdog.retries() && !f.reason.is_cascade() {
                        break;
                    }
                }
            }
        }
        state.version += 1;
        let result = match rescued {
            Some(substeps) => {
                // The substep length changes again after a rescue.
                self.pipeline.integrator.reset_history();
                let history = self.pipeline.integrator.history();
                self.watchdog.rescued(
                    step,
                    substeps,
                    model.scene.substeps,
                    reason,
                    &mut start,
                    history,
                );
                state.clock.steps = step;
                self.profile.steps += 1;
                Ok(())
            }
            // A step that could not be saved leaves the integrator as it found it.
            None => {
                self.pipeline.integrator.set_history(start_history);
                Err(diverged(step, last))
            }
        };
        self.watchdog.put_retry_start(start);
        result
    }

    /// After a failed attempt at the current step with `substeps` substeps: the state, the
    /// integrator's history and the watchdog's hold as they were when the step started. With
    /// one substep the state is already there (the failed substep never swapped its result in).
    fn back_to_step_start(&mut self, state: &mut State, substeps: u32) {
        if substeps > 1 {
            if let Some(start) = &self.step_start {
                state.kin.copy_from(start);
            }
        }
        self.pipeline.integrator.set_history(self.start_history);
        self.watchdog.rewind(self.start_hold);
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
}

fn diverged(step: u64, failure: Failure) -> Error {
    Error::Diverged {
        step,
        particle: failure.particle,
        reason: failure.reason,
        substeps: failure.substeps,
    }
}
