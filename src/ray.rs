//! A ray, the one primitive the picking and the cutting share, and its entry into a box.

use glam::Vec3;

use crate::error::{Error, Result};

/// A ray with a unit direction; distances along it are in m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    /// Unit length.
    pub dir: Vec3,
    /// `1 / dir` per component (infinite where `dir` is 0, and then unused).
    inv_dir: Vec3,
}

impl Ray {
    /// A ray from `origin` along `direction` (any non-zero length; normalised here). Rejects a
    /// non-finite origin and a zero or non-finite direction.
    pub fn new(origin: Vec3, direction: Vec3) -> Result<Ray> {
        Self::named(origin, direction, "origin", "direction")
    }

    /// [`Ray::new`] with the parameter names an error should carry.
    pub fn named(origin: Vec3, direction: Vec3, origin_name: &str, dir_name: &str) -> Result<Ray> {
        if !origin.is_finite() {
            return Err(Error::value(
                origin_name,
                format!("must be finite, got {:?}", origin.to_array()),
            ));
        }
        // Normalised in f64: in float32 the squared length of a direction shorter than about
        // 1e-19 or longer than 1.8e19 underflows or overflows: picks along it would measure
        // distances wrong (by 25 % for a 3e-23 m direction) or be refused.
        let dir = direction
            .is_finite()
            .then(|| direction.as_dvec3().try_normalize())
            .flatten()
            .map(|d| d.as_vec3())
            .ok_or_else(|| {
                Error::value(
                    dir_name,
                    format!(
                        "must be a finite, non-zero vector, got {:?}",
                        direction.to_array()
                    ),
                )
            })?;
        Ok(Ray {
            origin,
            dir,
            inv_dir: dir.recip(),
        })
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// Entry distance of a ray into the slab `[lo, hi]` of one axis and exit distance, for a ray
/// coordinate `o`, direction component `d` and its inverse `inv`. A ray parallel to the slab
/// is inside it everywhere or nowhere.
#[inline(always)]
fn slab(o: f32, d: f32, inv: f32, lo: f32, hi: f32) -> (f32, f32) {
    if d == 0.0 {
        if lo <= o && o <= hi {
            (f32::NEG_INFINITY, f32::INFINITY)
        } else {
            (f32::INFINITY, f32::NEG_INFINITY)
        }
    } else {
        let (a, b) = ((lo - o) * inv, (hi - o) * inv);
        if d > 0.0 {
            (a, b)
        } else {
            (b, a)
        }
    }
}

/// Distance along `ray` at which it enters the box `[mins, maxs]`, 0 if it starts inside, or
/// `None` if it misses (or the box lies behind the origin). Monotone in the bounds: a box that
/// contains another is entered no later.
#[inline]
pub fn ray_aabb(ray: &Ray, mins: Vec3, maxs: Vec3) -> Option<f32> {
    let (o, d, inv) = (ray.origin, ray.dir, ray.inv_dir);
    let (nx, fx) = slab(o.x, d.x, inv.x, mins.x, maxs.x);
    let (ny, fy) = slab(o.y, d.y, inv.y, mins.y, maxs.y);
    let (nz, fz) = slab(o.z, d.z, inv.z, mins.z, maxs.z);
    let enter = 0.0f32.max(nx).max(ny).max(nz);
    let exit = fx.min(fy).min(fz);
    (enter <= exit).then_some(enter)
}
