use glam::Vec3;

use super::{contact_velocity, Surfaces};
use crate::particles::Particles;
use crate::state::Kinematics;

/// The half-space `y < height + thickness`. A half-space cannot be tunnelled through: a particle
/// below the plane at the end of a step is caught however fast it came.
pub struct Floor {
    /// Height of the plane in m.
    pub height: f32,
    /// Coulomb friction coefficient.
    pub friction: f32,
    /// Gap kept between particles and the plane, in m.
    pub thickness: f32,
}

impl Floor {
    /// `p` raised onto the floor's offset plane when below it, however it got there (see
    /// [`super::Collider::push_out`]).
    pub fn push_out(&self, p: Vec3) -> Vec3 {
        Vec3::new(p.x, p.y.max(self.height + self.thickness), p.z)
    }

    /// Moves every dynamic particle of `next` below the floor onto it; see
    /// [`super::Collider::resolve`]; writes `+y`, zero velocity and the floor's friction into `surfaces` (when
    /// given) for each.
    pub fn resolve(
        &self,
        _start: &Kinematics,
        next: &mut Kinematics,
        surfaces: Option<&mut Surfaces>,
        particles: &Particles,
        chunk: usize,
    ) -> bool {
        let top = self.height + self.thickness;
        super::resolve_chunks(
            next,
            surfaces,
            chunk,
            |first, pos, mut vel, mut surfaces| {
                let mut finite = true;
                for i in 0..pos.len() {
                    if pos.y[i] < top && particles.is_dynamic(first + i) {
                        pos.y[i] = top;
                        let v = contact_velocity(vel.get(i), Vec3::Y, self.friction);
                        vel.set(i, v);
                        if let Some((normals, velocity, friction)) = &mut surfaces {
                            normals.set(i, Vec3::Y);
                            velocity.set(i, Vec3::ZERO);
                            friction[i] = self.friction;
                        }
                        finite &= v.is_finite();
                    }
                }
                finite
            },
        )
    }
}
