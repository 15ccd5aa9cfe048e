use super::{par_update, par_update2, FiniteCheck, Integrator, StepContext};
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

impl Integrator for Rk4 {
    fn name(&self) -> &'static str {
        "rk4"
    }

    fn step(&mut self, h: f32, ctx: &mut StepContext) -> bool {
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
                for c in 0..3 {
                    let (x, v, f) = (
                        cur.pos.component(c, &r),
                        cur.vel.component(c, &r),
                        f.component(c, &r),
                    );
                    let (sx, sv) = (sum.pos.component_mut(c), sum.vel.component_mut(c));
                    let (tx, tv) = (stage.pos.component_mut(c), stage.vel.component_mut(c));
                    for i in 0..x.len() {
                        let a = f[i] * w[r.start + i];
                        let stage_v = if k == 0 { v[i] } else { tv[i] };
                        let (prev_x, prev_v) = if k == 0 { (0.0, 0.0) } else { (sx[i], sv[i]) };
                        sx[i] = prev_x + weight * stage_v;
                        sv[i] = prev_v + weight * a;
                        tx[i] = x[i] + step_to * stage_v;
                        tv[i] = v[i] + step_to * a;
                    }
                }
            });
        }

        // k4, and the combination.
        ctx.eval_forces_at(stage);
        let (f, stage, sum) = (&*ctx.force, &*stage, &*sum);
        par_update(ctx.next, ctx.chunk, |mut out| {
            let r = out.range.clone();
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
                for i in 0..x.len() {
                    let wi = w[r.start + i];
                    let x_new = x[i] + h / 6.0 * (sx[i] + stage_v[i]);
                    let v_new = v[i] + h / 6.0 * (sv[i] + f[i] * wi);
                    let moving = wi > 0.0;
                    dx[i] = if moving { x_new } else { x[i] };
                    dv[i] = if moving { v_new } else { v[i] };
                    check.watch(dx[i]);
                    check.watch(dv[i]);
                }
            }
            check
        })
    }
}
