//! Colliders of any parry3d shape (sphere, box, capsule, cylinder), static or moving with a
//! prescribed linear and angular velocity: the `[[colliders]]` of a scene.
//!
//! Each substep poses every shape at the substep's end time, brings each candidate particle
//! into the shape's local frame and asks parry's `PointQuery::project_local_point` for the
//! nearest surface point. A particle inside, or closer than `thickness` outside, is put
//! `thickness` outside along the surface normal; its velocity relative to the surface's own
//! velocity there (`v + w x r`) loses the inward part and is slowed by Coulomb friction, so a
//! moving shape carries cloth that sticks to it. The position takes the same tangential change
//! as the velocity, times the substep (`x1 = x0 + h v1` with the velocity after friction):
//! otherwise the nearest-point projection keeps the slide of a particle that static friction
//! stopped, and cloth crept down every slope at `g h sin(angle)` per substep. Work is per particle and independent, so the
//! result is the same for any thread count, and a step allocates nothing.
//!
//! Swept, as the spheres are: the particle's path over the substep is taken into the shape's
//! frame at its start and its end (`x0` posed at the substep's start, `x1` at its end: the
//! relative motion, linearised), and a ray cast along it (parry's `RayCast`) finds where it
//! entered. A particle that crossed the shape within one substep, or that went deeper than the
//! middle, so that the nearest surface point is on the far side, is stopped at its entry point
//! instead: a fast particle or a fast shape neither tunnels nor pushes cloth through. A turning
//! shape's path is linearised over the substep, exact while `|angular_velocity| h` is small.

use glam::{DQuat, DVec3, Quat, Vec3};
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::{Ball, Capsule, Cuboid, Cylinder};

use super::contact_velocity;
use crate::particles::Particles;
use crate::scene::{ColliderSpec, ShapeKind};
use crate::state::Kinematics;

/// The scene's `[[colliders]]`, in order; a later one has the last word where two overlap.
pub struct Shapes {
    shapes: Vec<ShapeCollider>,
}

enum Geometry {
    Ball(Ball),
    Cuboid(Cuboid),
    Capsule(Capsule),
    Cylinder(Cylinder),
}

impl Geometry {
    #[inline]
    fn project(&self, local: Vec3) -> (Vec3, bool) {
        // `solid = false`: a point inside gets the nearest boundary point, not itself.
        let p = match self {
            Geometry::Ball(s) => s.project_local_point(local, false),
            Geometry::Cuboid(s) => s.project_local_point(local, false),
            Geometry::Capsule(s) => s.project_local_point(local, false),
            Geometry::Cylinder(s) => s.project_local_point(local, false),
        };
        (p.point, p.is_inside)
    }

    /// Where the segment `from + t d`, `t` in `[0, 1]`, first meets the solid shape, and the
    /// outward normal there; `t = 0` when `from` is inside.
    #[inline]
    fn entry(&self, from: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
        let ray = Ray::new(from, d);
        let hit = match self {
            Geometry::Ball(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Cuboid(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Capsule(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
            Geometry::Cylinder(s) => s.cast_local_ray_and_get_normal(&ray, 1.0, true),
        };
        hit.map(|h| (h.time_of_impact, h.normal))
    }
}

struct ShapeCollider {
    geometry: Geometry,
    /// Pose at time 0 and its rates, in f64 so that the pose at a late time is accurate.
    center: DVec3,
    rotation: DQuat,
    velocity: DVec3,
    angular_velocity: DVec3,
    friction: f32,
    thickness: f32,
    /// Radius of a ball around the centre holding the shape, plus thickness: the screen.
    reach: f32,
}

/// Where a shape is at one instant, and how its surface moves.
#[derive(Clone, Copy)]
struct Posed {
    center: Vec3,
    rotation: Quat,
    velocity: Vec3,
    angular_velocity: Vec3,
    /// How far beyond `thickness` particles are put, in m.
    margin: f32,
}

/// Particles are put this much (relative to the size of the coordinates involved) beyond
/// `thickness`, so that rounding in the frame change never leaves one a hair inside. A few
/// ulps: a larger lift leaves a resting particle airborne for whole substeps, sliding free.
const SURFACE_MARGIN: f32 = 8.0 * f32::EPSILON;

impl Shapes {
    pub fn new(specs: &[ColliderSpec]) -> Self {
        let shapes = specs
            .iter()
            .map(|s| {
                let r = s.radius.unwrap_or(0.0) as f32;
                let hh = s.half_height.unwrap_or(0.0) as f32;
                let (geometry, bound) = match s.shape {
                    ShapeKind::Sphere => (Geometry::Ball(Ball::new(r)), r),
                    ShapeKind::Box => {
                        let h = DVec3::from(s.half_extents.unwrap_or([0.0; 3])).as_vec3();
                        (Geometry::Cuboid(Cuboid::new(h)), h.length())
                    }
                    ShapeKind::Capsule => (Geometry::Capsule(Capsule::new_y(hh, r)), hh + r),
                    ShapeKind::Cylinder => (Geometry::Cylinder(Cylinder::new(hh, r)), hh.hypot(r)),
                };
                let rotation = DVec3::from(s.rotation);
                ShapeCollider {
                    geometry,
                    center: DVec3::from(s.center),
                    rotation: DQuat::from_scaled_axis(rotation),
                    velocity: DVec3::from(s.velocity),
                    angular_velocity: DVec3::from(s.angular_velocity),
                    friction: s.friction as f32,
                    thickness: s.thickness as f32,
                    reach: (bound + s.thickness as f32) * (1.0 + 1e-4) + 1e-6,
                }
            })
            .collect();
        Shapes { shapes }
    }

    /// Moves every dynamic particle of `next` that ended inside a shape (posed at `time`, the
    /// end of the substep of length `h`, in s) or within its thickness onto the offset surface;
    /// see [`super::Collider::resolve`].
    pub fn resolve(
        &self,
        start: &Kinematics,
        next: &mut Kinematics,
        particles: &Particles,
        chunk: usize,
        h: f32,
        time: f64,
    ) -> bool {
        super::resolve_chunks(next, chunk, |first, mut pos, mut vel| {
            let mut finite = true;
            for shape in &self.shapes {
                // Posed once per chunk: a few dozen flops, and no buffer to keep.
                let posed = shape.posed(time);
                let before = shape.posed(time - h as f64);
                let drift = (posed.center - before.center).length();
                let turn = posed.angular_velocity.length() * h;
                for i in 0..pos.len() {
                    let (p0, p1) = (start.pos.get(first + i), pos.get(i));
                    // A cheap screen: the path relative to the shape moves at most
                    // |x1 - x0| + |c1 - c0| + |w| h |x0 - c0|, so only a particle that
                    // ends within that of the shape's bounding ball can touch it.
                    let travel = (p1 - p0).length() + drift + turn * (p0 - before.center).length();
                    let limit = (shape.reach + travel) * (1.0 + 1e-4);
                    if (p1 - posed.center).length_squared() >= limit * limit
                        || !particles.is_dynamic(first + i)
                    {
                        continue;
                    }
                    if let Some((n, at)) = shape.contact(&before, &posed, p0, p1) {
                        let surface = posed.surface_velocity(at);
                        let v0 = vel.get(i);
                        let v = surface + contact_velocity(v0 - surface, n, shape.friction);
                        let dv = v - v0;
                        let at = at + h * (dv - dv.dot(n) * n);
                        pos.set(i, at);
                        vel.set(i, v);
                        finite &= at.is_finite() && v.is_finite();
                    }
                }
            }
            finite
        })
    }
}

impl ShapeCollider {
    fn posed(&self, time: f64) -> Posed {
        let turn = DQuat::from_scaled_axis(self.angular_velocity * time);
        let center = (self.center + self.velocity * time).as_vec3();
        Posed {
            center,
            margin: SURFACE_MARGIN * (self.reach + center.abs().max_element()),
            rotation: (turn * self.rotation).normalize().as_quat(),
            velocity: self.velocity.as_vec3(),
            angular_velocity: self.angular_velocity.as_vec3(),
        }
    }

    /// For a particle moving from `p0` (with the shape posed `before`) to `p1` (posed
    /// `posed`): the outward normal and the point `thickness` outside the surface where it
    /// ends up, when `p1` is inside the shape or closer to it than `thickness`, or its path
    /// crossed the shape. That point is the surface point nearest `p1`, or the entry point when
    /// the particle crossed the shape or went past its middle (the nearest point faces the way
    /// it was going).
    #[inline]
    fn contact(&self, before: &Posed, posed: &Posed, p0: Vec3, p1: Vec3) -> Option<(Vec3, Vec3)> {
        let local = posed.rotation.inverse() * (p1 - posed.center);
        let local0 = before.rotation.inverse() * (p0 - before.center);
        let d = local - local0;
        let (on_surface, inside) = self.geometry.project(local);
        let offset = local - on_surface;
        // Outward normal: away from the surface point when outside, towards it when inside.
        // A point exactly on the surface has no direction to it; the one from the centre is
        // outward for every convex shape here.
        let fallback = local.normalize_or(Vec3::Y);
        let nearest = if inside {
            (-offset).normalize_or(fallback)
        } else {
            offset.normalize_or(fallback)
        };
        // The entry point matters only for a particle that ended inside heading away from the
        // nearest surface point (past the middle), or one that ended outside but whose path is
        // long enough to have crossed the shape. The ray cast is the costly part (a GJK
        // iteration for the cylinder, 10x a projection), so it runs only then.
        let distance = offset.length();
        let may_cross = if inside {
            nearest.dot(d) > 0.0
        } else {
            distance < d.length()
        };
        let entry = may_cross
            .then(|| self.geometry.entry(local0, d))
            .flatten()
            .filter(|&(t, _)| t > 0.0);
        let (on_surface, n) = match entry {
            // Tunnelled (ended outside, having crossed), or pushed past the middle.
            Some((t, normal)) => (local0 + t * d, normal.normalize_or(nearest)),
            None if !inside && distance >= self.thickness => return None,
            None => (on_surface, nearest),
        };
        let lift = self.thickness + posed.margin;
        let at = posed.center + posed.rotation * (on_surface + n * lift);
        Some((posed.rotation * n, at))
    }
}

impl Posed {
    /// Velocity of the shape's material at the world point `at`.
    #[inline]
    fn surface_velocity(&self, at: Vec3) -> Vec3 {
        self.velocity + self.angular_velocity.cross(at - self.center)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Shapes {
        Shapes::new(&[ColliderSpec {
            shape: ShapeKind::Box,
            half_extents: Some([1.0, 1.0, 1.0]),
            center: [0.0; 3],
            thickness: 0.0,
            ..ColliderSpec::default()
        }])
    }

    #[test]
    fn a_point_inside_a_box_goes_to_the_nearest_face() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let (posed, p) = (s.posed(0.0), Vec3::new(0.2, 0.9, 0.1));
        let (n, at) = s.contact(&posed, &posed, p, p).unwrap();
        assert_eq!(n, Vec3::Y);
        assert!(
            at.y >= 1.0 && at.y < 1.001 && (at.x - 0.2).abs() < 1e-6,
            "{at}"
        );
    }

    #[test]
    fn a_point_outside_beyond_the_thickness_is_untouched() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let (posed, p) = (s.posed(0.0), Vec3::new(0.0, 1.01, 0.0));
        assert!(s.contact(&posed, &posed, p, p).is_none());
    }

    #[test]
    fn a_particle_crossing_the_whole_box_in_one_step_stops_at_the_entry_point() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let posed = s.posed(0.0);
        let (p0, p1) = (Vec3::new(0.3, 5.0, 0.0), Vec3::new(0.3, -5.0, 0.0));
        let (n, at) = s.contact(&posed, &posed, p0, p1).unwrap();
        assert_eq!(n, Vec3::Y);
        assert!(at.y >= 1.0 && at.y < 1.001, "{at}");
        // Past the middle but still inside: the entry point too, not the bottom face.
        let (n, at) = s
            .contact(&posed, &posed, p0, Vec3::new(0.3, -0.8, 0.0))
            .unwrap();
        assert_eq!(n, Vec3::Y);
        assert!(at.y >= 1.0, "{at}");
    }

    #[test]
    fn a_moving_turning_shape_is_posed_from_the_time() {
        let shapes = Shapes::new(&[ColliderSpec {
            shape: ShapeKind::Sphere,
            radius: Some(1.0),
            center: [1.0, 0.0, 0.0],
            velocity: [0.0, 2.0, 0.0],
            angular_velocity: [0.0, 0.0, std::f64::consts::PI],
            ..ColliderSpec::default()
        }]);
        let posed = shapes.shapes[0].posed(0.5);
        assert!((posed.center - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        // Half a turn a second for half a second: local x now points along world y.
        assert!((posed.rotation * Vec3::X - Vec3::Y).length() < 1e-6);
        // A point one metre along x from the centre moves at pi m/s along y, plus the drift.
        let v = posed.surface_velocity(posed.center + Vec3::X);
        assert!((v - Vec3::new(0.0, 2.0 + std::f32::consts::PI, 0.0)).length() < 1e-5);
    }
}
