use std::ops::Range;

use glam::Vec3;

use super::{ForceInput, ForceTerm};
use crate::soa::Vec3SliceMut;

/// Uniform gravity, `f = m g`. Only in the pipeline when `g` is not zero.
pub struct Gravity {
    /// Acceleration in m/s^2.
    pub g: Vec3,
}

impl ForceTerm for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }

    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        let mass = &input.mass[range];
        for (component, g) in [
            (&mut *out.x, self.g.x),
            (&mut *out.y, self.g.y),
            (&mut *out.z, self.g.z),
        ] {
            if g != 0.0 {
                for (f, m) in component.iter_mut().zip(mass) {
                    *f += m * g;
                }
            }
        }
    }
}
