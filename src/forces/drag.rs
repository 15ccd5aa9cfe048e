use std::ops::Range;

use super::{ForceInput, ForceTerm};
use crate::soa::Vec3SliceMut;

/// Linear air drag, `f = -c v`, the same for every particle. Only in the pipeline when `c > 0`.
pub struct AirDrag {
    /// Coefficient in N s/m.
    pub c: f32,
}

impl ForceTerm for AirDrag {
    fn name(&self) -> &'static str {
        "air_drag"
    }

    fn linearization(&self) -> super::Linearization {
        super::Linearization::Drag { c: self.c }
    }

    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        let vel = input.vel.slices(range);
        for (f, v) in [
            (&mut *out.x, vel.x),
            (&mut *out.y, vel.y),
            (&mut *out.z, vel.z),
        ] {
            for (f, v) in f.iter_mut().zip(v) {
                *f -= self.c * v;
            }
        }
    }
}
