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

use crate::grid::{Grid, SpringKind};
use crate::profile::Profile;
use crate::soa::{Vec3SliceMut, Vec3s};

/// The state a force evaluation reads.
#[derive(Clone, Copy)]
pub struct StateRef<'a> {
    pub grid: Grid,
    pub pos: &'a Vec3s,
    pub vel: &'a Vec3s,
    /// Particle masses in kg.
    pub mass: &'a [f32],
    pub springs: &'a Springs,
}

/// What a force term may read.
pub struct ForceInput<'a> {
    pub grid: Grid,
    pub pos: &'a Vec3s,
    pub vel: &'a Vec3s,
    /// Particle masses in kg (the true mass, also for pinned particles).
    pub mass: &'a [f32],
    pub springs: &'a Springs,
    /// Force on each spring's anchor, per spring kind, filled by [`ForceTerm::prepare`]
    /// before any [`ForceTerm::accumulate`] runs (empty for kinds no term prepares).
    pub spring_table: &'a [Vec3s; 6],
}

/// One additive force effect.
pub trait ForceTerm: Send + Sync {
    /// Name in `effects` and `profile()`.
    fn name(&self) -> &'static str;

    /// Adds this term's force on the particles `range` into `out`, whose slices cover exactly
    /// `range`. Must only read `input` and write `out`.
    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut);

    /// Spring kinds whose per-spring force this term computes in [`ForceTerm::prepare`].
    fn prepared_kinds(&self) -> &[SpringKind] {
        &[]
    }

    /// Writes the force on the anchor of each spring of `kind` anchored in `range` into `out`
    /// (slices covering exactly `range`). Runs for every range before any `accumulate`, so a
    /// spring's force is computed once and both its ends read it.
    fn prepare(
        &self,
        _input: &ForceInput,
        _kind: SpringKind,
        _range: Range<usize>,
        _out: &mut Vec3SliceMut,
    ) {
    }

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
///
/// An evaluation is two parallel sweeps. The first computes, once per spring, the force on its
/// anchor (the terms' [`ForceTerm::prepare`]) into a table. The second cuts the particles into
/// chunks; inside a chunk every term adds its force into the chunk's slice of the output while
/// that slice is hot in cache, springs by reading the table (`+F` at the anchor, `-F` at the
/// far end: bitwise the negation, so momentum is conserved exactly up to summation order).
/// Each particle's force is summed in the same order whatever the chunking, so the result is
/// bitwise independent of the number of threads.
pub struct ForceModel {
    terms: Vec<Box<dyn ForceTerm>>,
    /// `(term, kind)` for every spring kind some term prepares.
    prepared: Vec<(usize, SpringKind)>,
    /// Per-spring anchor forces, by kind; sized on the first evaluation.
    table: [Vec3s; 6],
    /// CPU nanoseconds per term during the current evaluation, summed over threads.
    cpu_nanos: Vec<AtomicU64>,
}

impl ForceModel {
    pub fn new(terms: Vec<Box<dyn ForceTerm>>) -> Self {
        let cpu_nanos = terms.iter().map(|_| AtomicU64::new(0)).collect();
        let prepared = terms
            .iter()
            .enumerate()
            .flat_map(|(t, term)| term.prepared_kinds().iter().map(move |&kind| (t, kind)))
            .collect();
        ForceModel {
            terms,
            prepared,
            table: Default::default(),
            cpu_nanos,
        }
    }

    pub fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.terms.iter().map(|t| t.name())
    }

    pub fn linearizations(&self) -> impl Iterator<Item = Linearization> + '_ {
        self.terms.iter().map(|t| t.linearization())
    }

    /// Heap memory of the spring table.
    pub fn heap_bytes(&self) -> usize {
        self.table.iter().map(Vec3s::heap_bytes).sum()
    }

    /// Writes the total force on every particle into `out` and returns the evaluation's wall
    /// time, which it also books into `profile` split among the terms.
    pub fn evaluate(
        &mut self,
        state: StateRef,
        out: &mut Vec3s,
        chunk: usize,
        profile: &mut Profile,
    ) -> Duration {
        let start = Instant::now();
        let StateRef {
            grid,
            pos,
            vel,
            mass,
            springs,
        } = state;
        let n = grid.len();
        for &(_, kind) in &self.prepared {
            if self.table[kind.index()].len() != n {
                self.table[kind.index()] = Vec3s::zeros(n);
            }
        }
        let Self {
            terms,
            prepared,
            table,
            cpu_nanos,
        } = self;

        // Sweep 1: each spring's force, once. Work items are (term, kind, chunk) triples.
        if !prepared.is_empty() {
            let input = ForceInput {
                grid,
                pos,
                vel,
                mass,
                springs,
                spring_table: &EMPTY_TABLE,
            };
            let tables = SharedTables::new(table);
            let chunks = n.div_ceil(chunk);
            (0..prepared.len() * chunks)
                .into_par_iter()
                .for_each(|item| {
                    let (t, kind) = prepared[item / chunks];
                    let c = item % chunks;
                    let range = c * chunk..((c + 1) * chunk).min(n);
                    // SAFETY: items write disjoint (kind, chunk) ranges of the table, and nothing
                    // reads it during this sweep.
                    let mut out = unsafe { tables.range_mut(kind.index(), range.clone()) };
                    let clock = Instant::now();
                    terms[t].prepare(&input, kind, range, &mut out);
                    cpu_nanos[t].fetch_add(clock.elapsed().as_nanos() as u64, Ordering::Relaxed);
                });
        }

        // Sweep 2: every term adds its force, chunk by chunk.
        let input = ForceInput {
            grid,
            pos,
            vel,
            mass,
            springs,
            spring_table: table,
        };
        out.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, mut f)| {
                let range = c * chunk..c * chunk + f.len();
                f.fill(Vec3::ZERO);
                for (term, nanos) in terms.iter().zip(cpu_nanos.iter()) {
                    let clock = Instant::now();
                    term.accumulate(&input, range.clone(), &mut f);
                    nanos.fetch_add(clock.elapsed().as_nanos() as u64, Ordering::Relaxed);
                }
            });

        let wall = start.elapsed();
        profile.force_time += wall;
        let cpu_total = cpu_nanos
            .iter()
            .map(|n| n.load(Ordering::Relaxed))
            .sum::<u64>();
        for (term, nanos) in terms.iter().zip(cpu_nanos.iter()) {
            let share = nanos.swap(0, Ordering::Relaxed) as f64 / cpu_total.max(1) as f64;
            profile.add(term.name(), wall.mul_f64(share));
        }
        wall
    }
}

static EMPTY_TABLE: [Vec3s; 6] = [
    Vec3s::new_const(),
    Vec3s::new_const(),
    Vec3s::new_const(),
    Vec3s::new_const(),
    Vec3s::new_const(),
    Vec3s::new_const(),
];

/// Raw views of the six per-kind tables, so that parallel work items can each write their own
/// disjoint range.
struct SharedTables {
    parts: [(*mut f32, *mut f32, *mut f32, usize); 6],
}

// SAFETY: the pointers are only turned into slices for disjoint ranges (see `range_mut`).
unsafe impl Sync for SharedTables {}

impl SharedTables {
    fn new(table: &mut [Vec3s; 6]) -> Self {
        let parts = std::array::from_fn(|k| {
            let v = &mut table[k];
            (
                v.x.as_mut_ptr(),
                v.y.as_mut_ptr(),
                v.z.as_mut_ptr(),
                v.x.len(),
            )
        });
        SharedTables { parts }
    }

    /// # Safety
    /// No two live results may overlap: every caller must use a distinct `(kind, range)`.
    unsafe fn range_mut(&self, kind: usize, range: Range<usize>) -> Vec3SliceMut<'_> {
        let (x, y, z, len) = self.parts[kind];
        assert!(range.end <= len, "table range out of bounds");
        let n = range.len();
        unsafe {
            Vec3SliceMut {
                x: std::slice::from_raw_parts_mut(x.add(range.start), n),
                y: std::slice::from_raw_parts_mut(y.add(range.start), n),
                z: std::slice::from_raw_parts_mut(z.add(range.start), n),
            }
        }
    }
}
