use super::{one_stage_update, StepContext};

/// Forward (explicit) Euler, the textbook scheme: both updates use the state at the start of
/// the step,
///
/// ```text
/// x' = x + h v
/// v' = v + h f(x, v) / m
/// ```
///
/// First order and not symplectic: an undamped oscillator gains energy every step, so it needs
/// damping or small steps. Kept as the baseline the accuracy study compares against.
pub(super) fn step(h: f32, ctx: &mut StepContext) -> bool {
    one_stage_update(ctx, h, |x, v, dv| (x + h * v, v + dv))
}
