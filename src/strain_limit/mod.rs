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
//! on a sphere gains hundreds of joules in two steps). The inelastic correction
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

mod kernel;
mod mesh;

use rayon::prelude::*;

use crate::grid::{Grid, SpringKind};
use crate::integrators::FiniteCheck;
use crate::mesh_cloth::MeshCloth;
use crate::particles::Particles;
use crate::soa::Vec3s;
use crate::springs::Springs;
use crate::state::Kinematics;
use kernel::Kernel;

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
pub(super) struct Check {
    /// Springs over the limit (each counted once, at its anchor).
    pub over: u32,
    /// Spring ends over the limit that can move: zero means no sweep could change anything.
    pub movable: u32,
    /// Largest `(l / L)^2`, at least 1.
    pub worst_ratio2: f32,
}

impl Check {
    pub(super) fn merge(self, other: Check) -> Check {
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
        assert_eq!(next.pos.len(), grid.len(), "state and grid disagree");
        let kernel = Kernel {
            grid,
            springs,
            mesh: None,
            inv_mass: &particles.inv_mass,
            factor: 1.0 + self.max_strain,
        };
        self.run(&kernel, next, chunk)
    }

    /// [`StrainLimit::apply`] on a mesh cloth: its stretch springs (one on every edge) are
    /// limited, its bend springs are not, as the grid's bending springs are not. Each vertex
    /// gathers the corrections of its springs in spring order, so the result is bitwise the same
    /// for any number of threads. `grid` and `springs` are the model's (a one-row grid with an
    /// empty stencil).
    ///
    /// # Panics
    /// If `chunk` is 0 or `next` does not have one particle per vertex.
    pub fn apply_mesh(
        &mut self,
        (grid, springs): (Grid, &Springs),
        mesh: &MeshCloth,
        particles: &Particles,
        next: &mut Kinematics,
        chunk: usize,
    ) -> StrainStats {
        assert_eq!(next.pos.len(), mesh.len(), "state and mesh disagree");
        let kernel = Kernel {
            grid,
            springs,
            mesh: Some(mesh),
            inv_mass: &particles.inv_mass,
            factor: 1.0 + self.max_strain,
        };
        self.run(&kernel, next, chunk)
    }

    fn run(&mut self, kernel: &Kernel, next: &mut Kinematics, chunk: usize) -> StrainStats {
        let n = next.pos.len();
        assert!(chunk > 0, "chunk must be positive");
        if self.count[0].len() != n {
            self.pos = [Vec3s::zeros(n), Vec3s::zeros(n)];
            self.count = [vec![0; n], vec![0; n]];
        }
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
    use super::kernel::over_limit;
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
