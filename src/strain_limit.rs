//! Provot strain limiting (X. Provot, "Deformation constraints in a mass-spring model to
//! describe rigid cloth behavior", Graphics Interface 1995).
//!
//! Soft springs let a hanging cloth sag into a "super-elastic" sheet; stiff ones force a tiny
//! step. Provot's fix is a pass after integration: a spring longer than `(1 + max_strain)` times
//! its rest length `L` is shortened back to that limit by moving its two ends towards each
//! other, and the velocity of each moved particle is corrected by the move divided by the step,
//! so that the stretching motion is removed too, not only its result.
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
//! Cost, 128 x 128 on the shared 2-core machine: a check is about 0.17 of a symplectic Euler
//! step, a sweep with its check about half a step; memory is 25 bytes per particle.
//!
//! In a step it belongs after the integrator and the kinematic pins (so that it pulls the
//! cloth after a dragged particle, instead of back to where the particle was) and before the
//! colliders (so that contacts have the last word).

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
    /// Positions written by the last sweep, and the buffer the next sweep writes.
    pos: [Vec3s; 2],
    /// Springs over the limit at each particle that can move, from the last check.
    count: Vec<u8>,
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
    /// Four sweeps: with a call after every step, they cut the worst strain of the built-in
    /// `hanging` scene (32 x 32) from 0.46 to 0.18 and of `drape` from 0.26 to 0.107, for
    /// about two sweeps per step on average while the cloth hangs at its limit and none when
    /// it is within it (46 sweeps in 2000 steps of `drape`). Eight reach 0.15 and 0.100 for
    /// twice the cost; soft or large cloths that hang on the limit want 8-16.
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
            count: Vec::new(),
        }
    }

    /// Heap memory held by the reusable buffers.
    pub fn heap_bytes(&self) -> usize {
        self.pos.iter().map(Vec3s::heap_bytes).sum::<usize>() + self.count.capacity()
    }

    /// Applies the limit to `next` (the state the integrator just wrote), in place; `h` (s) is
    /// the (sub)step that produced it, used for the velocity correction `dv = dx / h`.
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
    /// If `chunk` is 0, `h` is not positive, or `next` does not have `grid.len()` particles.
    pub fn apply(
        &mut self,
        h: f32,
        grid: Grid,
        springs: &Springs,
        particles: &Particles,
        next: &mut Kinematics,
        chunk: usize,
    ) -> StrainStats {
        let n = grid.len();
        assert!(chunk > 0, "chunk must be positive");
        assert!(h > 0.0, "the step h must be positive, got {h}");
        assert_eq!(next.pos.len(), n, "state and grid disagree");
        if self.count.len() != n {
            self.pos = [Vec3s::zeros(n), Vec3s::zeros(n)];
            self.count = vec![0; n];
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
            count,
            ..
        } = self;

        let mut check = kernel.check(&next.pos, count, chunk);
        let mut sweeps = 0;
        while sweeps < *iterations && check.movable > 0 {
            // The first sweep reads the integrator's positions directly; later ones the last
            // sweep's, in `written`.
            let source = if sweeps == 0 { &next.pos } else { &*written };
            if !kernel.sweep(source, count, spare, chunk) {
                // Every correction was lost to rounding: the positions are a fixed point of the
                // sweep, and more sweeps would return exactly this state (and the last check).
                break;
            }
            std::mem::swap(written, spare);
            sweeps += 1;
            check = kernel.check(written, count, chunk);
        }
        let finite = sweeps == 0 || correct_state(next, written, h, chunk);
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

/// Writes the limited positions `limited` into `next` and adds the move over `h` to the
/// velocities. A component that did not move keeps its velocity bits.
/// Returns whether every velocity is finite afterwards (`dx / h` overflows for a move near
/// float32's range).
fn correct_state(next: &mut Kinematics, limited: &Vec3s, h: f32, chunk: usize) -> bool {
    let Kinematics { pos, vel } = next;
    pos.par_chunks_mut(chunk)
        .zip(vel.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (mut x, mut v))| {
            let range = c * chunk..c * chunk + x.len();
            let mut check = FiniteCheck::default();
            for comp in 0..3 {
                let (x, v) = (x.component_mut(comp), v.component_mut(comp));
                let new = limited.component(comp, &range);
                for i in 0..x.len() {
                    let dx = new[i] - x[i];
                    if dx != 0.0 {
                        v[i] += dx / h;
                    }
                    x[i] = new[i];
                    check.watch(v[i]);
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
