//! Kinematic pins: pinned particles moved to a target position by the user (dragging).

use glam::Vec3;

use crate::soa::Vec3s;

/// Pinned particles with a target. Each step puts the particle exactly on its target and gives
/// it the velocity of that move, `(target - x) / h`, so spring damping sees the motion. In the
/// pipeline only while at least one target is set.
#[derive(Clone, Debug, Default)]
pub struct KinematicPins {
    targets: Vec<(usize, Vec3)>,
}

impl KinematicPins {
    pub const NAME: &'static str = "kinematic_pins";

    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    pub fn set(&mut self, p: usize, target: Vec3) {
        match self.targets.iter_mut().find(|(q, _)| *q == p) {
            Some(entry) => entry.1 = target,
            None => self.targets.push((p, target)),
        }
    }

    /// The target of particle `p`, if it has one.
    pub fn target(&self, p: usize) -> Option<Vec3> {
        self.targets.iter().find(|(q, _)| *q == p).map(|&(_, t)| t)
    }

    /// Every `(particle, target)`, in the order they were set.
    pub fn targets(&self) -> &[(usize, Vec3)] {
        &self.targets
    }

    pub fn remove(&mut self, p: usize) {
        self.targets.retain(|(q, _)| *q != p);
    }

    pub fn clear(&mut self) {
        self.targets.clear();
    }

    /// Puts every target's particle on it; returns whether the velocities it wrote are finite
    /// (a drag across float32's range overflows).
    /// `start` holds the positions at the start of the step, `pos` and `vel` the step's result.
    pub fn apply(&self, h: f32, start: &Vec3s, pos: &mut Vec3s, vel: &mut Vec3s) -> bool {
        let mut finite = true;
        for &(p, target) in &self.targets {
            let v = (target - start.get(p)) / h;
            vel.set(p, v);
            pos.set(p, target);
            finite &= v.is_finite();
        }
        finite
    }
}
