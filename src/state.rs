//! Particle state: what changes every step ([`Kinematics`]) and what does not ([`Particles`]).

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

    pub fn heap_bytes(&self) -> usize {
        self.pos.heap_bytes() + self.vel.heap_bytes()
    }
}

/// Per-particle constants and flags.
#[derive(Clone, Debug)]
pub struct Particles {
    /// Mass in kg (kept for pinned particles, so unpinning restores it).
    pub mass: Vec<f32>,
    /// 1 / mass, or 0 for a particle that integration must not move (pinned or cut).
    pub inv_mass: Vec<f32>,
    pub pinned: Vec<bool>,
    /// False once a particle has been cut out of the cloth.
    pub alive: Vec<bool>,
}

impl Particles {
    pub fn new(n: usize, mass: f32) -> Self {
        Particles {
            mass: vec![mass; n],
            inv_mass: vec![1.0 / mass; n],
            pinned: vec![false; n],
            alive: vec![true; n],
        }
    }

    pub fn len(&self) -> usize {
        self.mass.len()
    }

    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Whether integration and collisions move particle `p`.
    pub fn is_dynamic(&self, p: usize) -> bool {
        self.inv_mass[p] > 0.0
    }

    /// Recomputes `inv_mass[p]` from the flags.
    pub fn refresh(&mut self, p: usize) {
        self.inv_mass[p] = if self.pinned[p] || !self.alive[p] {
            0.0
        } else {
            1.0 / self.mass[p]
        };
    }

    pub fn heap_bytes(&self) -> usize {
        (self.mass.capacity() + self.inv_mass.capacity()) * size_of::<f32>()
            + self.pinned.capacity()
            + self.alive.capacity()
    }
}
