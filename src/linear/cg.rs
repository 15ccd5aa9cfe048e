//! The preconditioned conjugate gradient on a system `A x = b` of 3-vectors, `A` symmetric
//! positive definite (a [`BlockStencil`] on the grid, a [`super::SpringMatrix`] on a mesh) (Hestenes and Stiefel 1952; Shewchuk, "An introduction to the conjugate
//! gradient method without the agonizing pain", 1994):
//!
//! ```text
//! x = 0, r = b, z = M^-1 r, p = z
//! repeat: q = A p, alpha = (r . z) / (p . q), x += alpha p, r -= alpha q,
//!         z = M^-1 r, beta = (r . z)_new / (r . z), p = z + beta p
//! ```
//!
//! until `|r| / |b|` is below the tolerance. Started from a guess `x` instead
//! ([`Start::Guess`]), `r = b - A x` and the same stop on `|r| / |b|`.
//! The preconditioner `M^-1` is the caller's (block
//! Jacobi through [`diagonal_blocks`], a multigrid V-cycle); it must be symmetric positive
//! definite for the iteration to be CG.
//!
//! **Filtered.** [`ConjugateGradient::solve_filtered`] takes a projection `S` (symmetric,
//! `S^2 = S`) and keeps every vector in its range: `r = S b`, `z = S M^-1 r`, `q = S A p`. It is
//! then CG on `S A S` restricted to `range(S)`, preconditioned by `S M^-1 S`, both positive
//! definite there when `A` and `M` are (Ascher and Boxerman, "On the modified conjugate
//! gradient method in cloth simulation", 2003: the pre-filtered PPCG of Baraff and Witkin's
//! constraint filtering), and `x` stays in `range(S)`. A direction along which `p . q` is not positive (the
//! matrix is not positive definite there, or overflowed) ends the solve where it stands.
//!
//! Dot products are partial sums over fixed chunks added in order ([`super::reduce`]) and every
//! vector update writes only its own chunk, so the iterates are bitwise the same for any number
//! of threads.

use rayon::prelude::*;

use super::block_lanes::Packed;
use super::reduce::{dot, dot3, par_dot, partials, REDUCE_CHUNK};
use super::stencil::{set_product, BlockStencil, SlotArrays};
use crate::soa::{Vec3SliceMut, Vec3s};

/// A symmetric matrix of 3 x 3 blocks that CG can multiply by, a range of rows at a time.
pub trait BlockOperator: Sync {
    /// `out = A x` over the rows `range` (`out` covers exactly `range`).
    /// Called after [`BlockOperator::prepare`] with the same `x`.
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut);

    /// Readies a product with `x`, once before its ranges of rows: what many rows share is
    /// computed here once (nothing by default).
    fn prepare(&self, _x: &Vec3s) {}

    /// Whether a product reads its operand faster packed whole, once before its ranges of rows
    /// ([`Packed`]): then the callers that keep a [`Packed`] pack `x` into it and call
    /// [`BlockOperator::apply_range_packed`] (false by default).
    fn packs(&self) -> bool {
        false
    }

    /// [`BlockOperator::apply_range`] given also `x` packed whole just before (a wrapper that
    /// does not forward it multiplies unpacked, by default).
    #[inline(always)]
    fn apply_range_packed(
        &self,
        (x, _packed): (&Vec3s, &Packed),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        self.apply_range(x, range, out)
    }

    /// Whether [`BlockOperator::add_after`] adds anything (false by default).
    fn adds_after(&self) -> bool {
        false
    }

    /// `y += B x` for the part `B` of `A` that [`BlockOperator::apply_range`] leaves out,
    /// after every range of `y` holds its rows: what is cheaper to take over all rows at once
    /// than row range by row range (nothing by default).
    fn add_after(&self, _x: &Vec3s, _y: &mut Vec3s) {}

    /// `y = A x`, in parallel over chunks of `chunk` rows.
    fn apply(&self, x: &Vec3s, y: &mut Vec3s, chunk: usize) {
        self.prepare(x);
        y.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, mut out)| {
                let range = c * chunk..c * chunk + out.len();
                crate::simd::dispatch!(self.apply_range(x, range.clone(), &mut out));
            });
        if self.adds_after() {
            self.add_after(x, y);
        }
    }
}

/// An operator whose products read their operand as `packed` holds it, packed whole just
/// before ([`BlockOperator::apply_range_packed`]): a type of its own, so that an operator that
/// does not pack keeps its product's code as it is.
pub(crate) struct Packing<'a, A> {
    pub a: &'a A,
    pub packed: &'a Packed,
}

impl<A: BlockOperator> BlockOperator for Packing<'_, A> {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        self.a.apply_range_packed((x, self.packed), range, out);
    }

    fn adds_after(&self) -> bool {
        self.a.adds_after()
    }

    fn add_after(&self, x: &Vec3s, y: &mut Vec3s) {
        self.a.add_after(x, y);
    }
}

/// `q = A p` (after [`BlockOperator::prepare`]), returning `p . q`.
fn product<A: BlockOperator>(a: &A, p: &Vec3s, q: &mut Vec3s, partials: &mut [f64]) -> f64 {
    if a.adds_after() {
        // `p . q` only once the part taken after the rows is in.
        q.par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(c, mut q)| {
                let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + q.len();
                crate::simd::dispatch!(a.apply_range(p, range.clone(), &mut q));
            });
        a.add_after(p, q);
        return par_dot(p, q, partials);
    }
    q.par_chunks_mut(REDUCE_CHUNK)
        .zip(partials.par_iter_mut())
        .enumerate()
        .for_each(|(c, (mut q, partial))| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + q.len();
            *partial = crate::simd::dispatch!({
                a.apply_range(p, range.clone(), &mut q);
                dot3(p.slices(range.clone()), q.as_slices())
            });
        });
    partials.iter().sum()
}

impl BlockOperator for BlockStencil {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        BlockStencil::apply_range(self, x, range, out)
    }
}

/// Where a solve starts: from `x = 0`, or from the guess `x` holds (in `range(S)`), whose
/// residual `S (b - A x)` starts the iteration; either way it stops on `|r| / |S b|`, so a
/// close guess takes only the iterations its own error needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Start {
    Zero,
    Guess,
}

/// The vectors of a CG solve, kept between solves so that a solve allocates nothing.
#[derive(Clone, Debug, Default)]
pub struct ConjugateGradient {
    r: Vec3s,
    z: Vec3s,
    p: Vec3s,
    q: Vec3s,
    partials: Vec<f64>,
    /// `p` packed for a product whose operator [`BlockOperator::packs`].
    packed: Packed,
}

impl ConjugateGradient {
    /// The workspace for systems of `n` nodes.
    pub fn new(n: usize) -> Self {
        ConjugateGradient {
            r: Vec3s::zeros(n),
            z: Vec3s::zeros(n),
            p: Vec3s::zeros(n),
            q: Vec3s::zeros(n),
            partials: partials(n),
            packed: Packed::default(),
        }
    }

    /// Solves `a x = b` from `x = 0`, with `precondition(r, z)` setting `z = M^-1 r`; stops
    /// when the relative residual `|r| / |b|` is at most `tolerance` or after `max_iterations`.
    /// Returns the iterations and the final relative residual: 0 for `b = 0`, NaN for a
    /// non-finite `b` (`x` is then left zero), and 1 when the first direction already broke
    /// down.
    pub fn solve<A: BlockOperator>(
        &mut self,
        a: &A,
        b: &Vec3s,
        x: &mut Vec3s,
        tolerance: f64,
        max_iterations: u32,
        precondition: impl FnMut(&Vec3s, &mut Vec3s),
    ) -> (u32, f64) {
        let settings = (tolerance, max_iterations);
        self.solve_filtered(a, b, x, settings, precondition, |_| {}, Start::Zero)
    }

    /// [`ConjugateGradient::solve`] with every vector kept in the range of the projection
    /// `filter` (which projects its argument in place): solves `S A S x = S b` for `x` in
    /// `range(S)`, from `start`, stopping on `|r| / |S b|` at most `tolerance` or after
    /// `max_iterations`.
    #[allow(clippy::too_many_arguments)]
    pub fn solve_filtered<A: BlockOperator>(
        &mut self,
        a: &A,
        b: &Vec3s,
        x: &mut Vec3s,
        (tolerance, max_iterations): (f64, u32),
        mut precondition: impl FnMut(&Vec3s, &mut Vec3s),
        mut filter: impl FnMut(&mut Vec3s),
        start: Start,
    ) -> (u32, f64) {
        let warm = start == Start::Guess;
        if !warm {
            x.fill(glam::Vec3::ZERO);
        }
        self.r.copy_from(b);
        filter(&mut self.r);
        let b_dot_b = par_dot(&self.r, &self.r, &mut self.partials);
        let b_norm = b_dot_b.sqrt();
        if !(b_norm > 0.0 && b_norm.is_finite()) {
            // Nothing to solve (every node held, or no load), or a non-finite right-hand side,
            // which the caller's finite check then reports.
            x.fill(glam::Vec3::ZERO);
            return (0, if b_norm == 0.0 { 0.0 } else { f64::NAN });
        }
        let mut residual = 1.0;
        if warm {
            // r = S b - S A x, as an iteration's update from zero along p = x would leave it.
            self.p.copy_from(x);
            self.product(a);
            filter(&mut self.q);
            x.fill(glam::Vec3::ZERO);
            residual = self.advance_solution(x, 1.0).sqrt() / b_norm;
            if residual <= tolerance {
                return (0, residual);
            }
        }
        let mut rz = self.precondition(&mut precondition, &mut filter);
        self.p.copy_from(&self.z);
        let mut iterations = 0;
        while residual > tolerance && iterations < max_iterations {
            let pq = self.product(a);
            filter(&mut self.q);
            if pq <= 0.0 || !pq.is_finite() {
                break; // breakdown: the matrix is not positive definite along p
            }
            let r_dot_r = self.advance_solution(x, (rz / pq) as f32);
            iterations += 1;
            residual = r_dot_r.sqrt() / b_norm;
            if residual <= tolerance {
                break;
            }
            let rz_new = self.precondition(&mut precondition, &mut filter);
            self.next_direction((rz_new / rz) as f32);
            rz = rz_new;
        }
        if iterations == 0 && !warm {
            // The first direction was already a breakdown; keep x = 0.
            residual = 1.0;
        }
        (iterations, residual)
    }

    /// `z = S M^-1 r`, returning `r . z`.
    fn precondition(
        &mut self,
        precondition: &mut impl FnMut(&Vec3s, &mut Vec3s),
        filter: &mut impl FnMut(&mut Vec3s),
    ) -> f64 {
        precondition(&self.r, &mut self.z);
        filter(&mut self.z);
        par_dot(&self.r, &self.z, &mut self.partials)
    }

    /// `q = A p`, returning `p . q`.
    fn product<A: BlockOperator>(&mut self, a: &A) -> f64 {
        let ConjugateGradient {
            p,
            q,
            partials,
            packed,
            ..
        } = self;
        let p = &*p;
        a.prepare(p);
        if a.packs() {
            packed.pack(p);
            return product(&Packing { a, packed }, p, q, partials);
        }
        product(a, p, q, partials)
    }

    /// `x += step p, r -= step q`; returns `r . r`.
    fn advance_solution(&mut self, x: &mut Vec3s, step: f32) -> f64 {
        let ConjugateGradient {
            r, p, q, partials, ..
        } = self;
        let (p, q) = (&*p, &*q);
        x.par_chunks_mut(REDUCE_CHUNK)
            .zip(r.par_chunks_mut(REDUCE_CHUNK))
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((x, r), partial))| {
                let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + x.len();
                *partial = crate::simd::dispatch!({
                    let (p, q) = (p.slices(range.clone()), q.slices(range.clone()));
                    let mut sum = 0.0;
                    for (x, r, p, q) in [
                        (x.x, &mut *r.x, p.x, q.x),
                        (x.y, &mut *r.y, p.y, q.y),
                        (x.z, &mut *r.z, p.z, q.z),
                    ] {
                        for i in 0..x.len() {
                            x[i] += step * p[i];
                            r[i] -= step * q[i];
                        }
                        sum += dot(r, r);
                    }
                    sum
                });
            });
        partials.iter().sum()
    }

    /// `p = z + beta p`.
    fn next_direction(&mut self, beta: f32) {
        let ConjugateGradient { p, z, .. } = self;
        let z = &*z;
        p.par_chunks_mut(REDUCE_CHUNK)
            .enumerate()
            .for_each(|(c, p)| {
                let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + p.len();
                let z = z.slices(range);
                crate::simd::dispatch!({
                    for (p, z) in [(p.x, z.x), (p.y, z.y), (p.z, z.z)] {
                        for (p, z) in p.iter_mut().zip(z) {
                            *p = z + beta * *p;
                        }
                    }
                })
            });
    }
}

/// `z = D r` for the block-diagonal `D` whose blocks are the six component arrays `d` (the
/// Jacobi preconditioners' inverse diagonal).
pub fn diagonal_blocks(d: &SlotArrays, r: &Vec3s, z: &mut Vec3s) {
    z.par_chunks_mut(REDUCE_CHUNK)
        .enumerate()
        .for_each(|(c, mut z)| {
            let range = c * REDUCE_CHUNK..c * REDUCE_CHUNK + z.len();
            let d: [&[f32]; 6] = std::array::from_fn(|k| &d[k][range.clone()]);
            crate::simd::dispatch!(set_product(d, r.slices(range.clone()), &mut z));
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A chain of nodes, each tied to its neighbours: `4 x_i - x_{i-1} - x_{i+1}` per component.
    struct Chain;

    impl BlockOperator for Chain {
        fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
            let n = x.len();
            for (i, p) in range.enumerate() {
                let mut y = 4.0 * x.get(p);
                if p > 0 {
                    y -= x.get(p - 1);
                }
                if p + 1 < n {
                    y -= x.get(p + 1);
                }
                (out.x[i], out.y[i], out.z[i]) = (y.x, y.y, y.z);
            }
        }
    }

    /// A solve started from a guess stops on the residual relative to the right-hand side, as
    /// one from zero does: from the answer it takes no iteration, and from a rough answer it
    /// reaches the same tolerance in fewer iterations than from zero.
    #[test]
    fn a_warm_started_solve_stops_on_the_residual_relative_to_the_right_hand_side() {
        let n = 3000;
        let b = Vec3s::from_fn(n, |p| Vec3::new((p as f32 * 0.01).sin(), 1.0, -0.5));
        let mut cg = ConjugateGradient::new(n);
        let jacobi = |r: &Vec3s, z: &mut Vec3s| z.copy_from(r);
        let mut cold = Vec3s::zeros(n);
        let (cold_iterations, residual) = cg.solve(&Chain, &b, &mut cold, 1e-6, 500, jacobi);
        assert!(residual <= 1e-6, "{residual}");
        let mut warm = cold.clone();
        let limits = (1e-5, 500);
        let (iterations, residual) =
            cg.solve_filtered(&Chain, &b, &mut warm, limits, jacobi, |_| {}, Start::Guess);
        assert_eq!((iterations, warm == cold), (0, true), "{residual}");
        let mut rough = Vec3s::zeros(n);
        cg.solve(&Chain, &b, &mut rough, 1e-2, 500, jacobi);
        let limits = (1e-6, 500);
        let (iterations, residual) =
            cg.solve_filtered(&Chain, &b, &mut rough, limits, jacobi, |_| {}, Start::Guess);
        assert!(residual <= 1e-6, "{residual}");
        assert!(
            (1..cold_iterations).contains(&iterations),
            "{iterations} from the rough answer, {cold_iterations} from zero"
        );
        let error = (0..n)
            .map(|p| (rough.get(p) - cold.get(p)).length())
            .fold(0.0f32, f32::max);
        assert!(error < 1e-5, "{error}");
    }
}
