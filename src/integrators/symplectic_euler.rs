use super::{one_stage_update, StepContext};

/// Semi-implicit (symplectic) Euler: the velocity first, then the position with the new
/// velocity:
///
/// ```text
/// v' = v + h f(x, v) / m
/// x' = x + h v'
/// ```
///
/// First order, one force evaluation per step, and symplectic: with no damping its energy
/// oscillates around the true value instead of drifting. Stable for `h sqrt(k/m) < 2`.
pub(super) fn step(h: f32, ctx: &mut StepContext) -> bool {
    one_stage_update(ctx, h, |x, v, dv| {
        let v_new = v + dv;
        (x + h * v_new, v_new)
    })
}
