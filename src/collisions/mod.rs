//! Colliders: static shapes the cloth cannot enter. Each runs after integration over the state
//! at the end of the step, with the state at its start available for swept tests.
//!
//! Contact model, the same for every shape: a particle that ends the step inside (closer to
//! the surface than the collider's `thickness`) is moved onto the surface, loses the velocity
//! component into the surface, and the tangential velocity is reduced by Coulomb friction,
//! `|dv_t| <= mu |dv_n|`, stopping it altogether when the normal impulse is large enough.

mod floor;
mod mesh;
mod predict;
mod shape;

use glam::Vec3;

pub use floor::Floor;
pub use predict::{Impulses, PredictedContacts};
pub use shape::{Pose, PoseKey, Shapes, ROTATION_TOLERANCE};

use crate::particles::Particles;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::state::Kinematics;

/// What a collider's prediction of contacts writes per particle, where it makes one: the
/// surface's outward normal, its velocity (m/s) there, and its Coulomb friction coefficient.
pub struct Surfaces {
    pub normal: Vec3s,
    pub velocity: Vec3s,
    pub friction: Vec<f32>,
}

impl Surfaces {
    pub fn zeros(n: usize) -> Self {
        Surfaces {
            normal: Vec3s::zeros(n),
            velocity: Vec3s::zeros(n),
            friction: vec![0.0; n],
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.normal.heap_bytes()
            + self.velocity.heap_bytes()
            + self.friction.capacity() * size_of::<f32>()
    }
}

/// One chunk of [`Surfaces`]: the normals, velocities and friction coefficients of its
/// particles.
type SurfacesChunk<'a> = (Vec3SliceMut<'a>, Vec3SliceMut<'a>, &'a mut [f32]);

/// Runs `contact` on each parallel chunk of `next` (given the chunk's first particle index, its
/// positions, its velocities, and the chunk of `surfaces` when given, where a contact writes the
/// surface's outward normal, velocity and friction) and returns whether every chunk reported finite
/// output: the traversal every collider shares, so each writes only its contact test.
fn resolve_chunks(
    next: &mut Kinematics,
    surfaces: Option<&mut Surfaces>,
    chunk: usize,
    contact: impl Fn(usize, Vec3SliceMut<'_>, Vec3SliceMut<'_>, Option<SurfacesChunk<'_>>) -> bool
        + Sync
        + Send,
) -> bool {
    use rayon::prelude::*;
    let Kinematics { pos, vel } = next;
    let chunks = pos
        .par_chunks_mut(chunk)
        .zip(vel.par_chunks_mut(chunk))
        .enumerate();
    match surfaces {
        None => chunks
            .map(|(c, (pos, vel))| contact(c * chunk, pos, vel, None))
            .reduce(|| true, |a, b| a & b),
        Some(Surfaces {
            normal,
            velocity,
            friction,
        }) => chunks
            .zip(normal.par_chunks_mut(chunk))
            .zip(velocity.par_chunks_mut(chunk))
            .zip(friction.par_chunks_mut(chunk))
            .map(|((((c, (pos, vel)), n), u), mu)| contact(c * chunk, pos, vel, Some((n, u, mu))))
            .reduce(|| true, |a, b| a & b),
    }
}

/// A collider: the closed set of shapes a scene can hold.
pub enum Collider {
    /// The scene's `[[spheres]]`: balls, as the `[[colliders]]` pass treats them.
    Spheres(Shapes),
    /// The `[[colliders]]` of any shape, static or moving.
    Shapes(Shapes),
    Floor(Floor),
}

impl Collider {
    /// Name in `effects` and `profile()`.
    pub fn name(&self) -> &'static str {
        match self {
            Collider::Spheres(_) => "spheres",
            Collider::Shapes(_) => "colliders",
            Collider::Floor(_) => "floor",
        }
    }

    /// Whether the collider moves or turns at `time` (s): then its contacts do work.
    pub fn moves(&self, time: f64) -> bool {
        match self {
            Collider::Spheres(s) | Collider::Shapes(s) => s.moves(time),
            Collider::Floor(_) => false,
        }
    }

    /// Bytes the collider holds on the heap.
    pub fn heap_bytes(&self) -> usize {
        match self {
            Collider::Spheres(s) | Collider::Shapes(s) => s.heap_bytes(),
            Collider::Floor(_) => 0,
        }
    }

    /// Where this collider, posed at `time` (s), puts a particle that moved from `from` to `to`
    /// and stays: by the same contact test the step runs, the entry point of a path that went
    /// into it or through it, the nearest point of the offset surface (`thickness` outside) for
    /// one that ended inside or within `thickness` of it without, else `to`.
    pub fn push_out(&self, from: Vec3, to: Vec3, time: f64) -> Vec3 {
        match self {
            Collider::Spheres(s) | Collider::Shapes(s) => s.push_out(from, to, time),
            Collider::Floor(f) => f.push_out(to),
        }
    }

    /// The contact this collider, posed at `time` (s), makes with a particle that moved from
    /// `from` to `to`: its outward normal there and where [`Collider::push_out`] puts the
    /// particle; `None` where it leaves the particle at `to`.
    pub fn contact(&self, from: Vec3, to: Vec3, time: f64) -> Option<(Vec3, Vec3)> {
        match self {
            Collider::Spheres(s) | Collider::Shapes(s) => s.contact_at(from, to, time),
            Collider::Floor(f) => {
                let at = f.push_out(to);
                (at != to).then_some((Vec3::Y, at))
            }
        }
    }

    /// Moves every dynamic particle of `next` that ended inside the collider out of it.
    /// `start` holds the positions at the start of the step, `h` is its length and `time` the
    /// simulated time at its end (s), where moving colliders are posed. Returns whether every
    /// value it wrote is finite (a contact at speeds near float32's limit can overflow).
    ///
    /// With `surfaces`, a prediction of contacts for an implicit solve: a particle is left where
    /// its contact put it, on the surface, without the friction slide along it, and the
    /// surface's outward normal there, its velocity and friction coefficient are written into
    /// `surfaces`
    /// (its velocity changes as without). The contact's plane is the one through that point along that normal; the move
    /// from where the particle was is not along the normal where the contact took the entry
    /// point of a path through a shape, and a slid point is off the surface.
    pub fn resolve(
        &self,
        start: &Kinematics,
        next: &mut Kinematics,
        surfaces: Option<&mut Surfaces>,
        particles: &Particles,
        chunk: usize,
        (h, time): (f32, f64),
    ) -> bool {
        match self {
            Collider::Spheres(s) | Collider::Shapes(s) => {
                s.resolve(start, next, surfaces, particles, chunk, (h, time))
            }
            Collider::Floor(f) => f.resolve(start, next, surfaces, particles, chunk),
        }
    }
}

/// Of the contacts `(outward normal, where the particle is put)` a particle that ended at `to`
/// makes, the deepest: the one that puts it farthest along its normal.
pub fn deepest(to: Vec3, contacts: impl Iterator<Item = (Vec3, Vec3)>) -> Option<(Vec3, Vec3)> {
    let depth = |&(n, at): &(Vec3, Vec3)| (at - to).dot(n);
    contacts.max_by(|a, b| depth(a).total_cmp(&depth(b)))
}

/// Velocity after contact with a surface of outward unit normal `n` and friction `mu`.
#[inline]
pub fn contact_velocity(v: Vec3, n: Vec3, mu: f32) -> Vec3 {
    let vn = v.dot(n);
    if vn >= 0.0 {
        return v; // already leaving the surface
    }
    let tangential = v - vn * n;
    let speed = tangential.length();
    let normal_impulse = -vn; // velocity change along n, per unit mass
    if speed <= mu * normal_impulse {
        Vec3::ZERO // static friction holds
    } else {
        tangential * (1.0 - mu * normal_impulse / speed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_removes_the_inward_velocity_and_applies_coulomb_friction() {
        let n = Vec3::Y;
        // Leaving: untouched.
        assert_eq!(
            contact_velocity(Vec3::new(1.0, 2.0, 0.0), n, 0.5),
            Vec3::new(1.0, 2.0, 0.0)
        );
        // Frictionless: tangential part kept.
        assert_eq!(
            contact_velocity(Vec3::new(1.0, -2.0, 0.0), n, 0.0),
            Vec3::new(1.0, 0.0, 0.0)
        );
        // Sliding: |dv_t| = mu |dv_n| = 0.5 * 2 = 1 off a tangential speed of 3.
        let v = contact_velocity(Vec3::new(3.0, -2.0, 0.0), n, 0.5);
        assert!((v - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6, "{v}");
        // Sticking: friction would reverse the motion, so it stops.
        assert_eq!(
            contact_velocity(Vec3::new(0.5, -2.0, 0.0), n, 0.5),
            Vec3::ZERO
        );
    }
}
