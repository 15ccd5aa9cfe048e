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
//! A sticking contact (`PredictedContacts::stuck`) is held in all three directions: `S = 0` at
//! its particle, and `z` prescribes its tangential velocity too, to the surface's own (the
//! particle stays put on a still collider), so the solve balances its neighbours against it
//! instead of friction moving it back after the solve. A sliding contact's friction is a
//! damper on its tangential velocity relative to the surface's (`c = slide_damping`): `c P_t`
//! on its diagonal block (`P_t = I - n n^T`, added by the integrator with the contact's `k`)
//! and `-c P_t (v - u)` in `b`.
//!
//! What the contact did is the residual of the unfiltered system at its particle, its impulse
//! `A dv - b` (N s): along `n` positive where it pushes, across `n` the friction a sticking
//! contact needed. One that pulls (the springs lifted the particle off its plane) is released,
//! and one that needed more friction than Coulomb allows slides, by
//! [`crate::collisions::PredictedContacts::correct`].

use glam::Vec3;

use crate::collisions::{Impulses, PredictedContacts};
use crate::soa::Vec3s;

/// One particle held on its plane.
#[derive(Clone, Copy, Debug)]
struct Held {
    /// The particle, and its place in the solve's vectors (the particle's index, or its place
    /// in the mesh solve's local numbering).
    p: usize,
    at: usize,
    /// Outward unit normal of its contact plane.
    n: Vec3,
    /// Whether it sticks: held in all three directions.
    stuck: bool,
    /// Prescribed normal velocity change, m/s.
    z_n: f32,
    /// Prescribed velocity change, m/s: `z_n n`, plus the tangential change where it sticks.
    z: Vec3,
    /// The friction damper's impulse at the start velocity, `-c P_t (v - u)` (N s), added to
    /// `b`.
    friction: Vec3,
    /// The unfiltered right-hand side at the particle, N s.
    b: Vec3,
    /// The stiffness `k` of the `k n n^T` (`k I` where it sticks) the matrix holds on its
    /// diagonal block (kg): it does not change the filtered system (`S n = 0`) but shapes the
    /// preconditioner.
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
    /// Per particle, the tangential impulse (N s) its sticking contact gave; zero elsewhere.
    tangential: Vec3s,
    /// `z`, then `A z`; then `A dv`.
    prescribed: Vec3s,
    product: Vec3s,
}

impl ContactFilter {
    /// The held particles of a step of length `h` from `(pos, vel)`: the free particles
    /// (`inv_mass > 0`) with a contact in `contacts`; `stiffness(p)` is the `k` of the
    /// `k n n^T` the caller adds to particle `p`'s diagonal block. The solve's vectors hold
    /// particle `p` at `place[p]` (at `p` without `place`); the impulses stay by particle.
    pub(super) fn gather(
        &mut self,
        h: f32,
        contacts: Option<&PredictedContacts>,
        (pos, vel, inv_mass): (&Vec3s, &Vec3s, &[f32]),
        stiffness: impl Fn(usize) -> f32,
        place: Option<&[u32]>,
    ) {
        let n = pos.len();
        self.held.clear();
        if self.impulse.len() != n {
            // Room for every particle held: a step allocates nothing however many land.
            self.held = Vec::with_capacity(n);
            self.impulse = vec![0.0; n];
            self.tangential = Vec3s::zeros(n);
            self.prescribed = Vec3s::zeros(n);
            self.product = Vec3s::zeros(n);
        }
        self.impulse.fill(0.0);
        self.tangential.fill(Vec3::ZERO);
        let Some(contacts) = contacts.filter(|c| c.count > 0) else {
            return;
        };
        for (p, &w) in inv_mass.iter().enumerate() {
            let normal = contacts.normal.get(p);
            if normal == Vec3::ZERO || w == 0.0 {
                continue;
            }
            let (at, v) = (normal.dot(pos.get(p)), vel.get(p));
            let target = contacts.offset[p].min(at);
            let z_n = (target - at) / h - normal.dot(v);
            let stuck = contacts.stuck[p];
            let slip = contacts.surface_velocity.get(p) - (v - normal.dot(v) * normal);
            let across = if stuck { slip } else { Vec3::ZERO };
            let c = contacts.slide_damping[p];
            self.held.push(Held {
                p,
                at: place.map_or(p, |place| place[p] as usize),
                n: normal,
                stuck,
                z_n,
                z: z_n * normal + across,
                friction: if c > 0.0 { c * slip } else { Vec3::ZERO },
                b: Vec3::ZERO,
                k: stiffness(p),
            });
        }
    }

    /// Whether no particle is held: the solve is the plain one.
    pub(super) fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// `v = S v`: the normal part of each held particle's vector removed, all of it where it
    /// sticks.
    pub(super) fn project(&self, v: &mut Vec3s) {
        for h in &self.held {
            let x = v.get(h.at);
            let free = if h.stuck {
                Vec3::ZERO
            } else {
                x - h.n.dot(x) * h.n
            };
            v.set(h.at, free);
        }
    }

    /// `b = S (b - A z)`, where `apply(x, y)` sets `y = A x`; keeps `b` at each held
    /// particle for its impulse.
    pub(super) fn reduce(&mut self, b: &mut Vec3s, apply: impl FnOnce(&Vec3s, &mut Vec3s)) {
        self.prescribed.fill(Vec3::ZERO);
        for h in &mut self.held {
            h.b = b.get(h.at);
            if h.friction != Vec3::ZERO {
                b.set(h.at, h.b + h.friction);
            }
            self.prescribed.set(h.at, h.z);
        }
        apply(&self.prescribed, &mut self.product);
        for i in 0..b.len() {
            b.set(i, b.get(i) - self.product.get(i));
        }
        self.project(b);
    }

    /// `dv = S y + z` from the filtered solution `y` in `dv`, then each held particle's
    /// impulse `A dv - b` (`apply` as for [`ContactFilter::reduce`]).
    pub(super) fn finish(&mut self, dv: &mut Vec3s, apply: impl FnOnce(&Vec3s, &mut Vec3s)) {
        self.project(dv);
        for h in &self.held {
            dv.set(h.at, dv.get(h.at) + h.z);
        }
        apply(dv, &mut self.product);
        for h in &self.held {
            // The diagonal's `k n n^T` (`k I`) is not part of the contact-free system; it acts
            // on `z` alone, which lies in the held directions.
            let product = self.product.get(h.at);
            self.impulse[h.p] = h.n.dot(product) - h.k * h.z_n - h.n.dot(h.b);
            if h.stuck {
                let impulse = product - h.k * h.z - h.b;
                self.tangential.set(h.p, impulse - h.n.dot(impulse) * h.n);
            }
        }
    }

    /// Per particle, what its contact did in the last solve; zero without one.
    pub(super) fn impulses(&self) -> Impulses<'_> {
        Impulses {
            normal: &self.impulse,
            tangential: &self.tangential,
        }
    }
}
