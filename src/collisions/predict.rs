//! The contacts a step is about to make, found before an implicit solver runs, so that the
//! solve can hold them.
//!
//! An implicit step at a display-frame length moves a falling particle centimetres past a
//! surface. Projecting it back afterwards, as the collider passes do, is right for an explicit
//! substep, but after an implicit solve it undoes a motion the solve had balanced its springs
//! against: rows of a cloth landing edge first would be put back on the floor on top of each
//! other, with their springs crushed, and the energy stored in those springs would come back as
//! motion. So before the solve, the collider passes are run on the free motion
//! `x + h v + h^2 g` of every particle; a particle they move is a contact, with the plane
//! through the surface point they put it on, along the surface's outward normal there. The
//! solver keeps such a particle on the outer side of its plane as part of the solve
//! (`ImplicitEuler`: exactly, its normal velocity change prescribed and filtered out of the
//! conjugate gradient's search directions, `src/integrators/contact_filter.rs`;
//! `ProjectiveDynamics`: a projection onto the plane's outer side, weighted in its global
//! matrix), so the springs around it feel the contact within the same step. What the filtered
//! solve costs against a stiff spring onto the plane is measured by `benches/ab_contact.py`
//! (`docs/notes/contact.md`, "Collider contact inside implicit Euler's solve").
//!
//! The free motion follows gravity alone, so the prediction is corrected after the solve
//! ([`PredictedContacts::correct`], run by the stepper until nothing changes, a few rounds at
//! most): a contact the solve held by pulling (its springs lifted the particle off the plane,
//! and a penalty that pulls it back drags the cloth down, energy a landing then returns as a
//! bounce) is released; a particle the springs carried into a collider its free motion missed
//! is held; a contact that slid along its plane into a curved surface is held on the plane
//! where the surface is now.
//!
//! Coulomb friction, for a solver whose contacts are exact constraints (implicit Euler), acts
//! inside the solve. A contact the prediction's friction stopped (it sticks) is held in all
//! three directions, at the surface's own tangential velocity, so the springs around it
//! balance against it within the step; after a round, one whose tangential impulse exceeds
//! `mu` times its normal impulse slides from the next round on. A sliding contact is held along
//! its normal, and across it a damper `-c (v'_t - u_t)` on its velocity relative to the
//! surface's acts within the solve: `c` gives the friction impulse Coulomb allows at the speed
//! the particle is estimated to slip at, and a damper, unlike a fixed impulse, never turns a
//! particle round, so it cannot add energy. For the other solvers, friction takes the
//! tangential velocity the prediction's contact took, bounded by what is left of it after the
//! solve ([`PredictedContacts::apply_friction`]). Taken after an exact solve, that velocity
//! would move the particle back while its neighbours stay where the solve put them: the
//! springs between them would store energy the solve never traded for, and the step's energy
//! judge would split the steps of a cloth at rest (docs/garments.md). The collider passes then
//! run on the result as on any step, and correct little.

use glam::Vec3;
use rayon::prelude::*;

use super::{Collider, Surfaces};
use crate::linear::Sym3;
use crate::particles::Particles;
use crate::soa::Vec3s;
use crate::state::Kinematics;

/// The contacts predicted for one substep, per particle.
pub struct PredictedContacts {
    /// The free motion's end, then where the colliders put it.
    predicted: Kinematics,
    /// The outward normal, velocity and friction coefficient of the surface where the colliders
    /// put a particle, zero elsewhere.
    surface: Surfaces,
    /// The outward unit normal of the contact plane, zero where there is no contact.
    pub normal: Vec3s,
    /// `n . s` for a point `s` of the contact plane: a particle at `x` is on its outer side
    /// when `n . x >= offset`.
    pub offset: Vec<f32>,
    /// The tangential speed (m/s) friction takes off a sliding contact after the solve.
    friction: Vec<f32>,
    /// The contact's Coulomb friction coefficient.
    mu: Vec<f32>,
    /// Whether the contact sticks: held in all three directions inside the solve, ending the
    /// step at the surface's tangential velocity. Only where the solver holds sticking contacts
    /// ([`PredictedContacts::find`]'s `sticks`).
    pub stuck: Vec<bool>,
    /// The tangential velocity (m/s) of the surface under a contact (zero on a still collider):
    /// a sticking particle's, and what a sliding one's friction damps its velocity towards.
    pub surface_velocity: Vec3s,
    /// The friction damper `c` (kg: N s per m/s of slip) of a sliding contact inside the solve,
    /// where the solver holds sticking contacts; zero elsewhere.
    pub slide_damping: Vec<f32>,
    /// Whether the solver holds sticking contacts: friction acts inside its solve.
    sticks: bool,
    /// How many particles have a contact.
    pub count: usize,
}

impl PredictedContacts {
    /// Name in `profile()`.
    pub const NAME: &'static str = "contact_prediction";

    pub fn new(n: usize) -> Self {
        PredictedContacts {
            predicted: Kinematics::zeros(n),
            surface: Surfaces::zeros(n),
            normal: Vec3s::zeros(n),
            offset: vec![0.0; n],
            friction: vec![0.0; n],
            mu: vec![0.0; n],
            stuck: vec![false; n],
            surface_velocity: Vec3s::zeros(n),
            slide_damping: vec![0.0; n],
            sticks: false,
            count: 0,
        }
    }

    /// Bytes held on the heap.
    pub fn heap_bytes(&self) -> usize {
        self.predicted.heap_bytes()
            + self.surface.heap_bytes()
            + self.normal.heap_bytes()
            + self.surface_velocity.heap_bytes()
            + (self.offset.capacity() + self.friction.capacity() + self.mu.capacity())
                * size_of::<f32>()
            + self.slide_damping.capacity() * size_of::<f32>()
            + self.stuck.capacity()
    }

    /// Finds the contacts of a substep of length `h` ending at `time` (s) from `current`,
    /// under the constant acceleration `g` (m/s^2), against `colliders`. With `sticks` (a
    /// solver whose contacts are exact constraints), a contact whose prediction friction
    /// stopped sticks.
    #[allow(clippy::too_many_arguments)]
    pub fn find(
        &mut self,
        colliders: &[Collider],
        current: &Kinematics,
        particles: &Particles,
        g: Vec3,
        (h, time): (f32, f64),
        chunk: usize,
        sticks: bool,
    ) {
        self.sticks = sticks;
        if colliders.is_empty() {
            // Self-collision alone (its holds, [`PredictedContacts::hold`]): nothing to predict,
            // and the last substep's holds are let go.
            self.release_all();
            return;
        }
        // Where each particle would be moving freely; the colliders only move dynamic ones.
        let free = |p: usize| {
            let (x, v) = (current.pos.get(p), current.vel.get(p));
            (x + h * v + h * h * g, v + h * g)
        };
        for p in 0..current.pos.len() {
            let (x, v) = free(p);
            self.predicted.pos.set(p, x);
            self.predicted.vel.set(p, v);
        }
        self.put_out(colliders, current, particles, (h, time), chunk);
        let mut count = 0;
        for p in 0..current.pos.len() {
            let (_, v) = free(p);
            let (normal, at) = (self.surface.normal.get(p), self.predicted.pos.get(p));
            let normal = if at.is_finite() { normal } else { Vec3::ZERO };
            self.set(p, (normal, at), v, particles.mass[p]);
            count += (normal != Vec3::ZERO) as usize;
        }
        self.count = count;
    }

    /// Particle `p` (of mass `m`, kg)'s contact on the plane through `at` with outward unit
    /// normal `normal` (none where it is zero), from the colliders' prediction that took its
    /// velocity `v` to `self.predicted.vel`: its friction, and where the solver holds sticking
    /// contacts whether it sticks, the prediction's friction having taken its whole tangential
    /// velocity relative to the surface (Coulomb: `|dv_t| < mu dv_n`, where a sliding one
    /// takes exactly `mu dv_n`), and for one that slides the damper that takes the same
    /// impulse at the slip the prediction left.
    fn set(&mut self, p: usize, (normal, at): (Vec3, Vec3), v: Vec3, m: f32) {
        let after = self.predicted.vel.get(p);
        let dv = after - v;
        let (dv_n, dv_t) = (dv.dot(normal), dv - dv.dot(normal) * normal);
        let mu = self.surface.friction[p];
        let u = self.surface.velocity.get(p);
        let (u_t, slip) = (u - u.dot(normal) * normal, after - u);
        let slip = (slip - slip.dot(normal) * normal).length();
        let stuck = self.sticks && normal != Vec3::ZERO && dv_t.length() < mu * dv_n * (1.0 - 1e-4);
        self.normal.set(p, normal);
        self.offset[p] = normal.dot(at);
        self.friction[p] = dv_t.length();
        self.mu[p] = mu;
        self.stuck[p] = stuck;
        self.surface_velocity.set(p, u_t);
        let sliding = self.sticks && !stuck && slip > 0.0;
        self.slide_damping[p] = if sliding {
            m * dv_t.length() / slip
        } else {
            0.0
        };
    }

    /// Lets every contact go, as [`PredictedContacts::set`] leaves a particle the colliders did
    /// not move: only particles with a contact have anything to clear (`count` of them).
    fn release_all(&mut self) {
        for p in 0..self.normal.len() {
            if self.count == 0 {
                break;
            }
            if self.normal.get(p) != Vec3::ZERO {
                self.normal.set(p, Vec3::ZERO);
                self.offset[p] = 0.0;
                self.friction[p] = 0.0;
                self.mu[p] = 0.0;
                self.stuck[p] = false;
                self.surface_velocity.set(p, Vec3::ZERO);
                self.slide_damping[p] = 0.0;
                self.count -= 1;
            }
        }
    }

    /// The friction damper `c P_t` (`P_t = I - n n^T`, kg) of particle `p`'s sliding contact on
    /// its diagonal block, where it has one.
    pub fn slide_block(&self, p: usize) -> Option<Sym3> {
        let c = self.slide_damping[p];
        (c > 0.0).then(|| Sym3::outer(-c, self.normal.get(p), c))
    }

    /// The directions the solve holds particle `p` in, as a projector: `n n^T` along a
    /// contact's normal, the identity for a sticking one, zero without a contact.
    pub fn held_directions(&self, p: usize) -> Sym3 {
        match (self.normal.get(p), self.stuck[p]) {
            (n, _) if n == Vec3::ZERO => Sym3::ZERO,
            (_, true) => Sym3::outer(0.0, Vec3::ZERO, 1.0),
            (n, false) => Sym3::outer(1.0, n, 0.0),
        }
    }

    /// Runs the colliders' prediction on `self.predicted`, from `current`: the surface normal
    /// and friction of each contact into `self.surface`.
    fn put_out(
        &mut self,
        colliders: &[Collider],
        current: &Kinematics,
        particles: &Particles,
        (h, time): (f32, f64),
        chunk: usize,
    ) {
        self.surface.normal.fill(Vec3::ZERO);
        for collider in colliders {
            let (predicted, surface) = (&mut self.predicted, &mut self.surface);
            collider.resolve(
                current,
                predicted,
                Some(surface),
                particles,
                chunk,
                (h, time),
            );
        }
    }

    /// Corrects the contacts after a solve wrote `solved` (from `current`, over a substep of
    /// length `h` ending at `time`) and returns how many changed. A contact holds only by
    /// pushing, and one that pulled is released: where the solver reports each contact's
    /// `impulses` (an exact constraint leaves its particle on its target, whichever way it
    /// acted), one whose normal impulse is negative; elsewhere one whose particle the solve
    /// left ahead of its target (the plane, or its start when it started behind it). A
    /// sticking contact whose tangential impulse exceeds `mu` times its normal impulse slides
    /// from now on, friction then taking at most `mu` times the normal impulse over its mass off
    /// its tangential speed. A particle without one whose solved motion ends inside a collider
    /// gets one, with the plane the collider puts it on: the prediction follows only gravity,
    /// and the springs can carry a particle into a collider its free motion missed. With
    /// `impulses`, not one that started inside and moved out, which its contact could only
    /// pull back.
    pub fn correct(
        &mut self,
        colliders: &[Collider],
        (current, solved): (&Kinematics, &Kinematics),
        impulses: Option<Impulses>,
        particles: &Particles,
        (h, time): (f32, f64),
        chunk: usize,
    ) -> usize {
        if colliders.is_empty() && self.count == 0 {
            // Nothing held, and nothing for a solve to be carried into.
            return 0;
        }
        self.predicted.copy_from(solved);
        self.put_out(colliders, current, particles, (h, time), chunk);
        let mut changed = 0;
        for p in 0..current.pos.len() {
            let (x, v) = (solved.pos.get(p), solved.vel.get(p));
            let n = self.normal.get(p);
            let (normal, at) = (self.surface.normal.get(p), self.predicted.pos.get(p));
            let inside = normal != Vec3::ZERO && at.is_finite();
            if n != Vec3::ZERO {
                let target = self.offset[p].min(n.dot(current.pos.get(p)));
                let pulled = match &impulses {
                    Some(impulse) => impulse.normal[p] < 0.0,
                    None => n.dot(x) > target,
                };
                if pulled {
                    self.normal.set(p, Vec3::ZERO);
                    self.stuck[p] = false;
                    self.count -= 1;
                    changed += 1;
                } else if let Some(excess) = impulses.as_ref().and_then(|i| self.slips(p, i)) {
                    // The excess over Coulomb's bound sets the particle slipping at about
                    // `excess / m`; the damper takes `mu` times the normal impulse there.
                    let allowed = self.mu[p] * impulses.as_ref().map_or(0.0, |i| i.normal[p]);
                    self.stuck[p] = false;
                    self.slide_damping[p] = particles.mass[p] * allowed / excess;
                    changed += 1;
                } else if inside && !same_plane((n, self.offset[p]), (normal, normal.dot(at))) {
                    // Slid along its plane into a curved surface (a ball's tangent plane
                    // leaves the ball): held on the plane where the surface is now, with the
                    // friction it had.
                    self.normal.set(p, normal);
                    self.offset[p] = normal.dot(at);
                    changed += 1;
                }
                continue;
            }
            // An exact constraint holds its particle on its target whichever way it must act:
            // one that started inside and is moving out (never deeper than its start, the
            // target then) would be pulled back in, and released again next round.
            let outward = impulses.is_some() && normal.dot(x) >= normal.dot(current.pos.get(p));
            if !inside || outward {
                continue;
            }
            self.set(p, (normal, at), v, particles.mass[p]);
            self.count += 1;
            changed += 1;
        }
        changed
    }

    /// For sticking contact `p`, where the solve needed more tangential impulse to hold it
    /// than Coulomb allows (`mu` times the normal impulse), so that it slides: by how much
    /// (N s).
    fn slips(&self, p: usize, impulses: &Impulses) -> Option<f32> {
        let allowed = self.mu[p] * impulses.normal[p];
        let needed = impulses.tangential.get(p).length();
        (self.stuck[p] && needed > allowed).then_some(needed - allowed)
    }
}

/// What an exact contact constraint did in the last solve, per particle (zero without one).
pub struct Impulses<'a> {
    /// The impulse along the contact's normal, N s: positive where it pushed.
    pub normal: &'a [f32],
    /// The impulse across it, N s, of a sticking contact.
    pub tangential: &'a Vec3s,
}

impl PredictedContacts {
    /// Holds particle `p`, which has no contact, on the outer side of the plane through `at`
    /// with outward unit normal `normal`, without friction; returns whether it was free.
    pub fn hold(&mut self, p: usize, normal: Vec3, at: Vec3) -> bool {
        if self.normal.get(p) != Vec3::ZERO {
            return false;
        }
        self.normal.set(p, normal);
        self.offset[p] = normal.dot(at);
        self.friction[p] = 0.0;
        self.stuck[p] = false;
        self.slide_damping[p] = 0.0;
        self.count += 1;
        true
    }
}

/// Whether two contact planes `(normal, offset)` are the same to within 0.01 rad and 1 um: a
/// flat face gives the same plane however far a particle slides on it.
fn same_plane((n, offset): (Vec3, f32), (m, other): (Vec3, f32)) -> bool {
    n.dot(m) > 0.99995 && (offset - other).abs() < 1e-6
}

impl PredictedContacts {
    /// Coulomb friction on the solver's result `next` for a substep of length `h`: each
    /// sliding contact's tangential velocity loses what the predicted contact's friction took,
    /// and no more than it has (friction stops a particle, it does not turn it round); its
    /// position moves with it, as the collider passes move it. Nothing where the solver holds
    /// sticking contacts: its friction acted inside the solve.
    pub fn apply_friction(&self, next: &mut Kinematics, h: f32, chunk: usize) {
        if self.sticks {
            return;
        }
        let Kinematics { pos, vel } = next;
        pos.par_chunks_mut(chunk)
            .zip(vel.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(c, (mut pos, mut vel))| {
                for i in 0..pos.len() {
                    let p = c * chunk + i;
                    let n = self.normal.get(p);
                    if n == Vec3::ZERO {
                        continue;
                    }
                    let v = vel.get(i);
                    let tangential = v - v.dot(n) * n;
                    let (speed, taken) = (tangential.length(), self.friction[p]);
                    let dv = if speed <= taken {
                        -tangential
                    } else {
                        -tangential * (taken / speed)
                    };
                    vel.set(i, v + dv);
                    pos.set(i, pos.get(i) + h * dv);
                }
            });
    }
}
