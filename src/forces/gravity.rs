use std::ops::Range;

use glam::Vec3;

use super::{ForceInput, ForceTerm, Fused};
use crate::soa::Vec3SliceMut;

/// Uniform gravity, `f = m g`. Only in the pipeline when `g` is not zero.
pub struct Gravity {
    /// Acceleration in m/s^2.
    pub g: Vec3,
}

impl Gravity {
    fn contribution(&self) -> Fused {
        Fused::MassTimes(self.g)
    }
}

impl ForceTerm for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }

    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        super::fused::accumulate(input, &[self.contribution()], false, range, out)
    }

    fn fused(&self) -> Option<Fused> {
        Some(self.contribution())
    }

    fn linearization(&self) -> super::Linearization {
        super::Linearization::Acceleration(self.g)
    }
}
