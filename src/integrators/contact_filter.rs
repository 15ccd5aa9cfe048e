//! Implicit Euler's predicted contacts held exactly inside its linear solve: constraint
//! filtering (Baraff and Witkin, "Large steps in cloth simulation", 1998, section 5.3), in the
//! pre-filtered form that is conjugate gradient on a positive definite system (Ascher and
//! Boxerman, "On the modified conjugate gradient method in cloth simulation", 2003; the change
//! of variables of Tamstorf, Jones and McCormick, "Smoothed aggregation multigrid for cloth
//! simulation", 2015).
//!
//! A free particle with a predicted contact (outward unit normal `n`, plane `n . x = offset`)
//! ends the step on its target `t = min(offset, n . x)` along `n`: on the plane, or where it
//! is when it starts behind it (pulling it onto the plane within the step would turn the depth
//! into speed; the collider pass after the step puts it out without velocity). From
//! `x' = x + h (v + dv)` its velocity change has the prescribed normal part
//!
//! ```text
//! dv . n = z = (t - n . x) / h - n . v
//! ```
//!
//! and a free tangential part. With `S = I - n n^T` at held particles (`I` elsewhere) and `z`
//! the vector of the `z n`, `dv = z + y` with `y` in `range(S)` and `A dv = b` on the free
//! directions is
//!
//! ```text
//! S A S y = S (b - A z)
//! ```
//!
//! solved by [`crate::linear::cg::ConjugateGradient::solve_filtered`] with this filter. Unlike
//! a stiff spring onto the plane, which leaves a particle `1 / (1 + stiffness)` of its free
//! motion behind the plane for the collider pass to push out (and that push adds energy to
//! the springs around it), the particle ends on its plane to rounding.
//!
//! What the contact did is the residual along `n` of the unfiltered system, its impulse
//! `n . (A dv - b)` (N s): positive where it pushes. One that pulls (the springs lifted the
//! particle off its plane) is released by [`crate::collisions::PredictedContacts::correct`].

use glam::Vec3;

use crate::collisions::PredictedContacts;
use crate::soa::Vec3s;

/// One particle held on its plane.
#[derive(Clone, Copy, Debug)]
struct Held {
    p: usize,
    /// Outward unit normal of its contact plane.
    n: Vec3,
    /// Prescribed normal velocity change, m/s.
    z: f32,
    /// `n . b` of the unfiltered right-hand side, N s.
    b: f32,
    /// The stiffness `k` of the `k n n^T` the matrix holds on its diagonal block (kg): it
    /// does not change the filtered system (`S n = 0`) but shapes the preconditioner.
    k: f32,
}

/// The held particles of one solve and what their contacts did, kept between steps so that
/// a step allocates nothing.
#[derive(Default)]
pub(super) struct ContactFilter {
    held: Vec<Held>,
    /// Per particle, the normal impulse (N s) its contact gave in the last solve; zero without
    /// one.
    impulse: Vec<f32>,
    /// `z`, then `A z`; then `A dv`.
    prescribed: Vec3s,
    product: Vec3s,
}

impl ContactFilter {
    /// The held particles of a step of length `h` from `(pos, vel)`: the free particles
    /// (`inv_mass > 0`) with a contact in `contacts`; `stiffness(p)` is the `k` of the
    /// `k n n^T` the caller adds to particle `p`'s diagonal block.
    pub(super) fn gather(
        &mut self,
        h: f32,
        contacts: Option<&PredictedContacts>,
        (pos, vel, inv_mass): (&Vec3s, &Vec3s, &[f32]),
        stiffness: impl Fn(usize) -> f32,
    ) {
        let n = pos.len();
        self.held.clear();
        if self.impulse.len() != n {
            // Room for every particle held: a step allocates nothing however many land.
            self.held = Vec::with_capacity(n);
            self.impulse = vec![0.0; n];
            self.prescribed = Vec3s::zeros(n);
            self.product = Vec3s::zeros(n);
        }
        self.impulse.fill(0.0);
        let Some(contacts) = contacts.filter(|c| c.count > 0) else {
            return;
        };
        for (p, &w) in inv_mass.iter().enumerate() {
            let normal = contacts.normal.get(p);
            if normal == Vec3::ZERO || w == 0.0 {
                continue;
            }
            let at = normal.dot(pos.get(p));
            let target = contacts.offset[p].min(at);
            let z = (target - at) / h - normal.dot(vel.get(p));
            let k = stiffness(p);
            self.held.push(Held {
                p,
                n: normal,
                z,
                b: 0.0,
                k,
            });
        }
    }

    /// Whether no particle is held: the solve is the plain one.
    pub(super) fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// `v = S v`: the normal part of each held particle's vector removed.
    pub(super) fn project(&self, v: &mut Vec3s) {
        for h in &self.held {
            let x = v.get(h.p);
            v.set(h.p, x - h.n.dot(x) * h.n);
        }
    }

    /// `b = S (b - A z)`, where `apply(x, y)` sets `y = A x`; keeps `n . b` of each held
    /// particle for its impulse.
    pub(super) fn reduce(&mut self, b: &mut Vec3s, apply: impl FnOnce(&Vec3s, &mut Vec3s)) {
        self.prescribed.fill(Vec3::ZERO);
        for h in &mut self.held {
            h.b = h.n.dot(b.get(h.p));
            self.prescribed.set(h.p, h.z * h.n);
        }
        apply(&self.prescribed, &mut self.product);
        for i in 0..b.len() {
            b.set(i, b.get(i) - self.product.get(i));
        }
        self.project(b);
    }

    /// `dv = S y + z` from the filtered solution `y` in `dv`, then each held particle's
    /// impulse `n . (A dv - b)` (`apply` as for [`ContactFilter::reduce`]).
    pub(super) fn finish(&mut self, dv: &mut Vec3s, apply: impl FnOnce(&Vec3s, &mut Vec3s)) {
        for h in &self.held {
            let y = dv.get(h.p);
            dv.set(h.p, y - h.n.dot(y) * h.n + h.z * h.n);
        }
        apply(dv, &mut self.product);
        for h in &self.held {
            // The diagonal's `k n n^T` is not part of the contact-free system.
            self.impulse[h.p] = h.n.dot(self.product.get(h.p)) - h.k * h.z - h.b;
        }
    }

    /// Per particle, the normal impulse (N s) its contact gave in the last solve; zero without
    /// one.
    pub(super) fn impulses(&self) -> &[f32] {
        &self.impulse
    }
}
