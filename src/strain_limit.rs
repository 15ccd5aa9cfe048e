//! Provot strain limiting (X. Provot, "Deformation constraints in a mass-spring model to
//! describe rigid cloth behavior", Graphics Interface 1995).
//!
//! Soft springs let a hanging cloth sag into a "super-elastic" sheet; stiff ones force a tiny
//! step. Provot's fix is a pass after integration: a spring longer than `(1 + max_strain)` times
//! its rest length `L` is shortened back to that limit by moving its two ends towards each
//! other, and the stretching motion is removed too, not only its result: the two ends of each
//! spring that was over the limit lose the part of their relative velocity that pulls them
//! apart, as in an inelastic collision along the spring.
//!
//! Provot corrected the velocity by the move divided by the step, `dv = dx / h`. That turns
//! every position correction into motion, also those that fight another pass: where a
//! collider pushes a particle out of a sphere and the stretched springs around it pull it back
//! in, `dx / h` gave the cloth tens of metres per second each step (a resting 128 x 128 cloth
//! on a sphere gained hundreds of joules in two steps, issue #11). The inelastic correction
//! cannot add kinetic energy: each spring's impulse conserves momentum and takes away only
//! separating speed, and each particle takes the average of its springs' impulses (see
//! [`StrainLimit::apply`]), so the pass only ever removes kinetic energy.
//!
//! What is limited, and why:
//! - **Structural and shear springs**, live ones (`springs.active`), whatever the stiffness of
//!   their family (even 0): the limit describes how far the weave can stretch, a property of
//!   the cloth, not of the force model. **Bending springs are not limited** (as in Provot):
//!   each spans two structural springs in a straight line, so by the triangle inequality it
//!   cannot pass `(1 + max_strain)` times its rest length unless one of those does; limiting
//!   it too would add work and couple corrections two particles apart for nothing.
//! - **Stretch only** (`l > (1 + max_strain) L`). Compression is left alone: a compressed
//!   spring is a fold or a wrinkle, which cloth does freely; pushing particles apart would
//!   fight the bending response instead of the over-stretch Provot targets.
//! - Springs of zero rest length have no strain and are skipped.
//!
//! How: a Jacobi iteration. Each sweep reads the positions of the previous sweep and writes new
//! ones into a second buffer, every particle gathering the corrections of its eight limited
//! springs over the grid stencil, in a fixed order, as the force code gathers forces: no
//! atomics, no scatter, and each particle's sum is the same whatever the chunking, so the
//! result is bitwise independent of the number of threads and of `chunk`.
//!
//! The correction of a spring `(p, q)` over the limit `lim = (1 + max_strain) L` is
//!
//! ```text
//! dx_p = w_p / (w_p + w_q) * (l - lim) / l * (x_q - x_p) / max(c_p, c_q)
//! dx_q = -dx_p * m_p / m_q
//! ```
//!
//! with `w` the inverse masses and `c` the number of springs over the limit at each end
//! (counted only at particles that can move). Plain Jacobi applies every spring's full
//! correction at once and overshoots a particle that several springs pull the same way;
//! dividing by the count makes each particle's move at most the average of its springs' full
//! corrections, which cannot overshoot. Dividing by `max(c_p, c_q)` rather than by each end's
//! own count keeps the two ends' moves equal and opposite (bitwise for equal masses), so the
//! pass conserves momentum and the centre of mass; it slows a spring down only where its far
//! end has more springs to fix. There is no over-relaxation factor: on a soft hanging cloth
//! (`hanging` with k / 10) at one sweep per step, 1.5 let the worst strain reach 2.2 instead
//! of 0.71, and 2.0 reached 6.1, worse than no limit (4.8): the velocity correction turns
//! overshoot into motion.
//!
//! Each sweep is preceded by a check that counts the springs over the limit. A check that finds
//! none that a correction could move ends the pass, so a cloth within its limit costs one check
//! and is left bitwise unchanged; so does a sweep that changes no position (every correction
//! smaller than an ulp of the coordinates: the float floor, a few `1e-6` of strain above the
//! limit for the tests' metre-sized cloths), since every further sweep would return the same
//! state.
//!
//! Convergence is local: a sweep carries a correction one particle further, so a few sweeps
//! undo over-stretch near pins, grabs and impacts, but a stretch spread over the whole cloth
//! (all of it has to shrink from the edges in) needs on the order of `n^2` sweeps for an `n`
//! wide cloth (330 sweeps for a 6 x 6 cloth stretched by half, 1121 for 12 x 12). In a
//! simulation the sweeps add up across steps, each step starting from the last one's result.
//!
//! Cost: a check is a fraction of a symplectic Euler step, a sweep with its check about half a
//! step, and the velocity correction one more sweep's work, only in steps where a spring was
//! over the limit; memory is 26 bytes per particle.
//!
//! In a step it belongs after the integrator and the kinematic pins (so that it pulls the
//! cloth after a dragged particle, instead of back to where the particle was) and before the
//! colliders (so that contacts have the last word).

use std::ops::Range;

use rayon::prelude::*;

use crate::forces::springs::{neighbour_runs, Run};
use crate::forces::Springs;
use crate::grid::{Grid, SpringKind};
use crate::integrators::FiniteCheck;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::state::{Kinematics, Particles};

/// The spring kinds the pass limits: structural and shear (see the module documentation).
pub const LIMITED_KINDS: [SpringKind; 4] = [
    SpringKind::StructuralI,
    SpringKind::StructuralJ,
    SpringKind::ShearDiagonal,
    SpringKind::ShearAntiDiagonal,
];

/// What one [`StrainLimit::apply`] did, measured by its last check (after the last sweep).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainStats {
    /// Correction sweeps that moved something: 0 when nothing was over the limit.
    pub iterations: u32,
    /// Live structural and shear springs still over the limit, those joining two particles
    /// that cannot move (pinned or cut) included: nothing can shorten them.
    pub over_limit: u32,
    /// Largest relative stretch `l / L - 1` over all live structural and shear springs, or 0
    /// when none is stretched.
    pub worst_strain: f32,
    /// Whether every value the pass wrote is finite.
    pub finite: bool,
}

impl Default for StrainStats {
    /// A pass that found nothing to do.
    fn default() -> Self {
        StrainStats {
            iterations: 0,
            over_limit: 0,
            worst_strain: 0.0,
            finite: true,
        }
    }
}

/// Provot strain limiting: after integration, structural and shear springs stretched beyond
/// `(1 + max_strain)` times their rest length are shortened back towards it by moving their
/// ends (shared by inverse mass), and velocities are corrected by the position change / `h`.
/// Memory: 25 bytes per particle (two position buffers and a count), made on the first call.
#[derive(Clone, Debug)]
pub struct StrainLimit {
    /// Largest allowed relative stretch `l / L - 1` (dimensionless; Provot used 0.1, the
    /// default). Smaller is stiffer-looking cloth and more springs to correct each step, so
    /// more sweeps to reach the limit; must be finite and `>= 0`.
    pub max_strain: f32,
    /// Correction sweeps per call at most (default [`StrainLimit::DEFAULT_ITERATIONS`]). More
    /// holds the limit more tightly during fast motion, each sweep costing about half a step
    /// while something is over the limit; the pass stops early once nothing is (or nothing
    /// moves any more). A sweep carries a correction one particle further, so a few fix local
    /// over-stretch (near pins, at a grab, at an impact) while a stretch spread over the whole
    /// cloth is undone over several steps. 0 only measures ([`StrainStats`]), changing nothing.
    pub iterations: u32,
    /// Positions written by the last sweep, and the buffer the next sweep writes; after the
    /// sweeps, the second holds the velocity corrections.
    pos: [Vec3s; 2],
    /// Springs over the limit at each particle that can move: from the first check (the
    /// springs whose stretching motion the velocity correction removes), and from the last.
    count: [Vec<u8>; 2],
}

/// What a check of a whole state found.
#[derive(Clone, Copy, Debug, Default)]
struct Check {
    /// Springs over the limit (each counted once, at its anchor).
    over: u32,
    /// Spring ends over the limit that can move: zero means no sweep could change anything.
    movable: u32,
    /// Largest `(l / L)^2`, at least 1.
    worst_ratio2: f32,
}

impl Check {
    fn merge(self, other: Check) -> Check {
        Check {
            over: self.over + other.over,
            movable: self.movable + other.movable,
            worst_ratio2: self.worst_ratio2.max(other.worst_ratio2),
        }
    }
}

impl Default for StrainLimit {
    fn default() -> Self {
        StrainLimit::new(Self::DEFAULT_MAX_STRAIN, Self::DEFAULT_ITERATIONS)
    }
}

impl StrainLimit {
    pub const NAME: &'static str = "strain_limit";
    /// Provot's 10 %.
    pub const DEFAULT_MAX_STRAIN: f32 = 0.1;
    /// Four sweeps (of positions, and as many of velocities): enough to undo local
    /// over-stretch near pins, grabs and impacts in a step; soft or large cloths that hang on
    /// the limit want 8-16. docs/stability.md measures the worst strain they leave.
    pub const DEFAULT_ITERATIONS: u32 = 4;

    /// # Panics
    /// If `max_strain` is not finite or negative (validate scene input before).
    pub fn new(max_strain: f32, iterations: u32) -> Self {
        assert!(
            max_strain.is_finite() && max_strain >= 0.0,
            "max_strain must be finite and >= 0, got {max_strain}"
        );
        StrainLimit {
            max_strain,
            iterations,
            pos: Default::default(),
            count: Default::default(),
        }
    }

    /// Heap memory held by the reusable buffers.
    pub fn heap_bytes(&self) -> usize {
        self.pos.iter().map(Vec3s::heap_bytes).sum::<usize>()
            + self.count.iter().map(Vec::capacity).sum::<usize>()
    }

    /// Applies the limit to `next` (the state the integrator just wrote), in place: positions
    /// by the sweeps, then velocities by the inelastic correction of every spring that was
    /// over the limit before the sweeps and whose ends still move apart along it:
    ///
    /// ```text
    /// s = max(0, (v_q - v_p) . d) / (|d|^2 max(c_p, c_q))        d = x_q - x_p (after)
    /// dv_p = w_p / (w_p + w_q) s d,       dv_q = -w_q / (w_p + w_q) s d
    /// ```
    ///
    /// Each particle's new velocity is then a convex combination of its old velocity and the
    /// velocities each of its springs' full impulses would give it (weights `1 / max(c_p,
    /// c_q) <= 1 / c_p`), and each full impulse keeps its pair's momentum and does not raise
    /// its kinetic energy; by Jensen's inequality the pass cannot raise the total kinetic
    /// energy.
    /// Particles with `inv_mass == 0` (pinned, kinematic or cut) are never moved and keep
    /// their bits; so does every particle no correction reached. `chunk` is the number of
    /// particles per parallel work item; the result does not depend on it.
    ///
    /// `next` should be finite (check the integrator's result first): a spring with a
    /// non-finite end is ignored, it does not spread to its neighbours.
    ///
    /// Allocates only when the number of particles changes (the first call).
    ///
    /// # Panics
    /// If `chunk` is 0 or `next` does not have `grid.len()` particles.
    pub fn apply(
        &mut self,
        grid: Grid,
        springs: &Springs,
        particles: &Particles,
        next: &mut Kinematics,
        chunk: usize,
    ) -> StrainStats {
        let n = grid.len();
        assert!(chunk > 0, "chunk must be positive");
        assert_eq!(next.pos.len(), n, "state and grid disagree");
        if self.count[0].len() != n {
            self.pos = [Vec3s::zeros(n), Vec3s::zeros(n)];
            self.count = [vec![0; n], vec![0; n]];
        }
        let kernel = Kernel {
            grid,
            springs,
            inv_mass: &particles.inv_mass,
            factor: 1.0 + self.max_strain,
        };
        let Self {
            iterations,
            pos: [written, spare],
            count: [first, latest],
            ..
        } = self;

        let mut check = kernel.check(&next.pos, first, chunk);
        let mut sweeps = 0;
        while sweeps < *iterations && check.movable > 0 {
            // The first sweep reads the integrator's positions and the first check's counts
            // directly; later ones the last sweep's and the last check's.
            let (source, count) = if sweeps == 0 {
                (&next.pos, &*first)
            } else {
                (&*written, &*latest)
            };
            if !kernel.sweep(source, count, spare, chunk) {
                // Every correction was lost to rounding: the positions are a fixed point of the
                // sweep, and more sweeps would return exactly this state (and the last check).
                break;
            }
            std::mem::swap(written, spare);
            sweeps += 1;
            check = kernel.check(written, latest, chunk);
        }
        let finite = sweeps == 0 || {
            // As many Jacobi sweeps over the velocities as over the positions: one leaves part
            // of the separating speed where several springs pull on a particle.
            // Each sweep carries the correction one spring further; stop when no over-limit
            // spring moves apart any more.
            for _ in 0..sweeps {
                if !kernel.velocity_corrections(next, written, first, spare, chunk) {
                    break;
                }
                add_corrections(&mut next.vel, spare, first, chunk);
            }
            correct_state(next, written, chunk)
        };
        StrainStats {
            iterations: sweeps,
            over_limit: check.over,
            finite,
            worst_strain: check.worst_ratio2.sqrt() - 1.0,
        }
    }
}

/// What the check and the sweep read.
struct Kernel<'a> {
    grid: Grid,
    springs: &'a Springs,
    inv_mass: &'a [f32],
    /// `1 + max_strain`.
    factor: f32,
}

/// Whether a spring of squared length `l2`, rest length `rest` and `active` flag is over the
/// limit `factor * rest`. The check and the sweep must agree bit for bit on this (the counts
/// they share depend on it), so both call this one function. A non-finite length is never
/// over: a diverged neighbour is left for the integrator's check to report.
#[inline(always)]
fn over_limit(l2: f32, rest: f32, active: f32, factor: f32) -> bool {
    let lim = factor * rest;
    // `&`, not `&&`: no branches, so the loops calling this vectorise.
    (active != 0.0) & (rest > 0.0) & (l2 > lim * lim) & (l2 < f32::INFINITY)
}

impl Kernel<'_> {
    /// Counts, for every particle that can move, its springs over the limit in `pos` into
    /// `count`, and returns the totals.
    fn check(&self, pos: &Vec3s, count: &mut [u8], chunk: usize) -> Check {
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
        run: Run,
        start: usize,
        count: &mut [u8],
    ) -> Check {
        let len = run.len;
        let (a, b, s) = (
            run.a..run.a + len,
            run.b..run.b + len,
            run.spring..run.spring + len,
        );
        // Every slice cut to `len` up front, so that the loop has no bounds checks and vectorises.
        let (xa, ya, za) = (&pos.x[a.clone()], &pos.y[a.clone()], &pos.z[a.clone()]);
        let (xb, yb, zb) = (&pos.x[b.clone()], &pos.y[b.clone()], &pos.z[b]);
        let (xa, ya, za, xb, yb, zb) = (
            &xa[..len],
            &ya[..len],
            &za[..len],
            &xb[..len],
            &yb[..len],
            &zb[..len],
        );
        let rest = &self.springs.rest[kind.index()][s.clone()][..len];
        let active = &self.springs.active[kind.index()][s][..len];
        let wa = &self.inv_mass[a.clone()][..len];
        let count = &mut count[a.start - start..a.end - start][..len];
        let factor = self.factor;
        // The largest ratio is kept as the bits of a positive float, which order like the
        // floats: an integer maximum vectorises, a float one (NaN-aware) does not.
        let (mut over, mut movable, mut worst) = (0u32, 0u32, 1.0f32.to_bits());
        for i in 0..len {
            let (dx, dy, dz) = (xb[i] - xa[i], yb[i] - ya[i], zb[i] - za[i]);
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
    fn sweep(&self, pos: &Vec3s, count: &[u8], out: &mut Vec3s, chunk: usize) -> bool {
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
    fn velocity_corrections(
        &self,
        before: &Kinematics,
        after: &Vec3s,
        count: &[u8],
        out: &mut Vec3s,
        chunk: usize,
    ) -> bool {
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
        run: Run,
        start: usize,
        out: &mut Vec3SliceMut,
    ) -> bool {
        let len = run.len;
        let (a, b, s) = (
            run.a..run.a + len,
            run.b..run.b + len,
            run.spring..run.spring + len,
        );
        let (x0a, x0b) = run_ends(&before.pos, &a, &b);
        let (xa, xb) = run_ends(after, &a, &b);
        let (va, vb) = run_ends(&before.vel, &a, &b);
        let rest = &self.springs.rest[kind.index()][s.clone()][..len];
        let active = &self.springs.active[kind.index()][s][..len];
        let (wa, wb) = (
            &self.inv_mass[a.clone()][..len],
            &self.inv_mass[b.clone()][..len],
        );
        let (ca, cb) = (&count[a.clone()][..len], &count[b][..len]);
        let o = a.start - start..a.end - start;
        let (ox, oy, oz) = (
            &mut out.x[o.clone()][..len],
            &mut out.y[o.clone()][..len],
            &mut out.z[o][..len],
        );
        let factor = self.factor;
        let mut any = 0u32;
        for i in 0..len {
            let d0 = [
                x0b[0][i] - x0a[0][i],
                x0b[1][i] - x0a[1][i],
                x0b[2][i] - x0a[2][i],
            ];
            let was_over = over_limit(
                d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2],
                rest[i],
                active[i],
                factor,
            );
            let (dx, dy, dz) = (
                xb[0][i] - xa[0][i],
                xb[1][i] - xa[1][i],
                xb[2][i] - xa[2][i],
            );
            let l2 = dx * dx + dy * dy + dz * dz;
            let apart = (vb[0][i] - va[0][i]) * dx
                + (vb[1][i] - va[1][i]) * dy
                + (vb[2][i] - va[2][i]) * dz;
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

    /// Adds the corrections of one run of springs to `out` (which starts at particle `start`).
    #[inline(always)]
    fn sweep_run(
        &self,
        pos: &Vec3s,
        count: &[u8],
        kind: SpringKind,
        run: Run,
        start: usize,
        out: &mut Vec3SliceMut,
    ) {
        let len = run.len;
        let (a, b, s) = (
            run.a..run.a + len,
            run.b..run.b + len,
            run.spring..run.spring + len,
        );
        // Every slice cut to `len` up front, so that the loop has no bounds checks and vectorises.
        let (xa, ya, za) = (&pos.x[a.clone()], &pos.y[a.clone()], &pos.z[a.clone()]);
        let (xb, yb, zb) = (&pos.x[b.clone()], &pos.y[b.clone()], &pos.z[b.clone()]);
        let (xa, ya, za, xb, yb, zb) = (
            &xa[..len],
            &ya[..len],
            &za[..len],
            &xb[..len],
            &yb[..len],
            &zb[..len],
        );
        let rest = &self.springs.rest[kind.index()][s.clone()][..len];
        let active = &self.springs.active[kind.index()][s][..len];
        let (wa, wb) = (
            &self.inv_mass[a.clone()][..len],
            &self.inv_mass[b.clone()][..len],
        );
        let (ca, cb) = (&count[a.clone()][..len], &count[b][..len]);
        let o = a.start - start..a.end - start;
        let (ox, oy, oz) = (
            &mut out.x[o.clone()][..len],
            &mut out.y[o.clone()][..len],
            &mut out.z[o][..len],
        );
        let factor = self.factor;
        for i in 0..len {
            let (dx, dy, dz) = (xb[i] - xa[i], yb[i] - ya[i], zb[i] - za[i]);
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

/// The three components of `v` over the spring ends `a` and `b`, each cut to the run's length.
type Ends<'a> = ([&'a [f32]; 3], [&'a [f32]; 3]);

#[inline(always)]
fn run_ends<'a>(v: &'a Vec3s, a: &Range<usize>, b: &Range<usize>) -> Ends<'a> {
    let len = a.len();
    let (a, b) = (v.slices(a.clone()), v.slices(b.clone()));
    (
        [&a.x[..len], &a.y[..len], &a.z[..len]],
        [&b.x[..len], &b.y[..len], &b.z[..len]],
    )
}

/// Adds the velocity corrections `dv` to the particles the first check counted springs at
/// (`count`); every other velocity keeps its bits.
fn add_corrections(vel: &mut Vec3s, dv: &Vec3s, count: &[u8], chunk: usize) {
    vel.par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, mut v)| {
            let range = c * chunk..c * chunk + v.len();
            let count = &count[range.clone()];
            for comp in 0..3 {
                let (v, dv) = (v.component_mut(comp), dv.component(comp, &range));
                for i in 0..v.len() {
                    if count[i] != 0 {
                        v[i] += dv[i];
                    }
                }
            }
        });
}

/// Writes the limited positions `limited` into `next`; returns whether every velocity is
/// finite.
fn correct_state(next: &mut Kinematics, limited: &Vec3s, chunk: usize) -> bool {
    let Kinematics { pos, vel } = next;
    pos.par_chunks_mut(chunk)
        .zip(vel.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (mut x, mut v))| {
            let range = c * chunk..c * chunk + x.len();
            let mut check = FiniteCheck::default();
            for comp in 0..3 {
                x.component_mut(comp)
                    .copy_from_slice(limited.component(comp, &range));
                for &v in v.component_mut(comp).iter() {
                    check.watch(v);
                }
            }
            check.all_finite()
        })
        .reduce(|| true, |a, b| a & b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_live_springs_with_a_rest_length_and_a_finite_length_above_the_limit_are_over() {
        let (factor, rest) = (1.1f32, 0.5f32);
        let lim2 = (factor * rest) * (factor * rest);
        assert!(!over_limit(lim2, rest, 1.0, factor)); // at the limit: not over
        assert!(over_limit(
            f32::from_bits(lim2.to_bits() + 1),
            rest,
            1.0,
            factor
        ));
        assert!(!over_limit(4.0 * lim2, rest, 0.0, factor)); // cut spring
        assert!(!over_limit(4.0 * lim2, 0.0, 1.0, factor)); // no rest length
        assert!(!over_limit(0.01 * lim2, rest, 1.0, factor)); // compressed
        assert!(!over_limit(f32::NAN, rest, 1.0, factor));
        assert!(!over_limit(f32::INFINITY, rest, 1.0, factor));
    }

    #[test]
    fn buffers_are_made_on_the_first_call_only() {
        let limit = StrainLimit::default();
        assert_eq!(limit.heap_bytes(), 0);
        assert_eq!(limit.max_strain, StrainLimit::DEFAULT_MAX_STRAIN);
        assert_eq!(limit.iterations, StrainLimit::DEFAULT_ITERATIONS);
    }

    #[test]
    #[should_panic(expected = "max_strain")]
    fn a_negative_limit_is_refused() {
        StrainLimit::new(-0.1, 4);
    }
}
