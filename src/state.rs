//! The state: what changes every step. Positions and velocities, the kinematic pins' targets,
//! the clock, and a version that every change of the positions bumps (caches of derived data
//! compare it).

use crate::pins::KinematicPins;
use crate::soa::Vec3s;

/// Positions (m) and velocities (m/s) of every particle.
#[derive(Clone, Debug, PartialEq)]
pub struct Kinematics {
    pub pos: Vec3s,
    pub vel: Vec3s,
}

impl Kinematics {
    pub fn zeros(n: usize) -> Self {
        Kinematics {
            pos: Vec3s::zeros(n),
            vel: Vec3s::zeros(n),
        }
    }

    pub fn copy_from(&mut self, other: &Kinematics) {
        self.pos.copy_from(&other.pos);
        self.vel.copy_from(&other.vel);
    }

    /// The first particle whose position or velocity is not finite.
    pub fn first_non_finite(&self) -> Option<usize> {
        (0..self.pos.len()).find(|&p| !(self.pos.get(p).is_finite() && self.vel.get(p).is_finite()))
    }

    pub fn heap_bytes(&self) -> usize {
        self.pos.heap_bytes() + self.vel.heap_bytes()
    }
}

/// Steps taken and simulated time, and the time requested from `advance` but not simulated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Clock {
    pub steps: u64,
    /// Simulated time at step `steps_base`: `time = time_base + (steps - steps_base) dt`, so
    /// that a change of `dt` changes the future, not the past, while a fixed `dt` gives times
    /// exact in the step count.
    pub time_base: f64,
    pub steps_base: u64,
    /// Requested but not yet simulated time, in s.
    pub accumulator: f64,
}

impl Clock {
    /// Simulated time in s, with `dt` the step now.
    pub fn time(&self, dt: f64) -> f64 {
        self.time_base + (self.steps as f64 - self.steps_base as f64) * dt
    }

    /// The step changes from `old_dt`: the steps so far keep the time they took.
    pub fn change_dt(&mut self, old_dt: f64) {
        (self.time_base, self.steps_base) = (self.time(old_dt), self.steps);
    }
}

/// Everything a step changes.
pub struct State {
    pub kin: Kinematics,
    /// Targets of the kinematic pins (dragged particles).
    pub targets: KinematicPins,
    pub clock: Clock,
    /// Increments whenever positions change (a step, `set_positions`, a reset).
    pub version: u64,
}

impl State {
    pub fn new(pos: Vec3s) -> Self {
        let n = pos.len();
        State {
            kin: Kinematics {
                pos,
                vel: Vec3s::zeros(n),
            },
            targets: KinematicPins::default(),
            clock: Clock::default(),
            version: 0,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.kin.heap_bytes()
    }
}
