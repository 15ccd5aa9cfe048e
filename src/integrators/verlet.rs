use super::{one_stage_update, History, StepContext};

/// Position (Stoermer) Verlet:
///
/// ```text
/// x_{n+1} = 2 x_n - x_{n-1} + h^2 f(x_n, v_n) / m,      v_n = (x_n - x_{n-1}) / h
/// ```
///
/// Second order in position, symplectic and time-reversible, one force evaluation per step.
///
/// **Its velocity** is the backward difference of the last two positions, `v_n = (x_n -
/// x_{n-1}) / h`: exact at the half step `t_{n-1/2}`, first-order accurate at `t_n`. It is what
/// damping, drag and the colliders see, and what `velocities` reports.
///
/// **Its form.** The recurrence is evaluated in its summed form, `h v_{n+1} = h v_n + h^2 a_n`,
/// `x_{n+1} = x_n + h v_{n+1}` (Hairer, Lubich and Wanner, *Geometric Numerical Integration*,
/// VIII.5): algebraically the same positions, but the two-term form `2 x_n - x_{n-1}` turns every
/// float32 rounding of a position (about 1e-7 m at 1 m) into a velocity error of 1e-7/h, which
/// swamps the truncation error below h = 0.01 s; the summed form does not. The history
/// `x_{n-1} = x_n - h v_n` is therefore implied by `v`, so a collider or the user changing a
/// velocity changes the history consistently.
///
/// **Its start.** The first step after a start or an outside change uses the second-order
/// Taylor start `x_1 = x_0 + h v_0 + h^2 a_0 / 2`, treating `v_0` as a true velocity. The start
/// is what makes the positions second order: with `x_1 = x_0 + h v_0 + h^2 a_0` the same
/// recurrence is symplectic Euler, first order.
#[derive(Default)]
pub struct Verlet {
    /// Whether the stored velocities are already backward differences.
    primed: bool,
}

impl Verlet {
    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        let kick = if self.primed { 1.0 } else { 0.5 };
        one_stage_update(ctx, h, |x, v, dv| {
            let v_new = v + kick * dv;
            (x + h * v_new, v_new)
        })
    }

    pub fn reset_history(&mut self) {
        self.primed = false;
    }

    pub fn accept(&mut self) {
        self.primed = true;
    }

    pub fn history(&self) -> History {
        History {
            primed: self.primed,
        }
    }

    pub fn set_history(&mut self, history: History) {
        self.primed = history.primed;
    }
}
