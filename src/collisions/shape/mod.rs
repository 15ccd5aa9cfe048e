//! Colliders of any parry3d shape (sphere, box, capsule, cylinder, plane, triangle mesh), static,
//! moving with a prescribed linear and angular velocity, or posed between steps by the caller
//! (`set_collider_pose`): the `[[colliders]]` of a scene.
//!
//! Each substep poses every shape at the substep's end time, brings each candidate particle
//! into the shape's local frame and asks parry's `PointQuery::project_local_point` for the
//! nearest surface point. A particle inside, or closer than `thickness` outside, is put
//! `thickness` outside along the surface normal; its velocity relative to the surface's own
//! velocity there (`v + w x r`) loses the inward part and is slowed by Coulomb friction, so a
//! moving shape carries cloth that sticks to it. The position takes the same tangential change
//! as the velocity, times the substep (`x1 = x0 + h v1` with the velocity after friction):
//! otherwise the nearest-point projection would keep the slide of a particle that static
//! friction stopped, and cloth would creep down every slope at `g h sin(angle)` per substep.
//! Work is per particle and independent, so the result is the same for any thread count, and a
//! step allocates nothing.
//!
//! Swept, as the spheres are: the particle's path over the substep is taken into the shape's
//! frame at its start and its end (`x0` posed at the substep's start, `x1` at its end: the
//! relative motion, linearised), and a ray cast along it (parry's `RayCast`) finds where it
//! entered. A particle that crossed the shape within one substep, or that went deeper than the
//! middle, so that the nearest surface point is on the far side, is stopped at its entry point
//! instead: a fast particle or a fast shape neither tunnels nor pushes cloth through. A turning
//! shape's path is linearised over the substep, exact while `|angular_velocity| h` is small.
//!
//! A mesh (`geometry.rs`) answers the same two questions locally, from a grid over its triangles
//! or parry's BVH; a closed one is a solid, an open one a one-sided sheet. A pose set between
//! steps (`pose.rs`) is reached over the next step at constant velocity and turn rate.

mod geometry;
mod pose;

use glam::{DQuat, DVec3, Quat, Vec3};

use super::{contact_velocity, Surfaces};
use crate::particles::Particles;
use crate::scene::{ColliderSpec, ShapeKind};
use crate::state::Kinematics;
use geometry::{Geometry, Projection};
pub use pose::{Pose, PoseKey, ROTATION_TOLERANCE};

/// The scene's `[[colliders]]`, in order; a later one has the last word where two overlap.
pub struct Shapes {
    shapes: Vec<ShapeCollider>,
    /// Per collider, the pose set between steps, if any (then its scripted motion is over).
    keys: Vec<Option<PoseKey>>,
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
    /// Half the length of the segment along the shape's local y axis, through its centre, that
    /// [`ShapeCollider::reach`] is measured from: a capsule's half height, 0 (the centre) for
    /// the others. A long capsule's bounding ball holds much that is far from it (the
    /// mannequin's torso's holds the whole shirt), and a particle near it passes the screen to
    /// the costly nearest-point query.
    core: f32,
    /// Radius of a tube around the core segment holding the shape, plus thickness: the screen
    /// (infinite for a plane).
    reach: f32,
    /// The shape's size (m, finite; 0 for a plane), which scales the rounding margin.
    scale: f32,
    /// For a ball in a scene with a floor, the lowest height the floor leaves a particle at (m:
    /// its height plus its thickness), else minus infinity. See [`ShapeCollider::contact`].
    floor: f32,
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
    /// The colliders of validated specs; `floor` is the lowest height the scene's floor leaves
    /// a particle at (m), when it has one.
    pub fn new(specs: &[ColliderSpec], floor: Option<f32>) -> Self {
        let shapes: Vec<ShapeCollider> = specs
            .iter()
            .map(|s| {
                let (geometry, bound) = Geometry::of(s);
                let core = match s.shape {
                    ShapeKind::Capsule => s.half_height.unwrap_or(0.0) as f32,
                    _ => 0.0,
                };
                let reach = match s.shape {
                    ShapeKind::Plane => f32::INFINITY,
                    _ => (bound - core + s.thickness as f32) * (1.0 + 1e-4) + 1e-6,
                };
                let rotation = DVec3::from(s.rotation);
                let floor = match (s.shape, floor) {
                    (ShapeKind::Sphere, Some(level)) => level,
                    _ => f32::NEG_INFINITY,
                };
                ShapeCollider {
                    geometry,
                    center: DVec3::from(s.center),
                    rotation: DQuat::from_scaled_axis(rotation),
                    velocity: DVec3::from(s.velocity),
                    angular_velocity: DVec3::from(s.angular_velocity),
                    friction: s.friction as f32,
                    thickness: s.thickness as f32,
                    core,
                    reach,
                    scale: bound + s.thickness as f32,
                    floor,
                }
            })
            .collect();
        let keys = vec![None; shapes.len()];
        Shapes { shapes, keys }
    }

    /// Bytes the colliders hold on the heap: what their meshes take.
    pub fn heap_bytes(&self) -> usize {
        self.shapes
            .iter()
            .map(|s| s.geometry.heap_bytes())
            .sum::<usize>()
            + self.keys.capacity() * size_of::<Option<PoseKey>>()
    }

    /// How many colliders there are.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// Whether any shape moves or turns at `time` (s).
    pub fn moves(&self, time: f64) -> bool {
        self.shapes.iter().zip(&self.keys).any(|(shape, key)| {
            let (_, velocity, angular_velocity) = shape.pose_at(time, key.as_ref());
            velocity != DVec3::ZERO || angular_velocity != DVec3::ZERO
        })
    }

    /// Collider `i`'s pose at `time` (s).
    pub fn pose(&self, i: usize, time: f64) -> Pose {
        self.shapes[i].pose_at(time, self.keys[i].as_ref()).0
    }

    /// Puts collider `i` at `to` by `now + dt` (s): over the step from `now`, it moves there
    /// from where it is at `now`, and rests there after (its scripted motion is over).
    pub fn set_pose(&mut self, i: usize, to: Pose, now: f64, dt: f64) {
        self.keys[i] = Some(PoseKey {
            from: self.pose(i, now),
            to,
            start: now,
            end: now + dt,
        });
    }

    /// The poses set between steps, per collider (what a snapshot keeps).
    pub fn keys(&self) -> &[Option<PoseKey>] {
        &self.keys
    }

    /// Replaces the poses set between steps (from a snapshot); `keys` must hold one entry per
    /// collider.
    pub fn set_keys(&mut self, keys: Vec<Option<PoseKey>>) {
        assert_eq!(keys.len(), self.shapes.len(), "one key per collider");
        self.keys = keys;
    }

    /// Where the shapes posed at `time` (s), in order, put a particle that moved from `from` to
    /// `to` and stays (see [`super::Collider::push_out`]).
    pub fn push_out(&self, from: Vec3, to: Vec3, time: f64) -> Vec3 {
        self.shapes
            .iter()
            .zip(&self.keys)
            .fold(to, |to, (shape, key)| {
                let posed = shape.posed(time, key.as_ref());
                shape
                    .contact(&posed, &posed, from, to)
                    .map_or(to, |(_, at)| at)
            })
    }

    /// The deepest contact the shapes posed at `time` (s) make with a particle that moved from
    /// `from` to `to`: the outward normal and the point [`Shapes::push_out`]'s shape would put
    /// it at, of the shape that puts it farthest along its normal; `None` where none touches.
    pub fn contact_at(&self, from: Vec3, to: Vec3, time: f64) -> Option<(Vec3, Vec3)> {
        let contacts = self
            .shapes
            .iter()
            .zip(&self.keys)
            .filter_map(|(shape, key)| {
                let posed = shape.posed(time, key.as_ref());
                shape.contact(&posed, &posed, from, to)
            });
        super::deepest(to, contacts)
    }

    /// Moves every dynamic particle of `next` that ended inside a shape (posed at `time`, the
    /// end of the substep of length `h`, in s) or within its thickness onto the offset surface;
    /// with `surfaces`, a prediction: see [`super::Collider::resolve`].
    pub fn resolve(
        &self,
        start: &Kinematics,
        next: &mut Kinematics,
        surfaces: Option<&mut Surfaces>,
        particles: &Particles,
        chunk: usize,
        (h, time): (f32, f64),
    ) -> bool {
        let slide = surfaces.is_none();
        super::resolve_chunks(
            next,
            surfaces,
            chunk,
            |first, mut pos, mut vel, mut surfaces| {
                let mut finite = true;
                for (shape, key) in self.shapes.iter().zip(&self.keys) {
                    // Posed once per chunk: a few dozen flops, and no buffer to keep.
                    let posed = shape.posed(time, key.as_ref());
                    let before = shape.posed(time - h as f64, key.as_ref());
                    let drift = (posed.center - before.center).length();
                    let turn = posed.angular_velocity.length() * h;
                    let axis = posed.rotation * Vec3::Y;
                    for i in 0..pos.len() {
                        let (p0, p1) = (start.pos.get(first + i), pos.get(i));
                        // As in `contact`: where the floor will leave it.
                        let lifted = Vec3::new(p1.x, p1.y.max(shape.floor), p1.z);
                        // A cheap screen: the path relative to the shape moves at most
                        // |x1 - x0| + |c1 - c0| + |w| h |x0 - c0|, and the distance to the
                        // core segment changes no faster than the point, so only a particle
                        // that ends within that of the tube round the core can touch it.
                        let travel =
                            (p1 - p0).length() + drift + turn * (p0 - before.center).length();
                        let limit = (shape.reach + posed.margin + travel) * (1.0 + 1e-4);
                        let q = lifted - posed.center;
                        let along = q.dot(axis).clamp(-shape.core, shape.core);
                        if (q - along * axis).length_squared() >= limit * limit
                            || !particles.is_dynamic(first + i)
                        {
                            continue;
                        }
                        if let Some((n, at)) = shape.contact(&before, &posed, p0, p1) {
                            let surface = posed.surface_velocity(at);
                            let v0 = vel.get(i);
                            let v = surface + contact_velocity(v0 - surface, n, shape.friction);
                            let at = if slide {
                                let dv = v - v0;
                                let slid = shape.on_ball(&posed, at + h * (dv - dv.dot(n) * n));
                                // The slide can take a point in the crease below the floor again.
                                shape.above_floor(posed.center, n, slid).1
                            } else {
                                at
                            };
                            if let Some((normals, velocity, friction)) = &mut surfaces {
                                normals.set(i, n);
                                velocity.set(i, surface);
                                friction[i] = shape.friction;
                            }
                            pos.set(i, at);
                            vel.set(i, v);
                            finite &= at.is_finite() && v.is_finite();
                        }
                    }
                }
                finite
            },
        )
    }
}

impl ShapeCollider {
    /// The pose, velocity (m/s) and angular velocity (rad/s) at `time` (s): set between steps
    /// (`key`), or scripted by the scene.
    fn pose_at(&self, time: f64, key: Option<&PoseKey>) -> (Pose, DVec3, DVec3) {
        if let Some(key) = key {
            return key.at(time);
        }
        let turn = DQuat::from_scaled_axis(self.angular_velocity * time);
        let pose = Pose {
            position: self.center + self.velocity * time,
            rotation: (turn * self.rotation).normalize(),
        };
        (pose, self.velocity, self.angular_velocity)
    }

    fn posed(&self, time: f64, key: Option<&PoseKey>) -> Posed {
        let (pose, velocity, angular_velocity) = self.pose_at(time, key);
        let center = pose.position.as_vec3();
        Posed {
            center,
            margin: SURFACE_MARGIN * (self.scale + center.abs().max_element()),
            rotation: pose.rotation.as_quat(),
            velocity: velocity.as_vec3(),
            angular_velocity: angular_velocity.as_vec3(),
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
        // Judged where the floor pass, which runs next, will leave it: a particle under the
        // floor beside a ball standing on it is lifted, possibly into the ball.
        let p1 = Vec3::new(p1.x, p1.y.max(self.floor), p1.z);
        let local = posed.rotation.inverse() * (p1 - posed.center);
        let local0 = before.rotation.inverse() * (p0 - before.center);
        let d = local - local0;
        // Further than this from the surface, a particle that started outside cannot touch it.
        let max_dist = (self.thickness + d.length() + posed.margin) * (1.0 + 1e-4);
        let Projection {
            point: on_surface,
            inside,
            fallback,
        } = self.geometry.project(local, max_dist)?;
        let offset = local - on_surface;
        // Outward normal: away from the surface point when outside, towards it when inside.
        let nearest = if inside {
            (-offset).normalize_or(fallback)
        } else {
            offset.normalize_or(fallback)
        };
        let one_sided = self.geometry.one_sided();
        // The entry point matters only for a particle that ended inside heading away from the
        // nearest surface point (past the middle), or one that ended outside but whose path is
        // long enough to have crossed the shape. The ray cast is the costly part (a GJK
        // iteration for the cylinder, 10x a projection), so it runs only then.
        let distance = offset.length();
        // A one-sided sheet has no middle: a particle behind it may have crossed it.
        let may_cross = if inside && !one_sided {
            // Past the middle; or in through another face: a particle that started on the inner
            // side of the nearest face's plane, outside the shape, did not cross that face (one
            // falling onto a box's top beside its edge ends nearest the side).
            let other_face = self.geometry.has_edges() && nearest.dot(local0 - on_surface) < 0.0;
            nearest.dot(d) > 0.0 || other_face
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
            // Outside beyond the thickness; or behind a sheet, further than that.
            None if (!inside || one_sided) && distance >= self.thickness => return None,
            None => (on_surface, nearest),
        };
        let lift = self.thickness + posed.margin;
        let at = posed.center + posed.rotation * (on_surface + n * lift);
        Some(self.above_floor(posed.center, posed.rotation * n, at))
    }

    /// For a ball, `at` (after the friction slide) back on the ball's offset surface if the
    /// slide left it inside: in float32 a slide along the tangent plane of a particle moving
    /// fast round a ball can end it a few micrometres inside. Other shapes: `at` as it is.
    #[inline]
    fn on_ball(&self, posed: &Posed, at: Vec3) -> Vec3 {
        let Geometry::Ball(ball) = &self.geometry else {
            return at;
        };
        let reach = ball.radius + self.thickness + posed.margin;
        let offset = at - posed.center;
        if offset.length_squared() >= reach * reach {
            return at;
        }
        posed.center + offset.normalize_or(Vec3::Y) * reach
    }

    /// The contact point `at` with outward normal `n` of a ball centred at `center`, moved up
    /// the ball's offset surface to the floor's level, in the same vertical plane, where it lies
    /// under that level. The floor pass, which runs next, would lift it straight back into the
    /// ball: a cloth caught in the crease between a ball and the floor it stands on would sink
    /// into the ball. Other shapes, and points above the floor, are returned as they are.
    #[inline]
    fn above_floor(&self, center: Vec3, n: Vec3, at: Vec3) -> (Vec3, Vec3) {
        if at.y >= self.floor {
            return (n, at);
        }
        let radius = (at - center).length();
        let drop = self.floor - center.y;
        let ring = (radius * radius - drop * drop).max(0.0).sqrt();
        let across = Vec3::new(n.x, 0.0, n.z).normalize_or(Vec3::X);
        let offset = across * ring + Vec3::Y * drop;
        (offset.normalize_or(Vec3::Y), center + offset)
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
        Shapes::new(
            &[ColliderSpec {
                shape: ShapeKind::Box,
                half_extents: Some([1.0, 1.0, 1.0]),
                center: [0.0; 3],
                thickness: 0.0,
                ..ColliderSpec::default()
            }],
            None,
        )
    }

    #[test]
    fn a_point_inside_a_box_goes_to_the_nearest_face() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let (posed, p) = (s.posed(0.0, None), Vec3::new(0.2, 0.9, 0.1));
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
        let (posed, p) = (s.posed(0.0, None), Vec3::new(0.0, 1.01, 0.0));
        assert!(s.contact(&posed, &posed, p, p).is_none());
    }

    #[test]
    fn a_particle_crossing_the_whole_box_in_one_step_stops_at_the_entry_point() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let posed = s.posed(0.0, None);
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

    /// A particle that falls onto a box's top beside an edge, deeper in one step than it is
    /// from the side, is nearest the side face; put out there, it ended under the top beside
    /// the box, its springs to the neighbours on the top stretched (a cloth landing at 1/60 s
    /// gained energy). It came in through the top, and goes back there.
    #[test]
    fn a_particle_falling_onto_a_box_beside_its_edge_lands_on_the_top() {
        let shapes = unit_box();
        let s = &shapes.shapes[0];
        let posed = s.posed(0.0, None);
        let (p0, p1) = (Vec3::new(0.99, 1.01, 0.0), Vec3::new(0.99, 0.95, 0.0));
        let (n, at) = s.contact(&posed, &posed, p0, p1).unwrap();
        assert_eq!(n, Vec3::Y);
        assert!(at.y >= 1.0 && at.y < 1.001 && at.x < 1.0, "{at}");
        // One that started inside, beside the side face, still leaves by the nearest face.
        let p = Vec3::new(0.99, 0.95, 0.0);
        let (n, _) = s.contact(&posed, &posed, p, p).unwrap();
        assert_eq!(n, Vec3::X);
    }

    #[test]
    fn a_moving_turning_shape_is_posed_from_the_time() {
        let shapes = Shapes::new(
            &[ColliderSpec {
                shape: ShapeKind::Sphere,
                radius: Some(1.0),
                center: [1.0, 0.0, 0.0],
                velocity: [0.0, 2.0, 0.0],
                angular_velocity: [0.0, 0.0, std::f64::consts::PI],
                ..ColliderSpec::default()
            }],
            None,
        );
        let posed = shapes.shapes[0].posed(0.5, None);
        assert!((posed.center - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        // Half a turn a second for half a second: local x now points along world y.
        assert!((posed.rotation * Vec3::X - Vec3::Y).length() < 1e-6);
        // A point one metre along x from the centre moves at pi m/s along y, plus the drift.
        let v = posed.surface_velocity(posed.center + Vec3::X);
        assert!((v - Vec3::new(0.0, 2.0 + std::f32::consts::PI, 0.0)).length() < 1e-5);
    }
}
