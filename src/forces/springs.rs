//! The spring force: Hooke's law with damping along the spring.
//!
//! Force on particle `a` from the spring `(a, b)` with rest length `L` and current length
//! `l = |x_b - x_a|`, unit direction `u = (x_b - x_a) / l`:
//!
//! ```text
//! f_a = k (l - L) u + c ((v_b - v_a) . u) u,     f_b = -f_a
//! ```
//!
//! A spring of zero current length has no direction and exerts no force.
//!
//! Each spring is evaluated once per block, at its anchor, into the block's table; both ends
//! then read that value (`+F` at the anchor, `-F` at the far end: bitwise negated, so momentum
//! is conserved exactly up to the order of summation). The loop over a run of springs is one
//! straight loop over equal-length slices, which the compiler vectorises.

use std::ops::Range;

use super::StateRef;
use crate::grid::SpringKind;
use crate::soa::Vec3SliceMut;
use crate::springs::{anchored_run, overstretched};

/// The law of one spring family: stiffness `k` in N/m, damping `c` in N s/m.
#[derive(Clone, Copy, Debug)]
pub(super) struct SpringLaw {
    pub k: f32,
    pub c: f32,
}

impl SpringLaw {
    /// Writes the force on the anchor of every spring of `kind` anchored in `range` into `out`
    /// (slices covering exactly `range`; zero for slots with no spring). With a `watch` limit,
    /// also returns whether a live spring is longer than that many times its rest length (the
    /// watchdog's stretch check, in the same loop; a separate instantiation, so a scene without
    /// a limit pays nothing for it).
    pub fn tabulate(
        self,
        state: StateRef,
        kind: SpringKind,
        range: Range<usize>,
        out: &mut Vec3SliceMut,
        watch: Option<f32>,
    ) -> bool {
        match watch {
            None => {
                crate::simd::dispatch!(self.forces::<false>(state, kind, range.clone(), out, 0.0))
            }
            Some(limit) => {
                crate::simd::dispatch!(self.forces::<true>(state, kind, range.clone(), out, limit))
            }
        }
    }

    #[inline(always)]
    fn forces<const WATCH: bool>(
        self,
        state: StateRef,
        kind: SpringKind,
        range: Range<usize>,
        out: &mut Vec3SliceMut,
        limit: f32,
    ) -> bool {
        let run = anchored_run(state.grid.len(), state.grid.offset(kind), range);
        let len = run.len;
        let x = state.springs.view(kind, state.pos, run);
        let v = state.springs.view(kind, state.vel, run);
        let (rest, active) = (x.rest, x.active);
        let (fx, fy, fz) = (&mut out.x[..len], &mut out.y[..len], &mut out.z[..len]);
        let (k, c) = (self.k, self.c);
        // An integer OR, like `FiniteCheck`, so the loop still vectorises.
        let mut over = 0u32;
        for i in 0..len {
            let [dx, dy, dz] = x.delta(i);
            let l = (dx * dx + dy * dy + dz * dz).sqrt();
            if WATCH {
                over |= overstretched(l, rest[i], active[i], limit) as u32;
            }
            let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
            let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
            let [dvx, dvy, dvz] = v.delta(i);
            let closing = dvx * ux + dvy * uy + dvz * uz;
            let s = k * (l - rest[i]) + c * closing;
            // A dead slot's force is zero, not `0 * force`: its end may be a cut particle
            // anywhere, whose arithmetic need not be finite (0 * inf is NaN), and even the sign
            // of `0 * force` would let it reach the live cloth.
            let live = active[i] != 0.0;
            let dead = |f: f32| if live { f } else { 0.0 };
            fx[i] = dead(s * ux);
            fy[i] = dead(s * uy);
            fz[i] = dead(s * uz);
        }
        for f in [&mut *out.x, &mut *out.y, &mut *out.z] {
            f[len..].fill(0.0);
        }
        over != 0
    }
}
