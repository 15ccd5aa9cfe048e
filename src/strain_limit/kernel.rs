//! The arithmetic of strain limiting: counting the springs over the limit, the Jacobi sweep
//! that shortens them, and the velocity correction that removes their stretching motion. Each
//! walks the structural and shear springs of a chunk as [`SpringRun`]s through a `RunView`.

use rayon::prelude::*;

use super::{Check, LIMITED_KINDS};
use crate::grid::{Grid, SpringKind};
use crate::mesh_cloth::MeshCloth;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::{neighbour_runs, SpringRun, Springs};
use crate::state::Kinematics;

/// What the check and the sweep read.
pub(super) struct Kernel<'a> {
    pub grid: Grid,
    pub springs: &'a Springs,
    /// A mesh cloth's springs, limited instead of the stencil's ([`super::mesh`]).
    pub mesh: Option<&'a MeshCloth>,
    pub inv_mass: &'a [f32],
    /// `1 + max_strain`.
    pub factor: f32,
}

/// Whether a spring of squared length `l2`, rest length `rest` and `active` flag is over the
/// limit `factor * rest`. The check and the sweep must agree bit for bit on this (the counts
/// they share depend on it), so both call this one function. A non-finite length is never
/// over: a diverged neighbour is left for the integrator's check to report.
#[inline(always)]
pub(super) fn over_limit(l2: f32, rest: f32, active: f32, factor: f32) -> bool {
    let lim = factor * rest;
    // `&`, not `&&`: no branches, so the loops calling this vectorise.
    (active != 0.0) & (rest > 0.0) & (l2 > lim * lim) & (l2 < f32::INFINITY)
}

impl Kernel<'_> {
    /// Counts, for every particle that can move, its springs over the limit in `pos` into
    /// `count`, and returns the totals.
    pub(super) fn check(&self, pos: &Vec3s, count: &mut [u8], chunk: usize) -> Check {
        if let Some(mesh) = self.mesh {
            return self.check_mesh(mesh, pos, count, chunk);
        }
        count
            .par_chunks_mut(chunk)
            .enumerate()
            .map(|(c, count)| {
                let start = c * chunk;
                crate::simd::dispatch!(self.check_chunk(pos, start, count))
            })
            .reduce(
                || Check {
                    worst_ratio2: 1.0,
                    ..Check::default()
                },
                Check::merge,
            )
    }

    #[inline(always)]
    fn check_chunk(&self, pos: &Vec3s, start: usize, count: &mut [u8]) -> Check {
        let range = start..start + count.len();
        count.fill(0);
        let mut total = Check {
            worst_ratio2: 1.0,
            ..Check::default()
        };
        for kind in LIMITED_KINDS {
            let [anchors, ends] =
                neighbour_runs(self.grid.len(), self.grid.offset(kind), range.clone());
            if let Some(run) = anchors {
                total = total.merge(self.check_run::<true>(pos, kind, run, start, count));
            }
            if let Some(run) = ends {
                total = total.merge(self.check_run::<false>(pos, kind, run, start, count));
            }
        }
        total
    }

    /// One run of [`neighbour_runs`]: adds to `count` (which starts at particle `start`) and,
    /// for the run of anchors (`STATS`), measures each spring once.
    #[inline(always)]
    fn check_run<const STATS: bool>(
        &self,
        pos: &Vec3s,
        kind: SpringKind,
        run: SpringRun,
        start: usize,
        count: &mut [u8],
    ) -> Check {
        let x = self.springs.view(kind, pos, run);
        let (len, rest, active) = (x.len, x.rest, x.active);
        let wa = &self.inv_mass[run.a_range()][..len];
        let count = &mut count[run.a - start..run.a - start + len][..len];
        let factor = self.factor;
        // The largest ratio is kept as the bits of a positive float, which order like the
        // floats: an integer maximum vectorises, a float one (NaN-aware) does not.
        let (mut over, mut movable, mut worst) = (0u32, 0u32, 1.0f32.to_bits());
        for i in 0..len {
            let [dx, dy, dz] = x.delta(i);
            let l2 = dx * dx + dy * dy + dz * dz;
            let is_over = over_limit(l2, rest[i], active[i], factor);
            let moves = (is_over & (wa[i] > 0.0)) as u8;
            count[i] += moves;
            movable += moves as u32;
            if STATS {
                over += is_over as u32;
                let ratio2 = l2 / (rest[i] * rest[i]);
                // Live springs with a rest length and a finite ratio; the rest count as 1.
                let measured = (active[i] != 0.0) & (rest[i] > 0.0) & (ratio2 <= f32::MAX);
                let bits = if measured { ratio2.to_bits() } else { 0 };
                worst = worst.max(bits);
            }
        }
        Check {
            over,
            movable,
            worst_ratio2: f32::from_bits(worst),
        }
    }

    /// One Jacobi sweep: `out` = `pos` moved by the averaged corrections of the springs over
    /// the limit, as counted in `count` by a check of `pos`.
    /// Returns whether any position changed.
    pub(super) fn sweep(&self, pos: &Vec3s, count: &[u8], out: &mut Vec3s, chunk: usize) -> bool {
        if let Some(mesh) = self.mesh {
            return self.sweep_mesh(mesh, pos, count, out, chunk);
        }
        out.par_chunks_mut(chunk)
            .enumerate()
            .map(|(c, mut out)| {
                let start = c * chunk;
                crate::simd::dispatch!(self.sweep_chunk(pos, count, start, &mut out))
            })
            .reduce(|| false, |a, b| a | b)
    }

    #[inline(always)]
    fn sweep_chunk(&self, pos: &Vec3s, count: &[u8], start: usize, out: &mut Vec3SliceMut) -> bool {
        let range = start..start + out.len();
        // `out` first gathers the corrections, then becomes the new position.
        out.fill(glam::Vec3::ZERO);
        for kind in LIMITED_KINDS {
            let runs = neighbour_runs(self.grid.len(), self.grid.offset(kind), range.clone());
            for run in runs.into_iter().flatten() {
                self.sweep_run(pos, count, kind, run, start, out);
            }
        }
        let count = &count[range.clone()];
        let mut changed = 0u32;
        for (c, out) in [&mut *out.x, &mut *out.y, &mut *out.z]
            .into_iter()
            .enumerate()
        {
            let (x, out) = (
                &pos.component(c, &range)[..count.len()],
                &mut out[..count.len()],
            );
            for i in 0..count.len() {
                // A particle with nothing to correct keeps its bits (x + 0 would turn -0 into
                // +0); `count` is 0 for every particle that cannot move.
                let new = if count[i] == 0 { x[i] } else { x[i] + out[i] };
                changed |= new.to_bits() ^ x[i].to_bits();
                out[i] = new;
            }
        }
        changed != 0
    }

    /// The velocity corrections of [`StrainLimit::apply`] into `out`: for the springs over
    /// the limit in `before` (as `count` counted them), along their direction in `after`.
    /// Returns whether any spring's ends move apart (any correction is not zero).
    pub(super) fn velocity_corrections(
        &self,
        before: &Kinematics,
        after: &Vec3s,
        count: &[u8],
        out: &mut Vec3s,
        chunk: usize,
    ) -> bool {
        if let Some(mesh) = self.mesh {
            return self.velocity_corrections_mesh(mesh, (before, after), (count, out), chunk);
        }
        out.par_chunks_mut(chunk)
            .enumerate()
            .map(|(c, mut out)| {
                let start = c * chunk;
                let range = start..start + out.len();
                out.fill(glam::Vec3::ZERO);
                let mut any = false;
                for kind in LIMITED_KINDS {
                    let runs =
                        neighbour_runs(self.grid.len(), self.grid.offset(kind), range.clone());
                    for run in runs.into_iter().flatten() {
                        any |= crate::simd::dispatch!(
                            self.velocity_run(before, after, count, kind, run, start, &mut out)
                        );
                    }
                }
                any
            })
            .reduce(|| false, |a, b| a | b)
    }

    /// Adds the velocity corrections of one run of springs to `out` (which starts at particle
    /// `start`). As in [`Kernel::sweep_run`], every factor is symmetric in the two ends but
    /// `w_a` and the sign of `d`, so the far end computes exactly the opposite impulse.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn velocity_run(
        &self,
        before: &Kinematics,
        after: &Vec3s,
        count: &[u8],
        kind: SpringKind,
        run: SpringRun,
        start: usize,
        out: &mut Vec3SliceMut,
    ) -> bool {
        let x0 = self.springs.view(kind, &before.pos, run);
        let x = self.springs.view(kind, after, run);
        let v = self.springs.view(kind, &before.vel, run);
        let (len, rest, active) = (x.len, x.rest, x.active);
        let PairWeights {
            w: [wa, wb],
            c: [ca, cb],
        } = self.pair_weights(count, run);
        let (ox, oy, oz) = out_run(out, run, start);
        let factor = self.factor;
        let mut any = 0u32;
        for i in 0..len {
            let d0 = x0.delta(i);
            let was_over = over_limit(
                d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2],
                rest[i],
                active[i],
                factor,
            );
            let [dx, dy, dz] = x.delta(i);
            let l2 = dx * dx + dy * dy + dz * dz;
            let [dvx, dvy, dvz] = v.delta(i);
            let apart = dvx * dx + dvy * dy + dvz * dz;
            let shared = (ca[i].max(cb[i])) as f32;
            let s = wa[i] / (wa[i] + wb[i]) * (apart / (l2 * shared));
            // Masked, not multiplied by a flag (s may be NaN where the spring is not corrected).
            let keep = (was_over & (wa[i] > 0.0) & (apart > 0.0) & (l2 > 0.0)) as u32;
            any |= keep;
            let mask = keep.wrapping_neg();
            let masked = |v: f32| f32::from_bits(v.to_bits() & mask);
            let s = masked(s);
            ox[i] += s * masked(dx);
            oy[i] += s * masked(dy);
            oz[i] += s * masked(dz);
        }
        any != 0
    }

    /// The inverse masses and the over-limit counts of both ends of a run's springs, each cut
    /// to the run's length: what sharing a correction between the ends reads.
    #[inline(always)]
    fn pair_weights<'a>(&'a self, count: &'a [u8], run: SpringRun) -> PairWeights<'a> {
        let len = run.len;
        PairWeights {
            w: [
                &self.inv_mass[run.a_range()][..len],
                &self.inv_mass[run.b_range()][..len],
            ],
            c: [&count[run.a_range()][..len], &count[run.b_range()][..len]],
        }
    }

    /// Adds the corrections of one run of springs to `out` (which starts at particle `start`).
    #[inline(always)]
    fn sweep_run(
        &self,
        pos: &Vec3s,
        count: &[u8],
        kind: SpringKind,
        run: SpringRun,
        start: usize,
        out: &mut Vec3SliceMut,
    ) {
        let x = self.springs.view(kind, pos, run);
        let (len, rest, active) = (x.len, x.rest, x.active);
        let PairWeights {
            w: [wa, wb],
            c: [ca, cb],
        } = self.pair_weights(count, run);
        let (ox, oy, oz) = out_run(out, run, start);
        let factor = self.factor;
        for i in 0..len {
            let [dx, dy, dz] = x.delta(i);
            let l2 = dx * dx + dy * dy + dz * dz;
            let l = l2.sqrt();
            let lim = factor * rest[i];
            // Every factor is symmetric in the two ends except w_a and the sign of d, so the
            // far end computes exactly the opposite move (for equal masses, bit for bit).
            let shared = (ca[i].max(cb[i])) as f32;
            let s = wa[i] / (wa[i] + wb[i]) * ((l - lim) / (l * shared));
            // Masked, not multiplied by a flag: where the spring is not over the limit, s or d
            // may be NaN (a zero length, a diverged neighbour), and 0 * NaN is NaN. A bit mask
            // rather than `if`, so that the loop stays branch-free and vectorises.
            let keep = (over_limit(l2, rest[i], active[i], factor) & (wa[i] > 0.0)) as u32;
            let mask = keep.wrapping_neg();
            let masked = |v: f32| f32::from_bits(v.to_bits() & mask);
            let s = masked(s);
            ox[i] += s * masked(dx);
            oy[i] += s * masked(dy);
            oz[i] += s * masked(dz);
        }
    }
}

/// Both ends' inverse masses `w` and over-limit counts `c` over a run.
struct PairWeights<'a> {
    w: [&'a [f32]; 2],
    c: [&'a [u8]; 2],
}

/// The three components of `out` (which starts at particle `start`) over the run's particles.
#[inline(always)]
fn out_run<'a>(
    out: &'a mut Vec3SliceMut,
    run: SpringRun,
    start: usize,
) -> (&'a mut [f32], &'a mut [f32], &'a mut [f32]) {
    let o = run.a - start..run.a - start + run.len;
    (&mut out.x[o.clone()], &mut out.y[o.clone()], &mut out.z[o])
}
