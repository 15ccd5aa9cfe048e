use std::ops::Range;

use super::{ForceInput, ForceTerm, Fused};
use crate::soa::Vec3SliceMut;

/// Linear air drag, `f = -c v`, the same for every particle. Only in the pipeline when `c > 0`.
pub struct AirDrag {
    /// Coefficient in N s/m.
    pub c: f32,
}

impl AirDrag {
    fn contribution(&self) -> Fused {
        Fused::MinusVelocityTimes(self.c)
    }
}

impl ForceTerm for AirDrag {
    fn name(&self) -> &'static str {
        "air_drag"
    }

    fn linearization(&self) -> super::Linearization {
        super::Linearization::Drag { c: self.c }
    }

    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        super::fused::accumulate(input, &[self.contribution()], false, range, out)
    }

    fn fused(&self) -> Option<Fused> {
        Some(self.contribution())
    }
}
