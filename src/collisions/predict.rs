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
//! (`docs/contact.md`).
//!
//! The free motion follows gravity alone, so the prediction is corrected after the solve
//! ([`PredictedContacts::correct`], run by the stepper until nothing changes, a few rounds at
//! most): a contact the solve held by pulling (its springs lifted the particle off the plane,
//! and a penalty that pulls it back drags the cloth down, energy a landing then returns as a
//! bounce) is released; a particle the springs carried into a collider its free motion missed
//! is held; a contact that slid along its plane into a curved surface is held on the plane
//! where the surface is now.
//!
//! Coulomb friction takes the tangential velocity the prediction's contact took, bounded by
//! what is left of it after the solve ([`PredictedContacts::apply_friction`]); the collider
//! passes then run on the result as on any step, and correct little.

use glam::Vec3;
use rayon::prelude::*;

use super::Collider;
use crate::particles::Particles;
use crate::soa::Vec3s;
use crate::state::Kinematics;

/// The contacts predicted for one substep, per particle.
pub struct PredictedContacts {
    /// The free motion's end, then where the colliders put it.
    predicted: Kinematics,
    /// The outward normal of the surface where the colliders put a particle, zero elsewhere.
    surface: Vec3s,
    /// The outward unit normal of the contact plane, zero where there is no contact.
    pub normal: Vec3s,
    /// `n . s` for a point `s` of the contact plane: a particle at `x` is on its outer side
    /// when `n . x >= offset`.
    pub offset: Vec<f32>,
    /// The tangential velocity change the colliders made on the free motion (friction).
    friction: Vec3s,
    /// How many particles have a contact.
    pub count: usize,
}

impl PredictedContacts {
    /// Name in `profile()`.
    pub const NAME: &'static str = "contact_prediction";

    pub fn new(n: usize) -> Self {
        PredictedContacts {
            predicted: Kinematics::zeros(n),
            surface: Vec3s::zeros(n),
            normal: Vec3s::zeros(n),
            offset: vec![0.0; n],
            friction: Vec3s::zeros(n),
            count: 0,
        }
    }

    /// Bytes held on the heap.
    pub fn heap_bytes(&self) -> usize {
        self.predicted.heap_bytes()
            + self.surface.heap_bytes()
            + self.normal.heap_bytes()
            + self.friction.heap_bytes()
            + self.offset.capacity() * size_of::<f32>()
    }

    /// Finds the contacts of a substep of length `h` ending at `time` (s) from `current`,
    /// under the constant acceleration `g` (m/s^2), against `colliders`.
    pub fn find(
        &mut self,
        colliders: &[Collider],
        current: &Kinematics,
        particles: &Particles,
        g: Vec3,
        (h, time): (f32, f64),
        chunk: usize,
    ) {
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
            let (normal, at) = (self.surface.get(p), self.predicted.pos.get(p));
            let normal = if at.is_finite() { normal } else { Vec3::ZERO };
            let dv = self.predicted.vel.get(p) - v;
            self.normal.set(p, normal);
            self.offset[p] = normal.dot(at);
            self.friction.set(p, dv - dv.dot(normal) * normal);
            count += (normal != Vec3::ZERO) as usize;
        }
        self.count = count;
    }

    /// Runs the colliders' prediction on `self.predicted`, from `current`: the surface normal
    /// of each contact into `self.surface`.
    fn put_out(
        &mut self,
        colliders: &[Collider],
        current: &Kinematics,
        particles: &Particles,
        (h, time): (f32, f64),
        chunk: usize,
    ) {
        self.surface.fill(Vec3::ZERO);
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
    /// normal `impulses` (N s; an exact constraint leaves its particle on its target, whichever
    /// way it acted), one whose impulse is negative; elsewhere one whose particle the solve
    /// left ahead of its target (the plane, or its start when it started behind it). A
    /// particle without one whose solved motion ends inside a collider gets one, with the
    /// plane the collider puts it on: the prediction follows only gravity, and the springs can
    /// carry a particle into a collider its free motion missed. With `impulses`, not one that
    /// started inside and moved out, which its contact could only pull back.
    pub fn correct(
        &mut self,
        colliders: &[Collider],
        (current, solved): (&Kinematics, &Kinematics),
        impulses: Option<&[f32]>,
        particles: &Particles,
        (h, time): (f32, f64),
        chunk: usize,
    ) -> usize {
        self.predicted.copy_from(solved);
        self.put_out(colliders, current, particles, (h, time), chunk);
        let mut changed = 0;
        for p in 0..current.pos.len() {
            let (x, v) = (solved.pos.get(p), solved.vel.get(p));
            let n = self.normal.get(p);
            let (normal, at) = (self.surface.get(p), self.predicted.pos.get(p));
            let inside = normal != Vec3::ZERO && at.is_finite();
            if n != Vec3::ZERO {
                let target = self.offset[p].min(n.dot(current.pos.get(p)));
                let pulled = match impulses {
                    Some(impulse) => impulse[p] < 0.0,
                    None => n.dot(x) > target,
                };
                if pulled {
                    self.normal.set(p, Vec3::ZERO);
                    self.friction.set(p, Vec3::ZERO);
                    self.count -= 1;
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
            let dv = self.predicted.vel.get(p) - v;
            self.normal.set(p, normal);
            self.offset[p] = normal.dot(at);
            self.friction.set(p, dv - dv.dot(normal) * normal);
            self.count += 1;
            changed += 1;
        }
        changed
    }
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
        self.friction.set(p, Vec3::ZERO);
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
    /// contact's tangential velocity loses what the predicted contact's friction took, and no
    /// more than it has (friction stops a particle, it does not turn it round); its position
    /// moves with it, as the collider passes move it.
    pub fn apply_friction(&self, next: &mut Kinematics, h: f32, chunk: usize) {
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
                    let (speed, taken) = (tangential.length(), self.friction.get(p).length());
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
