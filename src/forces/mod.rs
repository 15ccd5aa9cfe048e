//! Forces: each effect that pushes on particles is a [`ForceTerm`]; the [`ForceModel`] holds
//! the terms a scene asked for and evaluates them all in one parallel sweep.
//!
//! The sweep cuts the particle range into chunks; inside a chunk every term adds its force into
//! the chunk's slice of the force buffer while that slice is hot in cache. Each particle's force
//! is summed in the same order whatever the chunking, so the result is bitwise independent of
//! the number of threads.

mod drag;
mod gravity;
pub mod springs;

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

pub use drag::AirDrag;
pub use gravity::Gravity;
pub use springs::{SpringForce, Springs};

use crate::grid::Grid;
use crate::profile::Profile;
use crate::soa::{Vec3SliceMut, Vec3s};

/// What a force term may read.
pub struct ForceInput<'a> {
    pub grid: Grid,
    pub pos: &'a Vec3s,
    pub vel: &'a Vec3s,
    /// Particle masses in kg (the true mass, also for pinned particles).
    pub mass: &'a [f32],
    pub springs: &'a Springs,
}

/// One additive force effect.
pub trait ForceTerm: Send + Sync {
    /// Name in `effects` and `profile()`.
    fn name(&self) -> &'static str;

    /// Adds this term's force on the particles `range` into `out`, whose slices cover exactly
    /// `range`. Must only read `input` and write `out`.
    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut);

    /// How the force depends on the state, for implicit integrators.
    fn linearization(&self) -> Linearization {
        Linearization::Constant
    }
}

/// The shape of a force term's Jacobians `df/dx`, `df/dv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Linearization {
    /// Independent of the state (gravity).
    Constant,
    /// `f = -c v`: `df/dv = -c I`.
    Drag { c: f32 },
    /// The springs of a family with stiffness `k` and damping `c` (see `forces/springs.rs`).
    Springs {
        family: crate::grid::Family,
        k: f32,
        c: f32,
    },
}

/// The force terms of a scene, in the order they are summed.
pub struct ForceModel {
    terms: Vec<Box<dyn ForceTerm>>,
    /// CPU nanoseconds per term during the current evaluation, summed over threads.
    cpu_nanos: Vec<AtomicU64>,
}

impl ForceModel {
    pub fn new(terms: Vec<Box<dyn ForceTerm>>) -> Self {
        let cpu_nanos = terms.iter().map(|_| AtomicU64::new(0)).collect();
        ForceModel { terms, cpu_nanos }
    }

    pub fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.terms.iter().map(|t| t.name())
    }

    pub fn linearizations(&self) -> impl Iterator<Item = Linearization> + '_ {
        self.terms.iter().map(|t| t.linearization())
    }

    /// Writes the total force on every particle into `out` and returns the sweep's wall time,
    /// which it also books into `profile` split among the terms.
    pub fn evaluate(
        &self,
        input: &ForceInput,
        out: &mut Vec3s,
        chunk: usize,
        profile: &mut Profile,
    ) -> Duration {
        let start = Instant::now();
        out.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, mut f)| {
                let range = c * chunk..c * chunk + f.len();
                f.fill(Vec3::ZERO);
                for (term, nanos) in self.terms.iter().zip(&self.cpu_nanos) {
                    let t = Instant::now();
                    term.accumulate(input, range.clone(), &mut f);
                    nanos.fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
                }
            });
        let wall = start.elapsed();
        profile.force_time += wall;
        let cpu_total = self
            .cpu_nanos
            .iter()
            .map(|n| n.load(Ordering::Relaxed))
            .sum::<u64>();
        for (term, nanos) in self.terms.iter().zip(&self.cpu_nanos) {
            let share = nanos.swap(0, Ordering::Relaxed) as f64 / cpu_total.max(1) as f64;
            profile.add(term.name(), wall.mul_f64(share));
        }
        wall
    }
}
