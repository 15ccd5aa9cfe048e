use super::{hold_mask, par_update, par_update2, select_bits, FiniteCheck, StepContext};
use crate::state::Kinematics;

/// Classic fourth-order Runge-Kutta on the first-order system `x' = v, v' = f(x, v) / m`:
///
/// ```text
/// k1 = F(x, v)                       with F(x, v) = (v, f(x, v) / m)
/// k2 = F((x, v) + h/2 k1)
/// k3 = F((x, v) + h/2 k2)
/// k4 = F((x, v) + h k3)
/// (x, v)' = (x, v) + h/6 (k1 + 2 k2 + 2 k3 + k4)
/// ```
///
/// Four force evaluations per step through the same force passes; colliders run once, after the
/// update. Fourth order, but not symplectic: without damping its energy slowly decays.
#[derive(Default)]
pub struct Rk4 {
    /// The stage state where forces are evaluated.
    stage: Option<Kinematics>,
    /// Running weighted sum of the stage derivatives `(v, a)`.
    sum: Option<Kinematics>,
}

impl Rk4 {
    pub fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
        let n = ctx.current.pos.len();
        let stage = self.stage.get_or_insert_with(|| Kinematics::zeros(n));
        let sum = self.sum.get_or_insert_with(|| Kinematics::zeros(n));
        let cur = ctx.current;
        let w = &ctx.particles.inv_mass;

        // k1 (at the current state), k2, k3: each is added into the weighted sum, then the
        // stage moves to where the next derivative is evaluated.
        for (k, (weight, step_to)) in [(1.0, 0.5 * h), (2.0, 0.5 * h), (2.0, h)]
            .into_iter()
            .enumerate()
        {
            ctx.eval_forces_at(if k == 0 { cur } else { stage });
            let f = &*ctx.force;
            par_update2(sum, stage, ctx.chunk, |r, mut sum, mut stage| {
                let w = &w[r.clone()];
                for c in 0..3 {
                    let (x, v, f) = (
                        cur.pos.component(c, &r),
                        cur.vel.component(c, &r),
                        f.component(c, &r),
                    );
                    let (sx, sv) = (sum.pos.component_mut(c), sum.vel.component_mut(c));
                    let (tx, tv) = (stage.pos.component_mut(c), stage.vel.component_mut(c));
                    crate::simd::dispatch!(stage_update(
                        k == 0,
                        weight,
                        step_to,
                        x,
                        v,
                        f,
                        w,
                        sx,
                        sv,
                        tx,
                        tv
                    ));
                }
            });
        }

        // k4, and the combination.
        ctx.eval_forces_at(stage);
        let (f, stage, sum) = (&*ctx.force, &*stage, &*sum);
        par_update(ctx.next, ctx.chunk, |mut out| {
            let r = out.range.clone();
            let w = &w[r.clone()];
            let mut check = FiniteCheck::default();
            for c in 0..3 {
                let (x, v, f) = (
                    cur.pos.component(c, &r),
                    cur.vel.component(c, &r),
                    f.component(c, &r),
                );
                let (sx, sv) = (sum.pos.component(c, &r), sum.vel.component(c, &r));
                let stage_v = stage.vel.component(c, &r);
                let (dx, dv) = (out.pos.component_mut(c), out.vel.component_mut(c));
                check.0 |= crate::simd::dispatch!(combine(h, x, v, f, w, sx, sv, stage_v, dx, dv));
            }
            check
        })
    }
}

/// Adds stage derivative `(stage v, a)` with `weight` into the sum (starting it when `first`)
/// and moves the stage to `(x, v) + step_to (stage v, a)`, for one component of a chunk.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn stage_update(
    first: bool,
    weight: f32,
    step_to: f32,
    x: &[f32],
    v: &[f32],
    f: &[f32],
    w: &[f32],
    sx: &mut [f32],
    sv: &mut [f32],
    tx: &mut [f32],
    tv: &mut [f32],
) {
    let n = x.len();
    let (v, f, w, sx, sv, tx, tv) = (
        &v[..n],
        &f[..n],
        &w[..n],
        &mut sx[..n],
        &mut sv[..n],
        &mut tx[..n],
        &mut tv[..n],
    );
    if first {
        for i in 0..n {
            let a = f[i] * w[i];
            sx[i] = weight * v[i];
            sv[i] = weight * a;
            tx[i] = x[i] + step_to * v[i];
            tv[i] = v[i] + step_to * a;
        }
    } else {
        for i in 0..n {
            let a = f[i] * w[i];
            let stage_v = tv[i];
            sx[i] += weight * stage_v;
            sv[i] += weight * a;
            tx[i] = x[i] + step_to * stage_v;
            tv[i] = v[i] + step_to * a;
        }
    }
}

/// `(x, v)' = (x, v) + h/6 (sum + k4)` for one component of a chunk; held particles keep
/// their bits. Returns the [`FiniteCheck`] bits of what it wrote.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn combine(
    h: f32,
    x: &[f32],
    v: &[f32],
    f: &[f32],
    w: &[f32],
    sx: &[f32],
    sv: &[f32],
    stage_v: &[f32],
    dx: &mut [f32],
    dv: &mut [f32],
) -> u32 {
    let n = x.len();
    let (v, f, w, sx, sv, stage_v, dx, dv) = (
        &v[..n],
        &f[..n],
        &w[..n],
        &sx[..n],
        &sv[..n],
        &stage_v[..n],
        &mut dx[..n],
        &mut dv[..n],
    );
    let mut check = FiniteCheck::default();
    for i in 0..n {
        let x_new = x[i] + h / 6.0 * (sx[i] + stage_v[i]);
        let v_new = v[i] + h / 6.0 * (sv[i] + f[i] * w[i]);
        let keep = hold_mask(w[i]);
        let (x_out, v_out) = (
            select_bits(keep, x[i], x_new),
            select_bits(keep, v[i], v_new),
        );
        dx[i] = x_out;
        dv[i] = v_out;
        check.watch(x_out);
        check.watch(v_out);
    }
    check.0
}
