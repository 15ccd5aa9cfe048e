use glam::{DVec3, Vec3};

use super::contact_velocity;
use crate::particles::Particles;
use crate::scene::SphereSpec;
use crate::soa::Vec3Slice;
use crate::state::Kinematics;

/// Static spheres, tested with a swept (continuous) test so that a particle fast enough to
/// cross a whole sphere within one step is still stopped at its surface.
pub struct Spheres {
    spheres: Vec<Sphere>,
}

/// The lowest height (m) a particle may have when the scene also has a floor: its height plus
/// its thickness.
#[derive(Clone, Copy, Debug)]
pub struct FloorLevel(pub f32);

#[derive(Clone, Copy, Debug)]
struct Sphere {
    center: Vec3,
    /// Radius plus thickness: the surface particles are kept on.
    reach: f32,
    friction: f32,
    /// The floor's level where the sphere reaches below it (a ball standing on the floor),
    /// else minus infinity. See [`Sphere::surface`].
    floor: f32,
}

/// Projections land this far outside `reach` (relative), so that rounding in `center + n * reach`
/// never leaves a particle a hair inside.
const SURFACE_MARGIN: f32 = 1e-5;

impl Spheres {
    /// The spheres of a scene; `floor` is the floor's level when the scene has one. A sphere
    /// wholly under the floor's level can take no contact (the floor keeps every particle
    /// above it) and is left out.
    pub fn new(specs: &[SphereSpec], floor: Option<FloorLevel>) -> Self {
        let spheres = specs
            .iter()
            .filter(|s| {
                let top = s.center[1] + s.radius + s.thickness;
                floor.is_none_or(|f| top as f32 > f.0)
            })
            .map(|s| {
                let center = DVec3::from(s.center).as_vec3();
                let reach = (s.radius + s.thickness) as f32;
                Sphere {
                    center,
                    reach,
                    friction: s.friction as f32,
                    floor: floor
                        .map(|f| f.0)
                        .filter(|&f| center.y - reach < f)
                        .unwrap_or(f32::NEG_INFINITY),
                }
            })
            .collect();
        Spheres { spheres }
    }
}

impl Sphere {
    /// Where the particle moving from `p0` to `p1` ends up, and the contact normal if it
    /// touched: the surface point nearest `p1` when `p1` is inside on the side it came from or
    /// it started inside; the entry point of the segment when it crossed the middle or passed
    /// right through (tunnelling).
    #[inline]
    fn contact(&self, p0: Vec3, p1: Vec3) -> Option<(Vec3, Vec3)> {
        // Judge the end point where the floor pass, which runs next, will leave it: a particle
        // under the floor beside a ball standing on it is lifted, possibly into the ball.
        let p1 = Vec3::new(p1.x, p1.y.max(self.floor), p1.z);
        let r2 = self.reach * self.reach;
        let rel1 = p1 - self.center;
        let rel0 = p0 - self.center;
        let started_outside = rel0.length_squared() >= r2;
        let ends_inside = rel1.length_squared() < r2;
        if started_outside && ends_inside && rel1.dot(rel0) > 0.0 {
            // Stopped short of the middle: the nearest surface point keeps the particle's motion
            // along the surface, as the floor does. The entry point would drop that motion from
            // the position while the velocity kept it, and a cloth resting on the sphere gained
            // energy every step (see the regression test in tests/stability.rs).
            return Some(self.surface(rel1.normalize_or(rel0.normalize_or(Vec3::Y))));
        }
        if started_outside {
            // Solve |rel0 + t d|^2 = reach^2 for the first t in [0, 1].
            let d = p1 - p0;
            let a = d.length_squared();
            let b = rel0.dot(d);
            if a == 0.0 || b >= 0.0 {
                return None; // not moving, or moving away: cannot enter
            }
            let disc = b * b - a * (rel0.length_squared() - r2);
            if disc < 0.0 {
                return None;
            }
            let t = (-b - disc.sqrt()) / a;
            // A NaN `t` (|p - c|^2 overflowing for a sphere 1e19 m away) is no hit either.
            if (t > 1.0 || t.is_nan()) && !ends_inside {
                return None;
            }
            let n = (rel0 + t.clamp(0.0, 1.0) * d).normalize_or(rel0.normalize_or(Vec3::Y));
            Some(self.surface(n))
        } else if ends_inside {
            Some(self.surface(rel1.normalize_or(rel0.normalize_or(Vec3::Y))))
        } else {
            None
        }
    }

    /// The point just outside the surface along the outward normal `n`, and the normal there.
    ///
    /// Where the sphere reaches below the floor, that point can lie under it, and the floor
    /// pass, which runs next, would lift the particle straight back into the sphere: a cloth
    /// caught in the crease between a ball and the floor it stands on sank into the ball. Such a
    /// point moves up the surface to the floor's level instead, in the same vertical plane,
    /// where both constraints hold.
    #[inline]
    fn surface(&self, n: Vec3) -> (Vec3, Vec3) {
        let scale = self.reach * (1.0 + SURFACE_MARGIN);
        let point = self.center + n * scale;
        match self.floor {
            level if point.y < level => {
                let drop = level - self.center.y;
                let ring = (scale * scale - drop * drop).max(0.0).sqrt();
                let across = Vec3::new(n.x, 0.0, n.z).normalize_or(Vec3::X);
                let n = (across * ring + Vec3::Y * drop) / scale;
                (n, self.center + across * ring + Vec3::Y * drop)
            }
            _ => (n, point),
        }
    }
}

/// Particles screened per batch (a stack buffer of flags).
const SCREEN: usize = 256;

impl Spheres {
    /// Marks the particles whose step from `p0` to `p1` could touch some sphere: the segment
    /// comes within `reach` of the centre only if `|p1 - c| < reach + |p1 - p0|`. Inflated a
    /// little so that rounding never screens out a particle the exact test would catch; the
    /// exact test decides.
    #[inline(always)]
    fn screen(&self, p0: Vec3Slice, p1: (&[f32], &[f32], &[f32]), out: &mut [bool]) {
        let n = out.len();
        let (x1, y1, z1) = (&p1.0[..n], &p1.1[..n], &p1.2[..n]);
        let (x0, y0, z0) = (&p0.x[..n], &p0.y[..n], &p0.z[..n]);
        out.fill(false);
        for sphere in &self.spheres {
            let (c, floor) = (sphere.center, sphere.floor);
            for i in 0..n {
                let (dx, dy, dz) = (x1[i] - x0[i], y1[i] - y0[i], z1[i] - z0[i]);
                let travel = (dx * dx + dy * dy + dz * dz).sqrt();
                // As in `contact`: where the floor will leave the particle.
                let (rx, ry, rz) = (x1[i] - c.x, y1[i].max(floor) - c.y, z1[i] - c.z);
                let limit = (sphere.reach + travel) * (1.0 + 1e-4) + 1e-6;
                out[i] |= rx * rx + ry * ry + rz * rz < limit * limit;
            }
        }
    }
}

impl Spheres {
    /// Moves every dynamic particle of `next` that ended inside a sphere (or whose path from
    /// `start` crossed one) onto its surface; see [`super::Collider::resolve`].
    pub fn resolve(
        &self,
        start: &Kinematics,
        next: &mut Kinematics,
        particles: &Particles,
        chunk: usize,
    ) -> bool {
        super::resolve_chunks(next, chunk, |first, mut pos, mut vel| {
            let mut finite = true;
            let start_pos = start.pos.slices(first..first + pos.len());
            let mut candidates = [false; SCREEN];
            for block in (0..pos.len()).step_by(SCREEN) {
                let len = SCREEN.min(pos.len() - block);
                let p0 = start_pos.slices_at(block..block + len);
                // A cheap, vectorised screen first; the exact swept test only where the
                // particle could touch a sphere (a few percent of the cloth at most).
                crate::simd::dispatch!(self.screen(
                    p0,
                    (
                        &pos.x[block..block + len],
                        &pos.y[block..block + len],
                        &pos.z[block..block + len]
                    ),
                    &mut candidates[..len],
                ));
                for j in (0..len).filter(|&j| candidates[j]) {
                    let (i, p) = (block + j, first + block + j);
                    if !particles.is_dynamic(p) {
                        continue;
                    }
                    let p0 = start.pos.get(p);
                    for sphere in &self.spheres {
                        if let Some((n, surface)) = sphere.contact(p0, pos.get(i)) {
                            let v = contact_velocity(vel.get(i), n, sphere.friction);
                            pos.set(i, surface);
                            vel.set(i, v);
                            finite &= surface.is_finite() && v.is_finite();
                        }
                    }
                }
            }
            finite
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_sphere() -> Sphere {
        Sphere {
            floor: f32::NEG_INFINITY,
            center: Vec3::ZERO,
            reach: 1.0,
            friction: 0.0,
        }
    }

    #[test]
    fn a_particle_crossing_the_whole_sphere_in_one_step_stops_at_the_entry_point() {
        let (n, at) = unit_sphere()
            .contact(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, -5.0, 0.0))
            .unwrap();
        assert_eq!(n, Vec3::Y);
        assert!(at.y >= 1.0 && at.y < 1.001, "{at}");
    }

    #[test]
    fn a_particle_passing_beside_the_sphere_is_untouched() {
        let s = unit_sphere();
        assert!(s
            .contact(Vec3::new(1.5, 5.0, 0.0), Vec3::new(1.5, -5.0, 0.0))
            .is_none());
        assert!(s
            .contact(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, 6.0, 0.0))
            .is_none());
        assert!(s
            .contact(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, 2.0, 0.0))
            .is_none());
    }

    #[test]
    fn a_particle_that_started_inside_is_pushed_out_radially() {
        let (n, at) = unit_sphere()
            .contact(Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.6, 0.0, 0.0))
            .unwrap();
        assert_eq!(n, Vec3::X);
        assert!(at.length() >= 1.0);
    }
}
