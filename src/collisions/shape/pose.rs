//! Where a collider is. A pose set between steps ([`super::Shapes::set_pose`]) is reached over
//! the next step, at the constant velocity and turn rate that take the shape from where it was
//! to where it was put (a [`PoseKey`]); friction acts on the velocity relative to that motion,
//! so cloth resting on a collider moved every step is carried along. After that step the shape
//! rests at the pose.

use glam::{DQuat, DVec3};

use crate::error::{Error, Result};
use crate::scene::MAX_COLLIDER_VALUE;

/// Where a collider's frame is: its origin (m) and orientation (a unit quaternion).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pose {
    pub position: DVec3,
    pub rotation: DQuat,
}

/// A pose set between steps: the collider goes from `from` at time `start` to `to` at `end`
/// (s; the end of the step after the call) at constant velocity and turn rate, and rests at
/// `to` after that.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PoseKey {
    pub from: Pose,
    pub to: Pose,
    pub start: f64,
    pub end: f64,
}

/// How far from 1 the norm of a quaternion given as a rotation may be (it is normalised).
pub const ROTATION_TOLERANCE: f64 = 1e-3;

impl Pose {
    /// A pose from a position (m, finite, within [`MAX_COLLIDER_VALUE`]) and a unit quaternion
    /// `[x, y, z, w]` (norm within [`ROTATION_TOLERANCE`] of 1; normalised), each named in the
    /// error on bad input.
    pub fn checked(names: (&str, &str), position: [f64; 3], rotation: [f64; 4]) -> Result<Pose> {
        let (pos_name, rot_name) = names;
        if let Some(x) = position
            .iter()
            .find(|x| !(x.is_finite() && x.abs() <= MAX_COLLIDER_VALUE))
        {
            return Err(Error::value(
                pos_name,
                format!(
                    "must be finite numbers of at most {MAX_COLLIDER_VALUE:e} m, got {x} in \
                     {position:?}"
                ),
            ));
        }
        let q = DQuat::from_array(rotation);
        let norm = q.length();
        if !(q.is_finite() && (norm - 1.0).abs() <= ROTATION_TOLERANCE) {
            return Err(Error::value(
                rot_name,
                format!(
                    "must be a unit quaternion [x, y, z, w] (norm within {ROTATION_TOLERANCE} \
                     of 1), got {rotation:?} of norm {norm}"
                ),
            ));
        }
        Ok(Pose {
            position: DVec3::from(position),
            rotation: q / norm,
        })
    }
}

impl PoseKey {
    /// The pose, velocity (m/s) and angular velocity (rad/s) at `time`.
    pub(super) fn at(&self, time: f64) -> (Pose, DVec3, DVec3) {
        let span = self.end - self.start;
        let f = (time - self.start) / span;
        // The step's last substep ends at `end` up to rounding in the clock's sums.
        if f > 1.0 + 1e-9 {
            return (self.to, DVec3::ZERO, DVec3::ZERO);
        }
        let velocity = (self.to.position - self.from.position) / span;
        let mut turn = self.to.rotation * self.from.rotation.inverse();
        if turn.w < 0.0 {
            turn = -turn; // the short way round
        }
        let angular_velocity = turn.to_scaled_axis() / span;
        let pose = if f >= 1.0 {
            self.to
        } else {
            let f = f.max(0.0);
            Pose {
                position: self.from.position.lerp(self.to.position, f),
                rotation: (DQuat::from_scaled_axis(turn.to_scaled_axis() * f) * self.from.rotation)
                    .normalize(),
            }
        };
        (pose, velocity, angular_velocity)
    }
}
